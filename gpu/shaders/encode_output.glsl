// Stage `output`: pow(max(x, 0), 1 / gamma) (seed 000's gamma correction).
uniform sampler2D mapped;
uniform float gamma;

void run_stage(vec2 frag_coord) {
  vec4 m = texelFetch(mapped, ivec2(frag_coord), 0);
  vec3 c = pow(max(m.rgb, vec3(0.0)), vec3(1.0 / gamma));
  emit0(vec4(c, m.a));
}
