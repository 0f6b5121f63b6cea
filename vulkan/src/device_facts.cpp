#include "bloomref/vulkan/device_facts.h"

#include <Imath/half.h>

#include <cmath>
#include <cstring>
#include <set>
#include <vector>

#include "bloomref/half.h"
#include "probe_f16.h"
#include "probe_f32.h"
#include "vk_objects.h"

namespace bloomref::vulkan {
namespace {

struct ProbeConstants {
  std::int32_t mode = 0;
  float a = 0, b = 0, c = 0, v = 0;
};

// The probe (vulkan/shaders/probe.comp) once over a w x 1 storage image of `format` reading
// `src` through `sampler`: the results as floats, RGBA per texel.
std::vector<float> run_probe(Context::Impl& ctx, const Image2D& src, VkSampler sampler,
                             const ProbeConstants& k, int w, VkFormat format) {
  const bool f16 = format == VK_FORMAT_R16G16B16A16_SFLOAT;
  ComputePipeline p(ctx, f16 ? probe_f16 : probe_f32, f16 ? sizeof probe_f16 : sizeof probe_f32,
                    {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
                    sizeof(ProbeConstants));
  Image2D dst(ctx, w, 1, format, VK_IMAGE_USAGE_STORAGE_BIT);
  p.bind_image(0, src.view(), sampler);
  p.bind_image(1, dst.view());
  ctx.submit([&](VkCommandBuffer cb) { p.dispatch(cb, &k, std::uint32_t((w + 63) / 64), 1); });
  const std::vector<unsigned char> bytes = dst.download();
  std::vector<float> out(std::size_t(w) * 4);
  if (!f16) {
    std::memcpy(out.data(), bytes.data(), out.size() * sizeof(float));
  } else {
    for (std::size_t i = 0; i < out.size(); ++i) {
      std::uint16_t bits = 0;
      std::memcpy(&bits, bytes.data() + 2 * i, 2);
      Imath::half h;
      h.setBits(bits);
      out[i] = float(h);
    }
  }
  return out;
}

}  // namespace

DeviceFacts measure_device_facts(Context& context) {
  Context::Impl& ctx = context.impl();
  DeviceFacts f;
  const Sampler nearest(ctx, VK_FILTER_NEAREST), linear(ctx, VK_FILTER_LINEAR);
  // 1. float -> half on a storage-image store, the values gpu/device_facts.cpp writes: a third
  //    and two thirds between neighbouring halves (nearest or toward zero), ties (even or away).
  std::vector<float> values;
  for (float base : {1.0f, 3.0f, 1000.0f, -7.0f}) {
    const float q = std::ldexp(1.0f, std::ilogb(std::fabs(base)) - 10);
    for (float frac : {0.3f, 0.7f, 0.5f}) values.push_back(base + std::copysign(frac * q, base));
    values.push_back(base + std::copysign(1.5f * q, base));
  }
  values.push_back(65520.0f);
  values.push_back(70000.0f);
  values.push_back(std::ldexp(1.0f, -20));
  values.push_back(std::ldexp(1.0f, -140));
  const int n = static_cast<int>(values.size());
  std::vector<float> texels(std::size_t(n) * 4);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 4; ++c) texels[std::size_t(i) * 4 + c] = values[std::size_t(i)];
  Image2D src(ctx, n, 1, VK_FORMAT_R32G32B32A32_SFLOAT, VK_IMAGE_USAGE_SAMPLED_BIT);
  src.upload(texels.data());
  ProbeConstants copy;
  const std::vector<float> h = run_probe(ctx, src, nearest.handle(), copy, n,
                                         VK_FORMAT_R16G16B16A16_SFLOAT);
  int rne = 0, rtz = 0;
  const int tested = n - 4;
  for (int i = 0; i < tested; ++i) {
    rne += h[std::size_t(i) * 4] == round_to_half(values[std::size_t(i)], HalfRounding::nearest_even);
    rtz += h[std::size_t(i) * 4] == round_to_half(values[std::size_t(i)], HalfRounding::toward_zero);
  }
  f.half_rounding = rne == tested ? "nearest-even" : rtz == tested ? "toward-zero" : "other";
  f.half_of_65520 = h[std::size_t(n - 4) * 4];
  f.half_of_70000 = h[std::size_t(n - 3) * 4];
  f.half_denormals_kept = h[std::size_t(n - 2) * 4] == values[std::size_t(n - 2)];
  const std::vector<float> full = run_probe(ctx, src, nearest.handle(), copy, n,
                                            VK_FORMAT_R32G32B32A32_SFLOAT);
  f.f32_denormals_kept = full[std::size_t(n - 1) * 4] == values[std::size_t(n - 1)];

  // 2. The linear sampler's weights: 1024 lookups across the span between texels 0 and 1.
  const float two[8] = {0, 0, 0, 1, 1, 1, 1, 1};
  Image2D row(ctx, 2, 1, VK_FORMAT_R32G32B32A32_SFLOAT, VK_IMAGE_USAGE_SAMPLED_BIT);
  row.upload(two);
  ProbeConstants sweep_k;
  sweep_k.mode = 1;
  const std::vector<float> sweep = run_probe(ctx, row, linear.handle(), sweep_k, 1024,
                                             VK_FORMAT_R32G32B32A32_SFLOAT);
  std::set<float> distinct;
  for (int i = 0; i < 1024; ++i) distinct.insert(sweep[std::size_t(i) * 4]);
  f.bilinear_distinct = static_cast<int>(distinct.size());
  f.subtexel_bits = 0;
  for (int b = 1; b <= 16; ++b)
    if (f.bilinear_distinct == (1 << b) + 1 || f.bilinear_distinct == (1 << b)) f.subtexel_bits = b;
  if (f.bilinear_distinct >= 1000) f.subtexel_bits = 0;

  // 3. FMA contraction and shader denormals, as gpu/device_facts.cpp: a = b = 1 + 2^-12,
  //    c = -(1 + 2^-11): rounded first the sum is 0, fused it is 2^-24.
  ProbeConstants arith_k;
  arith_k.mode = 2;
  arith_k.a = arith_k.b = 1.0f + std::ldexp(1.0f, -12);
  arith_k.c = -(1.0f + std::ldexp(1.0f, -11));
  arith_k.v = std::ldexp(1.0f, -126);
  const std::vector<float> arith = run_probe(ctx, row, nearest.handle(), arith_k, 1,
                                             VK_FORMAT_R32G32B32A32_SFLOAT);
  f.fma_contracted = arith[0] != 0.0f;
  f.shader_denormals_kept = arith[1] == std::ldexp(1.0f, -127);
  return f;
}

}  // namespace bloomref::vulkan
