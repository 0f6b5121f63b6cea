// Shared by every stage shader (prepended after #version and the build's #defines).
// Mirrors reference/include/bloomref/stages.h: same formulas, same operation order.

// Non-finite policy (stages.h sanitize_value): 0 zero, 1 clamp, 2 propagate, 3 error; finite
// values beyond range_guard (2^120, set by the executor) are clamped to it under every policy.
uniform float range_guard;
float sanitize_value(float v, int policy, float storage_max) {
  if (!(isnan(v) || isinf(v))) return abs(v) > range_guard ? sign(v) * range_guard : v;
  if (policy >= 2) return v;
  if (policy == 0 || isnan(v)) return 0.0;
  return v > 0.0 ? storage_max : -storage_max;
}

// Rec. 709 luminance (seed 000), or Rec. 601's weights with --luma rec601, summed left to
// right. `precise` (GLSL 4.00+) forbids reordering and fusing, so the threshold decision is
// bit-exact with the CPU's and a pixel exactly at the threshold is a real tie (parity can then
// catch `>=` for `>`).
float luminance(vec3 c) {
#ifdef LUMA_REC601
  precise float l = c.r * 0.299 + c.g * 0.587 + c.b * 0.114;
#else
  precise float l = c.r * 0.2126 + c.g * 0.7152 + c.b * 0.0722;
#endif
  return l;
}

// The luminance the threshold compares (--luma-space): of linear colour, or of max(c, 0)
// encoded by pow(., 1 / gamma) (LUMA_GAMMA, luma_gamma the run's gamma) or by IEC 61966-2-1's
// curve (LUMA_SRGB). Mirrors stages.h threshold_luminance.
uniform float luma_gamma;
float threshold_luminance(vec3 c) {
#if defined(LUMA_GAMMA)
  return luminance(pow(max(c, vec3(0.0)), vec3(1.0 / luma_gamma)));
#elif defined(LUMA_SRGB)
  vec3 x = max(c, vec3(0.0));
  vec3 curve = 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055;
  return luminance(mix(curve, 12.92 * x, lessThanEqual(x, vec3(0.0031308))));
#else
  return luminance(c);
#endif
}
