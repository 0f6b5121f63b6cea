// Stage `tonemap`: 1 - exp(-hdr * exposure) (seed 000's exposure tone mapping).
uniform sampler2D hdr;
uniform float exposure;

// 1 - exp(-a) without cancellation (reference/src/stages.cpp, tonemap_value): the Taylor series
// in Horner form below |a| = 0.5, same float constants and operation order as the CPU.
float one_minus_exp_neg(float a, float x) {
  if (abs(a) < 0.5) {
    precise float r = 1.0 - a * 0.125;
    r = 1.0 - a * 0.14285715 * r;
    r = 1.0 - a * 0.16666667 * r;
    r = 1.0 - a * 0.2 * r;
    r = 1.0 - a * 0.25 * r;
    r = 1.0 - a * 0.33333334 * r;
    r = 1.0 - a * 0.5 * r;
    precise float m = a * r;
    return m;
  }
  return 1.0 - exp(x);
}

void run_stage(vec2 frag_coord) {
  vec4 h = texelFetch(hdr, ivec2(frag_coord), 0);
  vec3 x = -h.rgb * exposure;
  vec3 mapped = vec3(one_minus_exp_neg(-x.r, x.r), one_minus_exp_neg(-x.g, x.g),
                     one_minus_exp_neg(-x.b, x.b));
  emit0(vec4(mapped, h.a));
}
