#include "bloomref/gpu/device_facts.h"

#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "bloomref/half.h"
#include "gl_objects.h"

namespace bloomref::gpu {
namespace {

// Runs the probe program once over a `w` x 1 target of `format`.
std::vector<float> run_probe(const Program& prog, const Texture& src, int mode, int w,
                             GLenum format) {
  Texture dst(w, 1, format);
  Framebuffer fb(dst);
  GLuint vao = 0;
  glGenVertexArrays(1, &vao);
  glBindVertexArray(vao);
  glViewport(0, 0, w, 1);
  glUseProgram(prog.id);
  prog.set("mode", mode);
  prog.set("src", 0);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, src.id);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glFinish();
  glDeleteVertexArrays(1, &vao);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return dst.read();
}

}  // namespace

DeviceFacts measure_device_facts(GlContext& ctx) {
  DeviceFacts f;
  f.renderer = ctx.info().renderer;
  const Program prog = build_program(false, "probe.glsl", {});

  // 1. float -> half on a render-target write. Values a third and two thirds of the way
  //    between neighbouring halves tell nearest from toward-zero; ties tell even from away.
  std::vector<float> values;
  for (float base : {1.0f, 3.0f, 1000.0f, -7.0f}) {
    const float q = std::ldexp(1.0f, std::ilogb(std::fabs(base)) - 10);  // half quantum there
    for (float frac : {0.3f, 0.7f, 0.5f}) values.push_back(base + std::copysign(frac * q, base));
    values.push_back(base + std::copysign(1.5f * q, base));  // tie to even: away from base
  }
  values.push_back(65520.0f);
  values.push_back(70000.0f);
  values.push_back(std::ldexp(1.0f, -20));  // a half denormal
  values.push_back(std::ldexp(1.0f, -140)); // a float denormal
  const int n = static_cast<int>(values.size());
  std::vector<float> texels(std::size_t(n) * 4);
  for (int i = 0; i < n; ++i) texels[i * 4] = texels[i * 4 + 1] = texels[i * 4 + 2] = texels[i * 4 + 3] = values[i];
  const Texture src(n, 1, GL_RGBA32F, texels.data());
  src.set_sampling(GL_NEAREST, GL_CLAMP_TO_EDGE);
  const std::vector<float> h = run_probe(prog, src, 0, n, GL_RGBA16F);
  int rne = 0, rtz = 0;
  const int tested = n - 4;
  for (int i = 0; i < tested; ++i) {
    rne += h[i * 4] == round_to_half(values[i], HalfRounding::nearest_even);
    rtz += h[i * 4] == round_to_half(values[i], HalfRounding::toward_zero);
  }
  f.half_rounding = rne == tested ? "nearest-even" : rtz == tested ? "toward-zero" : "other";
  f.half_of_65520 = h[(n - 4) * 4];
  f.half_of_70000 = h[(n - 3) * 4];
  f.half_denormals_kept = h[(n - 2) * 4] == values[n - 2];
  const std::vector<float> full = run_probe(prog, src, 0, n, GL_RGBA32F);
  f.f32_denormals_kept = full[(n - 1) * 4] == values[n - 1];

  // 2. Bilinear weight precision: 1024 lookups across the span between two texels (0 and 1).
  const float two[8] = {0, 0, 0, 1, 1, 1, 1, 1};
  const Texture row(2, 1, GL_RGBA32F, two);
  row.set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
  const std::vector<float> sweep = run_probe(prog, row, 1, 1024, GL_RGBA32F);
  std::set<float> distinct;
  for (int i = 0; i < 1024; ++i) distinct.insert(sweep[i * 4]);
  f.bilinear_distinct = static_cast<int>(distinct.size());
  f.subtexel_bits = 0;
  for (int b = 1; b <= 16; ++b)
    if (f.bilinear_distinct == (1 << b) + 1 || f.bilinear_distinct == (1 << b)) f.subtexel_bits = b;
  if (f.bilinear_distinct >= 1000) f.subtexel_bits = 0;

  // 3. FMA contraction and shader denormals: a = b = 1 + 2^-12, c = -(1 + 2^-11):
  //    a * b = 1 + 2^-11 + 2^-24 exactly; rounded first it is 1 + 2^-11 and the sum is 0,
  //    fused the sum is 2^-24.
  prog.set("a", 1.0f + std::ldexp(1.0f, -12));
  prog.set("b", 1.0f + std::ldexp(1.0f, -12));
  prog.set("c", -(1.0f + std::ldexp(1.0f, -11)));
  prog.set("v", std::ldexp(1.0f, -126));
  const std::vector<float> arith = run_probe(prog, src, 2, 1, GL_RGBA32F);
  f.fma_contracted = arith[0] != 0.0f;
  f.shader_denormals_kept = arith[1] == std::ldexp(1.0f, -127);
  // 4. GL_LINEAR reads of half textures (the mip chain's tent and downsample read its f16
  //    levels so), the same 1024-sample sweep over 2-texel rows uploaded as half bits: halves
  //    0x0010 and 0x0010 (2^-20, denormal) read 2^-20 at every weight unless denormal texels
  //    are flushed; 0 and 0x0001 (2^-24, the least denormal), and 1 and 1 + 2^-10 (one ULP
  //    apart), read values between the two where the filter keeps float precision, only the
  //    two where it rounds its result to halves.
  const auto sweep_half = [&](std::uint16_t left, std::uint16_t right) {
    const std::uint16_t bits[8] = {left, left, left, left, right, right, right, right};
    Texture t(2, 1, GL_RGBA16F);
    glBindTexture(GL_TEXTURE_2D, t.id);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 2);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, 2, 1, GL_RGBA, GL_HALF_FLOAT, bits);
    t.set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
    const std::vector<float> r = run_probe(prog, t, 1, 1024, GL_RGBA32F);
    std::vector<float> out(1024);
    for (int i = 0; i < 1024; ++i) out[i] = r[std::size_t(i) * 4];
    return out;
  };
  const std::vector<float> same = sweep_half(0x0010, 0x0010);
  f.half_denormal_texels = classify_equal(same, std::ldexp(1.0f, -20));
  f.half_filter_denormals = classify_between(sweep_half(0x0000, 0x0001), 0.0f,
                                             std::ldexp(1.0f, -24));
  f.half_filter_normals = classify_between(sweep_half(0x3c00, 0x3c01), 1.0f,
                                           1.0f + std::ldexp(1.0f, -10));
  ctx.check("measuring device facts");
  return f;
}

std::string classify_equal(const std::vector<float>& samples, float value) {
  bool all_value = true, all_zero = true;
  for (float v : samples) {
    all_value = all_value && v == value;
    all_zero = all_zero && v == 0.0f;
  }
  return all_value ? "kept" : all_zero ? "flushed" : "other";
}

std::string classify_between(const std::vector<float>& samples, float lo, float hi) {
  bool between = false, ends = true;
  for (float v : samples) {
    between = between || (v > lo && v < hi);
    ends = ends && (v == lo || v == hi);
  }
  if (between) return "float";
  if (ends) return "half";
  return "other";
}

}  // namespace bloomref::gpu
