#version 330 core
// Unity URP's bloom upsample (Bloom.shader, Upsample without _BLOOM_HQ): the level itself and
// one bilinear lookup of the level below, lerp(high, low, scatter) as HLSL's lerp writes it.
// bloomref's own GLSL of it: `compare` runs it for preset unity-urp.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;  // the level (highMip)
uniform sampler2D lowMip;      // the level below, or its upsample
uniform float scatter;

void main() {
  vec3 high = texture(srcTexture, texCoord).rgb;
  vec3 low = texture(lowMip, texCoord).rgb;
  level = high + (low - high) * scatter;
}
