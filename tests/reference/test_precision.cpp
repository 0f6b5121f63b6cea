// f32 (the shaders' order, GL float coordinates) against the f64 truth on every built-in scene
// and every corpus image: the error is printed and bounded.
//
// Bounds, derived:
//  * bloom (blur.N), relative to the largest bloom value: each pass moves a tap at most
//    delta = 2 * n * 2^-24 texels off its exact position (two float roundings of values below n:
//    s = (x + 0.5) / n and u = s * n - 0.5), changing the sample by at most delta * 2 * max; with
//    9 taps of total weight 1, a pass adds <= 2 * delta + 20 * 2^-24 relative (products, sums,
//    weight constants); N passes add N times that.
//  * output: |out32 - out64| <= |d|^(1/gamma) + slope * |d| where d is the error of the tone
//    mapped value (<= 4 * 2^-24 absolute from 1 - exp, plus the propagated bloom error, which is
//    damped by exp(-x) <= 1). The first term is the gamma curve's unbounded slope near black.
//  * threshold flips: a pixel whose luminance is within rounding of the threshold can be bright
//    in one precision and not the other (f32 rounds 0.2126 etc. to float). Its whole value then
//    differs; blurred, it adds at most its value (the N-pass response peaks below 1). The bloom
//    bound adds the sum of the flipped pixels' largest channels, and the test reports the count.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "bloomref/scenes.h"
#include "test_util.h"

using namespace bloomref;

namespace {

struct Errors {
  double bloom_rel = 0, out_abs = 0, out_rms = 0;
  std::size_t codes_differ = 0, nan32 = 0, nan64 = 0;
  std::size_t flips = 0;
  double flipped_mass = 0;  // sum over flipped pixels of max |channel|, relative to max bloom
};

Errors compare(const Image& scene, BloomParams p) {
  p.precision = Precision::f32;
  p.plan = PlanMode::full;
  const StageTrace t32 = execute(make_plan(p, scene.cview()), scene.cview(), {true});
  p.precision = Precision::f64;
  const StageTrace t64 = execute(make_plan(p, scene.cview()), scene.cview(), {true});
  Errors e;
  const std::string last = p.passes > 0 ? "blur." + std::to_string(p.passes) : "bright";
  const Image& b32 = t32.find(last)->image;
  const Image& b64 = t64.find(last)->image;
  double bmax = 0, bdiff = 0;
  for (std::size_t i = 0; i < b64.pixel_count() * 4; ++i) {
    if (i % 4 == 3 || !std::isfinite(b64.data()[i])) continue;
    bmax = std::max(bmax, double(std::fabs(b64.data()[i])));
    bdiff = std::max(bdiff, std::fabs(double(b32.data()[i]) - double(b64.data()[i])));
  }
  e.bloom_rel = bmax > 0 ? bdiff / bmax : bdiff;
  const Image& r32 = t32.find("bright")->image;
  const Image& r64 = t64.find("bright")->image;
  for (std::size_t i = 0; i < r64.pixel_count(); ++i) {
    const float* a = r32.data() + 4 * i;
    const float* b = r64.data() + 4 * i;
    const bool on32 = a[0] != 0 || a[1] != 0 || a[2] != 0, on64 = b[0] != 0 || b[1] != 0 || b[2] != 0;
    if (on32 == on64) continue;
    ++e.flips;
    const float* v = on32 ? a : b;
    e.flipped_mass += std::max({std::fabs(v[0]), std::fabs(v[1]), std::fabs(v[2])});
  }
  if (bmax > 0) e.flipped_mass /= bmax;
  const Image& o32 = t32.final_image();
  const ImageF64& o64 = *t64.output_f64;
  double sum2 = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < o64.pixel_count() * 4; ++i) {
    if (i % 4 == 3) continue;
    const double a = o32.data()[i], b = o64.data()[i];
    e.nan32 += std::isnan(a);
    e.nan64 += std::isnan(b);
    if (!std::isfinite(a) || !std::isfinite(b)) continue;
    e.out_abs = std::max(e.out_abs, std::fabs(a - b));
    sum2 += (a - b) * (a - b);
    ++n;
    e.codes_differ += quantize_8bit(float(a)) != quantize_8bit(float(b));
  }
  e.out_rms = n ? std::sqrt(sum2 / n) : 0;
  return e;
}

void check_bounds(const std::string& name, const Image& scene, const BloomParams& p) {
  const Errors e = compare(scene, p);
  const int n = std::max(scene.width(), scene.height());
  const double u = std::ldexp(1.0, -24);
  const double delta = 2.0 * n * u;
  const double bloom_bound = std::max(1, p.passes) * (4 * delta + 20 * u) + e.flipped_mass;
  const double d = 4 * u + bloom_bound;
  const double out_bound = std::pow(d, 1.0 / p.gamma) + d / p.gamma;
  std::printf("%-28s %5dx%-5d bloom rel %.2e (bound %.1e, %4.2f%%)  out max %.2e rms %.1e "
              "(bound %.1e)  8-bit codes differing %zu  threshold flips %zu\n",
              name.c_str(), scene.width(), scene.height(), e.bloom_rel, bloom_bound,
              100 * e.bloom_rel / bloom_bound, e.out_abs, e.out_rms, out_bound, e.codes_differ, e.flips);
  INFO(name);
  CHECK(e.bloom_rel <= bloom_bound);
  CHECK(e.out_abs <= out_bound);
  CHECK(e.nan32 == e.nan64);
}

}  // namespace

TEST_CASE("f32 against f64 on the built-in scenes", "[precision]") {
  for (const SceneInfo& s : scene_list()) check_bounds(s.name, make_scene(s.name), BloomParams{});
  BloomParams lin;
  lin.kernel = KernelName::linear5;
  check_bounds("demo (linear5)", make_scene("demo"), lin);
}

TEST_CASE("f32 against f64 on every corpus image", "[precision][corpus]") {
  const auto files = test::corpus_files();
  if (files.empty()) WARN("BLOOMREF_CORPUS is not set: corpus precision checks skipped");
  for (const std::string& f : files) {
    const LoadedImage in = load_image(f);
    check_bounds(std::filesystem::path(f).filename().string(), in.image, BloomParams{});
  }
}
