#version 330 core
// One level of a mip chain by the 4-tap box (--first-downsample box4, --downsample box4;
// docs/design.md, "Mip-chain variants"): four bilinear lookups at (+-1, +-1) texels of what it
// reads, each the mean of a 2x2 block, summed and times 0.25; then, on the first level when the
// host asks for it, Bevy's soft threshold (as bevy_downsample.frag). bloomref's own: `compare`
// runs it within Bevy's layout.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform int softThreshold;
uniform vec4 thresholdPrecomputations;  // Bevy's BloomUniforms, as bevy_downsample.frag

vec3 tap(vec2 steps) {
  return texture(srcTexture, texCoord + steps / vec2(textureSize(srcTexture, 0))).rgb;
}

void main() {
  level = (tap(vec2(-1.0, -1.0)) + tap(vec2(1.0, -1.0)) + tap(vec2(-1.0, 1.0)) +
           tap(vec2(1.0, 1.0))) * 0.25;
  if (softThreshold == 1) {
    vec4 t = thresholdPrecomputations;
    float brightness = max(level.r, max(level.g, level.b));
    float softness = clamp(brightness - t.y, 0.0, t.z);
    softness = softness * softness * t.w;
    float contribution = max(brightness - t.x, softness);
    contribution /= max(brightness, 0.00001);
    level *= contribution;
  }
}
