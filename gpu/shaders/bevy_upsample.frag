#version 330 core
// The mip chain's upsample as Bevy's bloom computes it (bloom.wesl, sample_input_3x3_tent): the
// 3x3 tent (1 2 1 / 16) with its taps one texel of the smaller level apart. The host blends the
// result into the larger level (or the scene) with a constant colour. bloomref's own: `compare`
// runs it for preset bevy.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;

void main() {
  vec2 texel = 1.0 / vec2(textureSize(srcTexture, 0));
  vec3 sum = vec3(0.0);
  for (int j = -1; j <= 1; ++j)
    for (int i = -1; i <= 1; ++i) {
      float weight = float((2 - abs(i)) * (2 - abs(j)));
      sum += weight * texture(srcTexture, texCoord + vec2(i, j) * texel).rgb;
    }
  level = sum / 16.0;
}
