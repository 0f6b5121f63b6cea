// Stage `down.k` (seed 003, FragShader_BloomFilter's DownSample; Jimenez 2014): 13 GL_LINEAR
// lookups at 0, +-1, +-2 source texels; the first level thresholds each lookup (L < threshold
// -> 0) and may weight each group of four by the Karis average 1 / (1 + L), normalised within
// the group. Same constants and order as reference/src/mip.cpp.
uniform sampler2D src;
uniform bool first_level;
uniform bool karis;
uniform float threshold;

const ivec2 down_offset[13] = ivec2[](ivec2(0, 0), ivec2(-1, -1), ivec2(1, -1), ivec2(1, 1),
    ivec2(-1, 1), ivec2(-2, -2), ivec2(0, -2), ivec2(2, -2), ivec2(2, 0), ivec2(2, 2),
    ivec2(0, 2), ivec2(-2, 2), ivec2(-2, 0));
const float down_weight[13] = float[](0.125, 0.125, 0.125, 0.125, 0.125, 0.03125, 0.0625,
    0.03125, 0.0625, 0.03125, 0.0625, 0.03125, 0.0625);
const int group_tap[20] = int[](1, 2, 3, 4, 5, 6, 0, 12, 6, 7, 8, 0, 0, 8, 9, 10, 12, 0, 10, 11);
const float group_weight[5] = float[](0.5, 0.125, 0.125, 0.125, 0.125);

void run_stage(vec2 frag_coord) {
  vec2 uv = frag_coord / vec2(target_size());
  vec2 texel = 1.0 / vec2(textureSize(src, 0));
  vec3 q[13];
  for (int i = 0; i < 13; ++i) {
    vec2 o = vec2(down_offset[i]);
    q[i] = texture(src, uv + o * texel).rgb;
    if (first_level && threshold_luminance(q[i]) < threshold) q[i] = vec3(0.0);
  }
  vec3 r = vec3(0.0);
  if (first_level && karis) {
    float w[13];
    for (int i = 0; i < 13; ++i) w[i] = 1.0 / (1.0 + max(luminance(q[i]), 0.0));  // L < 0: 1
    for (int g = 0; g < 5; ++g) {
      precise float s = 0.0;
      for (int j = 0; j < 4; ++j) s = s + w[group_tap[g * 4 + j]];
      for (int j = 0; j < 4; ++j) {
        int i = group_tap[g * 4 + j];
        float f = group_weight[g] * w[i] / s;
        r = r + f * q[i];
      }
    }
  } else {
    for (int i = 0; i < 13; ++i) r = r + q[i] * down_weight[i];
  }
  emit0(vec4(r, 1.0));
}
