// Entry point of a stage run as a compute shader: one invocation per texel, 8x8 work groups,
// frag_coord = (x + 0.5, y + 0.5) as a fragment would see it; results go to images whose
// format (STORAGE_FORMAT: rgba32f or rgba16f) is the stage's storage.
layout(local_size_x = 8, local_size_y = 8) in;
layout(STORAGE_FORMAT, binding = 0) uniform writeonly image2D dst0;
layout(STORAGE_FORMAT, binding = 1) uniform writeonly image2D dst1;
ivec2 target_size() { return imageSize(dst0); }
void emit0(vec4 v) { imageStore(dst0, ivec2(gl_GlobalInvocationID.xy), v); }
void emit1(vec4 v) { imageStore(dst1, ivec2(gl_GlobalInvocationID.xy), v); }
void run_stage(vec2 frag_coord);
void main() {
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(gid, imageSize(dst0)))) return;
  run_stage(vec2(gid) + 0.5);
}
