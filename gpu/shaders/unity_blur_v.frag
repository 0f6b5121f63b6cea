#version 330 core
// Unity URP's bloom pyramid, second pass of a level (Bloom.shader, FragBlurV): the first pass's
// result read at five points along y (0, +-1.38461538 and +-3.23076923 texels; the nine-tap
// Gaussian folded into bilinear lookups). bloomref's own GLSL of it: `compare` runs it for
// preset unity-urp.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform vec2 texelSize;  // 1 / the level's size, in f32 as the host computes it

vec3 tap(float offset) { return texture(srcTexture, texCoord + vec2(0.0, offset)).rgb; }

void main() {
  float t = texelSize.y;
  vec3 c0 = tap(-(t * 3.23076923)), c1 = tap(-(t * 1.38461538)), c2 = tap(0.0);
  vec3 c3 = tap(t * 1.38461538), c4 = tap(t * 3.23076923);
  level = c0 * 0.07027027 + c1 * 0.31621622 + c2 * 0.22702703 + c3 * 0.31621622 +
          c4 * 0.07027027;
}
