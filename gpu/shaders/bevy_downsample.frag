#version 330 core
// One level of the mip chain's downsample as Bevy's bloom computes it (bevyengine/bevy
// crates/bevy_post_process/src/bloom/bloom.wesl, sample_input_13_tap and downsample_first;
// docs/design.md, "Mip-chain variants"): 13 bilinear taps at 0, +-1 and +-2 texels of what it
// reads; on the first level each group of four is scaled by its weight, then by
// 1 / (1 + L / 4), L its Rec. 709 luminance, the sum clamped to [0.0001, 3.40282347e37], then
// the soft threshold when the host asks for it.
// bloomref's own: `compare` runs it for preset bevy.
in vec2 texCoord;
layout(location = 0) out vec3 level;
uniform sampler2D srcTexture;
uniform int firstDownsample;
// The soft threshold on the first level (softThreshold 1): the host's precomputed threshold,
// threshold - knee, 2 knee and 0.25 / (knee + 0.00001), as Bevy's BloomUniforms.
uniform int softThreshold;
uniform vec4 thresholdPrecomputations;

vec3 tap(vec2 steps) {
  return texture(srcTexture, texCoord + steps / vec2(textureSize(srcTexture, 0))).rgb;
}

vec3 soft_threshold(vec3 color) {
  vec4 t = thresholdPrecomputations;
  float brightness = max(color.r, max(color.g, color.b));
  float softness = clamp(brightness - t.y, 0.0, t.z);
  softness = softness * softness * t.w;
  float contribution = max(brightness - t.x, softness);
  contribution /= max(brightness, 0.00001);
  return color * contribution;
}

vec3 weighted(vec3 group) {
  return group * (1.0 / (1.0 + dot(group, vec3(0.2126, 0.7152, 0.0722)) / 4.0));
}

void main() {
  vec3 a = tap(vec2(-2.0, 2.0)), b = tap(vec2(0.0, 2.0)), c = tap(vec2(2.0, 2.0));
  vec3 d = tap(vec2(-2.0, 0.0)), e = tap(vec2(0.0)), f = tap(vec2(2.0, 0.0));
  vec3 g = tap(vec2(-2.0, -2.0)), h = tap(vec2(0.0, -2.0)), i = tap(vec2(2.0, -2.0));
  vec3 j = tap(vec2(-1.0, 1.0)), k = tap(vec2(1.0, 1.0));
  vec3 l = tap(vec2(-1.0, -1.0)), m = tap(vec2(1.0, -1.0));
  if (firstDownsample == 1) {
    vec3 sum = weighted((a + b + d + e) * (0.125 / 4.0)) + weighted((b + c + e + f) * (0.125 / 4.0)) +
               weighted((d + e + g + h) * (0.125 / 4.0)) + weighted((e + f + h + i) * (0.125 / 4.0)) +
               weighted((j + k + l + m) * (0.5 / 4.0));
    level = clamp(sum, vec3(0.0001), vec3(3.40282347e37));
  } else {
    level = (a + c + g + i) * 0.03125 + (b + d + f + h) * 0.0625 + (e + j + k + l + m) * 0.125;
  }
  if (softThreshold == 1) level = soft_threshold(level);
}
