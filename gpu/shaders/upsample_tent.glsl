// Stages `up.k` and `bloom` (seed 003's UpSample): current level (texelFetch; none for the
// full-resolution bloom) plus the 3x3 tent (1-2-1 / 16) of the smaller level at one of its
// texels. Same constants and order as reference/src/mip.cpp.
uniform sampler2D small;
uniform sampler2D current;
uniform bool has_current;

const ivec2 tent_offset[9] = ivec2[](ivec2(0, 0), ivec2(-1, -1), ivec2(0, -1), ivec2(1, -1),
    ivec2(1, 0), ivec2(1, 1), ivec2(0, 1), ivec2(-1, 1), ivec2(-1, 0));
const float tent_weight[9] = float[](0.25, 0.0625, 0.125, 0.0625, 0.125, 0.0625, 0.125,
    0.0625, 0.125);

void run_stage(vec2 frag_coord) {
  vec2 uv = frag_coord / vec2(target_size());
  vec2 texel = 1.0 / vec2(textureSize(small, 0));
  vec3 r = has_current ? texelFetch(current, ivec2(frag_coord), 0).rgb : vec3(0.0);
  for (int i = 0; i < 9; ++i)
    r = r + texture(small, uv + vec2(tent_offset[i]) * texel).rgb * tent_weight[i];
  emit0(vec4(r, 1.0));
}
