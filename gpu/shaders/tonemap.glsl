// Stage `tonemap`: 1 - exp(-hdr * exposure) (seed 000's exposure tone mapping).
uniform sampler2D hdr;
uniform float exposure;

void run_stage(vec2 frag_coord) {
  vec4 h = texelFetch(hdr, ivec2(frag_coord), 0);
#ifdef FAULT_NO_EXPOSURE
  vec3 mapped = vec3(1.0) - exp(-h.rgb);
#else
  vec3 mapped = vec3(1.0) - exp(-h.rgb * exposure);
#endif
  emit0(vec4(mapped, h.a));
}
