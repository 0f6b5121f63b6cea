// Entry point of a stage run as a compute shader: one invocation per texel, 8x8 work groups,
// frag_coord = (x + 0.5, y + 0.5) as a fragment would see it; results go to images whose
// format (STORAGE_FORMAT: rgba32f, rgba16f, r11f_g11f_b10f or rgba8) is the stage's storage. A dispatch covers the
// texels from u_origin on (0, 0 unless the adaptive plan dispatches one rectangle at a time).
layout(local_size_x = 8, local_size_y = 8) in;
uniform ivec2 u_origin;
layout(STORAGE_FORMAT, binding = 0) uniform writeonly image2D dst0;
layout(STORAGE_FORMAT, binding = 1) uniform writeonly image2D dst1;
ivec2 target_size() { return imageSize(dst0); }
ivec2 g_texel;
void emit0(vec4 v) { imageStore(dst0, g_texel, v); }
void emit1(vec4 v) { imageStore(dst1, g_texel, v); }
void run_stage(vec2 frag_coord);
void main() {
  g_texel = ivec2(gl_GlobalInvocationID.xy) + u_origin;
  if (any(greaterThanEqual(g_texel, imageSize(dst0)))) return;
  run_stage(vec2(g_texel) + 0.5);
}
