// The mip chain's CPU stages (mip.h) against the seed 003 shaders written per texel with
// texture(), closed forms, and the adaptive plan's per-level skipping against the full plan.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <tuple>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/mip.h"
#include "bloomref/sampler.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"
#include "bloomref/engine/support.h"
#include "test_util.h"

using namespace bloomref;

namespace {

// Seed 003's lookup, literally: uv = (x + 0.5) / size of the target; uv + o * (1 / size of the
// source); texture() with GL_LINEAR and clamp-to-edge.
void shader_lookup(ConstImageView src, int x, int y, int tw, int th, int ox, int oy, int bits,
                   float out[3]) {
  const float u = (static_cast<float>(x) + 0.5f) / static_cast<float>(tw);
  const float v = (static_cast<float>(y) + 0.5f) / static_cast<float>(th);
  gl_texture_rgb(src, u + static_cast<float>(ox) * (1.0f / static_cast<float>(src.width)),
                 v + static_cast<float>(oy) * (1.0f / static_cast<float>(src.height)), bits, out);
}

float lum(const float q[3]) { return q[0] * 0.2126f + q[1] * 0.7152f + q[2] * 0.0722f; }

// down.k per texel, as mip.h states it.
void shader_down(ConstImageView src, ImageView dst, bool first, float threshold, bool karis,
                 int bits) {
  const auto& taps = downsample_taps();
  for (int y = 0; y < dst.height; ++y)
    for (int x = 0; x < dst.width; ++x) {
      float q[13][3];
      for (int i = 0; i < 13; ++i) {
        shader_lookup(src, x, y, dst.width, dst.height, taps[i].ox, taps[i].oy, bits, q[i]);
        if (first && lum(q[i]) < threshold) q[i][0] = q[i][1] = q[i][2] = 0.0f;
      }
      float r[3] = {0.0f, 0.0f, 0.0f};
      if (first && karis) {
        float w[13];
        for (int i = 0; i < 13; ++i) w[i] = 1.0f / (1.0f + std::max(lum(q[i]), 0.0f));
        for (std::size_t g = 0; g < karis_groups().size(); ++g) {
          const std::vector<int>& grp = karis_groups()[g];
          float s = 0.0f;
          for (int i : grp) s = s + w[i];
          for (int i : grp) {
            const float f = karis_group_weights()[g] * w[i] / s;
            for (int c = 0; c < 3; ++c) r[c] = r[c] + f * q[i][c];
          }
        }
      } else {
        for (int i = 0; i < 13; ++i)
          for (int c = 0; c < 3; ++c) r[c] = r[c] + q[i][c] * taps[i].weight;
      }
      float* d = dst.pixel(x, y);
      d[0] = r[0], d[1] = r[1], d[2] = r[2], d[3] = 1.0f;
    }
}

// up.k / bloom per texel.
void shader_up(ConstImageView small, ConstImageView current, ImageView dst, int bits) {
  for (int y = 0; y < dst.height; ++y)
    for (int x = 0; x < dst.width; ++x) {
      float r[3] = {0.0f, 0.0f, 0.0f};
      if (!current.empty())
        for (int c = 0; c < 3; ++c) r[c] = current.pixel(x, y)[c];
      for (const MipTap& t : tent_taps()) {
        float s[3];
        shader_lookup(small, x, y, dst.width, dst.height, t.ox, t.oy, bits, s);
        for (int c = 0; c < 3; ++c) r[c] = r[c] + s[c] * t.weight;
      }
      float* d = dst.pixel(x, y);
      d[0] = r[0], d[1] = r[1], d[2] = r[2], d[3] = 1.0f;
    }
}

Image noise(int w, int h, std::uint32_t seed, bool hostile) {
  Image img(w, h);
  const float odd[] = {-0.0f, 1e-40f, 1e38f, INFINITY, -INFINITY, NAN, -3.5f};
  for (float& v : img.values()) {
    seed = seed * 1664525u + 1013904223u;
    v = static_cast<float>(seed >> 8) / 16777216.0f * 4.0f;
    if (hostile && (seed >> 28) == 0) v = odd[(seed >> 8) % 7];
  }
  return img;
}

}  // namespace

TEST_CASE("mip stages equal seed 003's shaders written per texel with texture()", "[mip]") {
  for (bool hostile : {false, true})
    for (auto [w, h] : {std::pair{37, 23}, {64, 33}, {5, 3}, {1, 1}, {2, 9}}) {
      const Image src = noise(w, h, 7u + w, hostile);
      const int tw = std::max(1, w / 2), th = std::max(1, h / 2);
      for (int bits : {0, 8}) {
        for (auto [first, karis] : {std::pair{true, false}, {true, true}, {false, false}}) {
          Image got(tw, th), want(tw, th);
          downsample(src.cview(), got.view(), DownsampleOptions{first, 1.5f, karis, bits}, 2);
          shader_down(src.cview(), want.view(), first, 1.5f, karis, bits);
          INFO((hostile ? "hostile " : "") << w << "x" << h << " bits " << bits << " first "
                                           << first << " karis " << karis);
          CHECK(test::same_bits_nan_agnostic(got.cview(), want.cview()));
        }
        // up.k: the half-size level tent-upsampled onto this one plus its own texel; bloom: no add.
        const Image small = noise(tw, th, 11u + h, hostile);
        for (bool add : {true, false}) {
          Image got(w, h), want(w, h);
          const ConstImageView current = add ? src.cview() : ConstImageView{};
          upsample_tent(small.cview(), current, got.view(), bits, 2);
          shader_up(small.cview(), current, want.view(), bits);
          INFO((hostile ? "hostile " : "") << w << "x" << h << " bits " << bits << " add " << add);
          CHECK(test::same_bits_nan_agnostic(got.cview(), want.cview()));
        }
      }
    }
}

TEST_CASE("mip stages keep a constant field: the weights sum to exactly 1", "[mip]") {
  // Down: 5 x 0.125 + 4 x 0.03125 + 4 x 0.0625 = 1; tent: 0.25 + 4 x 0.125 + 4 x 0.0625 = 1.
  // Every weight is a power of two, so with c = 3 every product and sum is exact.
  Image src(45, 30);
  for (float& v : src.values()) v = 3.0f;
  Image down(22, 15), up(45, 30);
  downsample(src.cview(), down.view(), DownsampleOptions{}, 1);
  upsample_tent(down.cview(), src.cview(), up.view(), 0, 1);
  for (int y = 0; y < 15; ++y)
    for (int x = 0; x < 22; ++x) REQUIRE(down.pixel(x, y)[1] == 3.0f);
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 45; ++x) REQUIRE(up.pixel(x, y)[0] == 6.0f);
  ImageF64 src64 = convert_image<double>(src.cview()), down64(22, 15);
  downsample(src64.cview(), down64.view(), DownsampleOptions{}, 1);
  CHECK(down64.pixel(21, 14)[2] == 3.0);
}

TEST_CASE("mip_support is conservative and not trivial", "[mip]") {
  // Sparse nonzero texels (some -0 and NaN, which count as nonzero) in a zero level: outside the
  // support the full stage computes exactly +0; the support leaves most texels out.
  for (auto [w, h] : {std::pair{97, 61}, {40, 40}, {3, 2}}) {
    Image src(w, h);
    std::uint32_t s = 5u + w;
    for (int i = 0; i < 6; ++i) {
      s = s * 1664525u + 1013904223u;
      float* p = src.pixel(int(s % unsigned(w)), int((s >> 12) % unsigned(h)));
      p[0] = i == 0 ? -0.0f : i == 1 ? NAN : 2.5f;
    }
    std::vector<std::uint8_t> mask(src.pixel_count());
    nonzero_support(src.cview(), mask.data(), 1);
    const int tw = std::max(1, w / 2), th = std::max(1, h / 2);
    for (int reach : {1, 2}) {
      const int dw = reach == 2 ? tw : w * 2, dh = reach == 2 ? th : h * 2;  // down / up
      Image full(dw, dh);
      if (reach == 2) downsample(src.cview(), full.view(), DownsampleOptions{}, 1);
      else upsample_tent(src.cview(), ConstImageView{}, full.view(), 0, 1);
      std::vector<std::uint8_t> active(full.pixel_count());
      const std::size_t n = mip_support<float>(mask.data(), w, h, nullptr, dw, dh, reach, 0,
                                               active.data(), 2);
      std::size_t outside_nonzero = 0;
      for (int y = 0; y < dh; ++y)
        for (int x = 0; x < dw; ++x) {
          if (active[std::size_t(y) * dw + x]) continue;
          const float* p = full.pixel(x, y);
          for (int c = 0; c < 3; ++c) outside_nonzero += !(p[c] == 0.0f && !std::signbit(p[c]));
        }
      INFO(w << "x" << h << " reach " << reach << " support " << n << " of " << full.pixel_count());
      CHECK(outside_nonzero == 0u);
      CHECK(n > 0u);
      if (w > 10) CHECK(n < full.pixel_count() / 2);
    }
    // up.k adds its own level's texel: one nonzero texel of `current` where the small level is
    // zero around it must be in the support (through `also`), and is where up.k is nonzero.
    const int uw = w * 2, uh = h * 2;
    Image current(uw, uh);
    current.pixel(uw - 1, 0)[1] = 1.0f;
    std::vector<std::uint8_t> also(current.pixel_count()), active(current.pixel_count());
    nonzero_support(current.cview(), also.data(), 1);
    Image zero_small(w, h);
    std::vector<std::uint8_t> none(zero_small.pixel_count(), 0);
    const std::size_t n = mip_support<float>(none.data(), w, h, also.data(), uw, uh, 1, 0,
                                             active.data(), 1);
    Image up(uw, uh);
    upsample_tent(zero_small.cview(), current.cview(), up.view(), 0, 1);
    INFO(w << "x" << h << " up.k with its own texel");
    CHECK(n == 1u);
    CHECK(active[std::size_t(uw - 1)] == 1);
    CHECK(up.pixel(uw - 1, 0)[1] == 1.0f);
  }
}

TEST_CASE("the adaptive mip plan gives the full plan's bits and skips per level", "[mip][determinism]") {
  auto mip = [](PlanMode plan) {
    BloomParams p;
    p.method = Method::mip;
    p.plan = plan;
    return p;
  };
  for (const auto& [name, scene] : test::scenes_and_corpus()) {
    INFO(name);
    CHECK(test::bit_identical(test::run_output(scene, mip(PlanMode::full)).cview(),
                              test::run_output(scene, mip(PlanMode::adaptive)).cview()));
  }
  // Karis, f16 storage, f64, propagated NaN/Inf, after-tonemap composite.
  const Image demo = make_scene("demo", 320, 180);
  for (auto [storage, precision, karis] : {std::tuple{Storage::f16, Precision::f32, true},
                                           {Storage::f32, Precision::f64, false},
                                           {Storage::f32, Precision::f32, true}}) {
    BloomParams full = mip(PlanMode::full), adaptive = mip(PlanMode::adaptive);
    for (BloomParams* p : {&full, &adaptive}) {
      p->storage = storage;
      p->precision = precision;
      p->karis = karis;
      p->nonfinite = NonFinite::propagate;
      p->composite = CompositeOrder::after_tonemap;
    }
    INFO(to_string(storage) << " " << to_string(precision) << " karis " << karis);
    CHECK(test::bit_identical(test::run_output(demo, full).cview(),
                              test::run_output(demo, adaptive).cview()));
  }
  // The demo's lights: the lower down levels are mostly left out.
  BloomParams p = mip(PlanMode::adaptive);
  const StageTrace t = execute(make_plan(p, demo.cview()), demo.cview());
  double down2 = -1;
  for (const auto& [stage, frac] : t.skipped_fraction)
    if (stage == "down.2") down2 = frac;
  CHECK(down2 > 0.9);
  // Nothing bright: the whole chain is left out, and the output is still the full plan's.
  p.threshold = 1e30f;
  const StageTrace none = execute(make_plan(p, demo.cview()), demo.cview());
  REQUIRE(none.skipped_fraction.size() == 12u);  // down.1..6, up.5..1, bloom
  for (const auto& [stage, frac] : none.skipped_fraction) {
    INFO(stage);
    CHECK(frac == 1.0);
  }
  BloomParams f = mip(PlanMode::full);
  f.threshold = 1e30f;
  CHECK(test::bit_identical(test::run_output(demo, f).cview(), none.final_image().cview()));
}
