// Stages `input` and `bright` in one draw, the seeds' way (seed 000: MRT, location 0 the scene,
// location 1 the bright colour). bright is decided on the sanitised value before it is stored.
uniform sampler2D raw;
uniform float threshold;
uniform int policy;
uniform float storage_max;

void run_stage(vec2 frag_coord) {
  vec4 v = texelFetch(raw, ivec2(frag_coord), 0);
  v = vec4(sanitize_value(v.r, policy, storage_max), sanitize_value(v.g, policy, storage_max),
           sanitize_value(v.b, policy, storage_max), sanitize_value(v.a, policy, storage_max));
  emit0(v);
  bool bright = threshold_luminance(v.rgb) > threshold;
  emit1(bright ? vec4(v.rgb, 1.0) : vec4(0.0, 0.0, 0.0, 1.0));
}
