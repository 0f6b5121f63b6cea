// The plan (plan.h): its scan of the scene against a value-by-value reading of the policy, the
// rows it finds dark left alone, its timing, and which scenes it calls dense.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/plan.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "test_util.h"

using namespace bloomref;

namespace {
// What the plan's scan must find, read value by value from the policy's definition (docs/design.md, "Specification":
// the input stage), written out here without the library's functions: NaN -> 0 unless
// propagated; +-Inf -> 0 (zero), +-the storage's largest value (clamp: 65504 for f16, 2^120 for
// f32) or itself (propagate); finite beyond 2^120 -> +-2^120 under every policy; bright when
// 0.2126 r + 0.7152 g + 0.0722 b, summed left to right in T, is above the threshold.
template <class T>
SceneFacts facts_by_hand(const Image& img, const BloomParams& p) {
  SceneFacts f;
  const double guard = std::ldexp(1.0, 120);
  const double largest = p.storage == Storage::f16 ? 65504.0 : guard;
  f.bright_rows.assign(std::size_t(img.height()), 0);
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const float* px = img.pixel(x, y);
      T v[3];
      for (int c = 0; c < 4; ++c) {
        const double d = px[c];
        double s = d;
        if (d != d) {
          ++f.nonfinite.nan;
          s = p.nonfinite == NonFinite::propagate ? d : 0.0;
        } else if (d == INFINITY || d == -INFINITY) {
          ++(d > 0 ? f.nonfinite.pos_inf : f.nonfinite.neg_inf);
          s = p.nonfinite == NonFinite::zero ? 0.0
              : p.nonfinite == NonFinite::clamp ? (d > 0 ? largest : -largest) : d;
        } else if (std::fabs(d) > guard) {
          ++f.nonfinite.out_of_range;
          s = d > 0 ? guard : -guard;
        }
        if (c < 3) v[c] = static_cast<T>(s);
      }
      T lum = v[0] * T(0.2126);
      lum = lum + v[1] * T(0.7152);
      lum = lum + v[2] * T(0.0722);
      if (lum > static_cast<T>(p.threshold)) {
        ++f.bright_pixels;
        f.bright_rows[std::size_t(y)] = 1;
      }
    }
  return f;
}
}  // namespace

TEST_CASE("extract_bright and mask_spans leave alone the rows the plan's scan found dark",
          "[stages][plan]") {
  // Rows 1 and 4 of six hold bright pixels (luminance 2.126 > 1); the others are dim. The scan
  // must flag exactly those rows; given the flags, the sweep into a zeroed image must give what
  // it gives without them, and a row flagged dark is not read (a bright pixel planted there
  // after the scan is not written: what the flag promises is the caller's, the plan's).
  Image src(9, 6, 0.25f);
  for (int x : {0, 4, 8}) src.pixel(x, 1)[0] = 10.0f;
  src.pixel(5, 4)[0] = 10.0f;
  BloomParams p;
  p.threads = 2;
  const SceneFacts facts = make_plan(p, src.cview()).facts;
  REQUIRE(facts.bright_rows == std::vector<std::uint8_t>{0, 1, 0, 0, 1, 0});
  Image plain = Image::zeroed(9, 6), hinted = Image::zeroed(9, 6);
  std::vector<std::uint8_t> m_plain(9 * 6, 0), m_hinted(9 * 6, 0);
  extract_bright(src.cview(), plain.view(), 1.0f, 2, true, m_plain.data());
  extract_bright(src.cview(), hinted.view(), 1.0f, 2, true, m_hinted.data(), facts.bright_rows.data());
  CHECK(test::bit_identical(plain.cview(), hinted.cview()));
  CHECK(m_plain == m_hinted);
  CHECK(std::count(m_hinted.begin(), m_hinted.end(), 1) == 4);
  RowSpans a, b;
  CHECK(mask_spans(m_plain.data(), 9, 6, a, 2) == 4);
  CHECK(mask_spans(m_hinted.data(), 9, 6, b, 2, facts.bright_rows.data()) == 4);
  for (int y = 0; y < 6; ++y) {
    REQUIRE(a[y].size() == b[y].size());
    for (std::size_t i = 0; i < a[y].size(); ++i)
      CHECK((a[y][i].x0 == b[y][i].x0 && a[y][i].x1 == b[y][i].x1));
  }
  src.pixel(3, 2)[1] = 10.0f;  // row 2 is flagged dark: left alone
  Image after = Image::zeroed(9, 6);
  std::vector<std::uint8_t> m_after(9 * 6, 0);
  extract_bright(src.cview(), after.view(), 1.0f, 2, true, m_after.data(), facts.bright_rows.data());
  CHECK(after.pixel(3, 2)[1] == 0.0f);
  CHECK(m_after == m_hinted);
  RowSpans c;
  m_after[2 * 9 + 3] = 1;  // and mask_spans takes a row flagged dark as empty
  CHECK(mask_spans(m_after.data(), 9, 6, c, 2, facts.bright_rows.data()) == 4);
  CHECK(c[2].empty());
}

TEST_CASE("the plan's scan finds what a value-by-value reading of the policy finds", "[stages][plan]") {
  // Beside the scenes and the corpus (NaN and Inf in BrightRingsNanInf.exr, values beyond 2^120
  // in scale.hdr and WideFloatRange.exr): rows of every width up to 4 vectors of the widest
  // row kernel and a tail (the kernels take 1, 2 or 4 pixels a vector), clean rows beside rows
  // with one non-finite value (in any channel, alpha too), and values within an ulp of the
  // threshold. Every instruction set's row kernel (scan_scene), and make_plan's.
  std::vector<std::pair<std::string, Image>> extra;
  for (int w : {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 13, 15, 16, 17, 19}) {
    Image img(w, 9);
    std::uint32_t state = 12345u + std::uint32_t(w);
    auto next = [&] { state = state * 1664525u + 1013904223u; return state >> 8; };
    for (int y = 0; y < img.height(); ++y)
      for (int x = 0; x < w; ++x) {
        float* px = img.pixel(x, y);
        for (int c = 0; c < 3; ++c) {
          float v = 1.0f;  // luminance of grey 1 is within rounding of the threshold 1
          for (std::uint32_t k = next() % 5; k-- > 0;)
            v = std::nextafter(v, next() % 2 ? 2.0f : 0.0f);
          px[c] = v;
        }
        px[3] = 1;
      }
    const float specials[] = {NAN, INFINITY, -INFINITY, 3e38f, -3e38f, 70000.0f};
    for (int y = 1; y < img.height(); y += 2)
      img.pixel(int(next() % std::uint32_t(w)), y)[next() % 4] = specials[(y / 2) % 6];
    extra.emplace_back("grey ties, width " + std::to_string(w), std::move(img));
  }
  for (auto& [name, img] : test::scenes_and_corpus(std::move(extra))) {
    for (NonFinite policy : {NonFinite::zero, NonFinite::clamp, NonFinite::propagate})
      for (Storage storage : {Storage::f32, Storage::f16})
        for (Precision prec : {Precision::f32, Precision::f64}) {
          BloomParams p;
          p.nonfinite = policy;
          p.storage = storage;
          p.precision = prec;
          p.threads = 2;
          const SceneFacts want = prec == Precision::f64 ? facts_by_hand<double>(img, p)
                                                         : facts_by_hand<float>(img, p);
          std::vector<std::pair<std::string, SceneFacts>> found = {
              {"make_plan", make_plan(p, img.cview()).facts}};
          for (BlurIsa isa : {BlurIsa::generic, BlurIsa::avx2, BlurIsa::avx512})
            if (blur_isa_available(isa))
              found.emplace_back(blur_isa_name(isa), scan_scene(img.cview(), p, isa));
          for (const auto& [how, got] : found) {
            INFO(name << ", " << to_string(policy) << ", " << to_string(storage) << ", "
                      << to_string(prec) << ", " << how);
            CHECK(got.bright_pixels == want.bright_pixels);
            CHECK(got.bright_rows == want.bright_rows);
            CHECK(got.nonfinite.nan == want.nonfinite.nan);
            CHECK(got.nonfinite.pos_inf == want.nonfinite.pos_inf);
            CHECK(got.nonfinite.neg_inf == want.nonfinite.neg_inf);
            CHECK(got.nonfinite.out_of_range == want.nonfinite.out_of_range);
          }
        }
  }
}

TEST_CASE("the plan's scan is a run's first timing and part of its total", "[stages][plan]") {
  const Image scene = make_scene("demo", 640, 360);
  for (PlanMode mode : {PlanMode::full, PlanMode::adaptive}) {
    BloomParams p;
    p.plan = mode;
    const Plan plan = make_plan(p, scene.cview());
    for (const StageTrace& t : {execute(plan, scene.cview()), execute(plan, Image(scene))}) {
      REQUIRE(!t.timings.empty());
      CHECK(t.timings[0].first == "plan");
      CHECK(t.timings[0].second == plan.facts.scan_ms);
      // The stages run one after another inside the run's own clock: their sum, the scan's
      // included, is at most the total.
      double sum = 0;
      for (const auto& [name, ms] : t.timings) sum += ms;
      CHECK(sum <= t.total_ms + 1e-9);
      CHECK(t.total_ms >= plan.facts.scan_ms);
    }
  }
}

TEST_CASE("a dense scene (10% of the pixels bright on half the rows) or a small one is blurred whole",
          "[stages][plan]") {
  SceneFacts f;
  f.width = 20;
  f.height = 10;
  auto rows = [&](int n) {  // the first n rows bright (which ones does not matter to the rule)
    f.bright_rows.assign(10, 0);
    std::fill_n(f.bright_rows.begin(), n, std::uint8_t(1));
  };
  rows(5);
  f.bright_pixels = 20;  // 10% of 200
  CHECK(dense_scene(f));
  f.bright_pixels = 19;
  CHECK_FALSE(dense_scene(f));
  f.bright_pixels = 200;
  rows(4);
  CHECK_FALSE(dense_scene(f));
  rows(10);
  CHECK(dense_scene(f));
  f.bright_rows.clear();  // no row facts (as for no scan): not dense
  CHECK_FALSE(dense_scene(f));

  // Small: at most 256x256 = 65,536 pixels, whatever is bright.
  SceneFacts s;
  s.width = 256;
  s.height = 256;
  CHECK(small_scene(s));
  s.width = 257;
  CHECK_FALSE(small_scene(s));
  s.width = 65536;
  s.height = 1;
  CHECK(small_scene(s));
  s.width = 65537;
  CHECK_FALSE(small_scene(s));

  // From the scan: the demo with a low threshold is dense, at the default one it is not; the
  // full plan never marks it (it tracks nothing).
  const Image demo = make_scene("demo", 480, 270);  // larger than a small scene
  BloomParams p;
  p.plan = PlanMode::adaptive;
  CHECK_FALSE(make_plan(p, demo.cview()).dense_scene);
  p.threshold = 0.05;
  const Plan dense = make_plan(p, demo.cview());
  CHECK(dense.dense_scene);
  p.plan = PlanMode::full;
  CHECK_FALSE(make_plan(p, demo.cview()).dense_scene);

  // The adaptive plan then blurs it as the full plan does: the bright stage inside the fused
  // blur, nothing skipped; on the sparse scene it tracks the support.
  auto has = [](const StageTrace& t, const std::string& name) {
    return std::any_of(t.timings.begin(), t.timings.end(),
                       [&](const auto& kv) { return kv.first == name; });
  };
  const StageTrace td = execute(dense, demo.cview());
  CHECK(has(td, "bright+blur.1-10+composite+tonemap+output"));
  REQUIRE(td.skipped_fraction.size() == 10u);
  for (const auto& [name, fraction] : td.skipped_fraction) CHECK(fraction == 0.0);
  p.plan = PlanMode::adaptive;
  p.threshold = 1.0;
  const StageTrace ts = execute(make_plan(p, demo.cview()), demo.cview());
  REQUIRE_FALSE(ts.skipped_fraction.empty());
  CHECK(ts.skipped_fraction.front().second > 0.5);  // blur.1: most texels left out

  // A small sparse scene (one bright texel at 63x63) is blurred whole too: nothing of the blur
  // left out, where at 640x480 the same scene's support is tracked.
  const Image small = make_scene("impulse", 63, 63);
  const Plan ps = make_plan(p, small.cview());
  CHECK(ps.small_scene);
  CHECK_FALSE(ps.dense_scene);
  const StageTrace tsmall = execute(ps, small.cview());
  CHECK(has(tsmall, "bright+blur.1-10+composite+tonemap+output"));
  REQUIRE(tsmall.skipped_fraction.size() == 10u);
  for (const auto& [name, fraction] : tsmall.skipped_fraction) CHECK(fraction == 0.0);
  const Image large = make_scene("impulse", 640, 480);
  const Plan pl = make_plan(p, large.cview());
  CHECK_FALSE(pl.small_scene);
  const StageTrace tlarge = execute(pl, large.cview());
  REQUIRE_FALSE(tlarge.skipped_fraction.empty());
  CHECK(tlarge.skipped_fraction.front().second > 0.99);  // one texel's support of 307,200
  p.plan = PlanMode::full;
  CHECK_FALSE(make_plan(p, small.cview()).small_scene);
}
