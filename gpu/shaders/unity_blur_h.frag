#version 330 core
// Unity URP's bloom pyramid, first pass of a level (Bloom.shader, FragBlurH): the level twice
// as large read at nine points two of its texels apart along x, with the Gaussian's weights.
// bloomref's own GLSL of it: `compare` runs it for preset unity-urp.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform vec2 texelSize;  // 1 / the source's size, in f32 as the host computes it (_TexelSize)

vec3 tap(float offset) { return texture(srcTexture, texCoord + vec2(offset, 0.0)).rgb; }

void main() {
  float t = texelSize.x * 2.0;
  vec3 c0 = tap(-(t * 4.0)), c1 = tap(-(t * 3.0)), c2 = tap(-(t * 2.0)), c3 = tap(-(t * 1.0));
  vec3 c4 = tap(0.0);
  vec3 c5 = tap(t * 1.0), c6 = tap(t * 2.0), c7 = tap(t * 3.0), c8 = tap(t * 4.0);
  level = c0 * 0.01621622 + c1 * 0.05405405 + c2 * 0.12162162 + c3 * 0.19459459 +
          c4 * 0.22702703 + c5 * 0.19459459 + c6 * 0.12162162 + c7 * 0.05405405 +
          c8 * 0.01621622;
}
