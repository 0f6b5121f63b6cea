// Device-facts probe (device_facts.cpp): mode 0 copies texels (store rounding), mode 1 samples
// GL_LINEAR at uv = (x + 0.5) / width between the texels of `src` (weight precision), mode 2
// evaluates a * b + c (FMA contraction) and v * 0.5 (denormal flush) from uniforms.
uniform sampler2D src;
uniform int mode;
uniform float a, b, c, v;

void run_stage(vec2 frag_coord) {
  if (mode == 0) {
    emit0(texelFetch(src, ivec2(frag_coord), 0));
  } else if (mode == 1) {
    float s = (frag_coord.x / 1024.0) * 0.5 + 0.25;  // texel centres of a 2-texel row: 0.25, 0.75
    emit0(texture(src, vec2(s, 0.5)));
  } else {
    emit0(vec4(a * b + c, v * 0.5, 0.0, 1.0));
  }
}
