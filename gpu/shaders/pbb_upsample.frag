#version 330 core
// The mip chain's upsample with the interface of LearnOpenGL's "Physically Based Bloom" host
// code: the 3x3 tent (1 2 1 / 16) with its taps filterRadius apart in texture coordinates; the
// host adds the result into the larger level by blending. bloomref's own: `compare` runs it for
// preset learnopengl-pbb, and the bug corpus (data/bugs/) changes it.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform float filterRadius;

void main() {
  vec3 sum = vec3(0.0);
  for (int j = -1; j <= 1; ++j)
    for (int i = -1; i <= 1; ++i) {
      float weight = float((2 - abs(i)) * (2 - abs(j)));
      sum += weight * texture(srcTexture, texCoord + vec2(i, j) * filterRadius).rgb;
    }
  level = sum / 16.0;
}
