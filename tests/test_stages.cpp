// The per-pixel stages against closed forms written out by hand.
#include <sys/mman.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <cfloat>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <random>
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
template <class T>
BasicImage<T> one_pixel(T r, T g, T b, T a = 1) {
  BasicImage<T> img(1, 1);
  T* p = img.pixel(0, 0);
  p[0] = r; p[1] = g; p[2] = b; p[3] = a;
  return img;
}
}  // namespace

TEMPLATE_TEST_CASE("threshold is strict: luminance exactly at it is not bright", "[stages]",
                   float, double) {
  using T = TestType;
  // L(1, 1, 1) = 0.2126 + 0.7152 + 0.0722 = 1 exactly in float and double (left to right).
  CHECK(luminance(T(1), T(1), T(1)) == T(1));
  const T up = std::nextafter(T(1), T(2));
  for (auto [v, bright] : {std::pair<T, bool>{T(1), false}, {up, true}, {std::nextafter(T(1), T(0)), false}}) {
    BasicImage<T> src = one_pixel<T>(v, v, v), dst(1, 1);
    extract_bright(src.cview(), dst.view(), T(1), 1);
    INFO("value " << v);
    CHECK(dst.pixel(0, 0)[0] == (bright ? v : T(0)));
    CHECK(dst.pixel(0, 0)[3] == T(1));
  }
  // NaN luminance is not bright.
  BasicImage<T> nan = one_pixel<T>(T(NAN), 0, 0), dst(1, 1);
  extract_bright(nan.cview(), dst.view(), T(1), 1);
  CHECK(dst.pixel(0, 0)[0] == T(0));
}

TEMPLATE_TEST_CASE("extract_bright into a zeroed image writes only bright pixels and gives their "
                   "nonzero mask", "[stages]", float, double) {
  using T = TestType;
  // One row of hostile pixels, each followed by its expected (bright, nonzero): luminance
  // 0.2126 r + 0.7152 g + 0.0722 b against threshold 1 (strict), nonzero meaning some channel's
  // bits are not +0's (-0, NaN and Inf count).
  const T inf = std::numeric_limits<T>::infinity(), nan = std::numeric_limits<T>::quiet_NaN();
  struct Case {
    T r, g, b;
    bool bright, nonzero;
  };
  const std::vector<Case> cases = {
      {T(0), T(0), T(0), false, false},       {T(1), T(1), T(1), false, false},  // tie
      {T(2), T(2), T(2), true, true},         {T(10), T(0), T(0), true, true},   // L = 2.126
      {T(-0.0), T(5), T(0), true, true},      // -0 in a bright pixel counts
      {T(0), T(0), T(20), true, true},        // L = 1.444
      {inf, T(0), T(0), true, true},          {nan, T(9), T(9), false, false},   // NaN L
      {T(-50), T(0), T(0), false, false},     {T(0), T(3), T(0), true, true},
      {T(0.5), T(0.5), T(0.5), false, false}, {T(100), T(-1), T(0), true, true},
  };
  const int w = int(cases.size());
  BasicImage<T> src(w, 1);
  for (int x = 0; x < w; ++x) {
    T* p = src.pixel(x, 0);
    p[0] = cases[x].r;
    p[1] = cases[x].g;
    p[2] = cases[x].b;
    p[3] = T(1);
  }
  BasicImage<T> sparse = BasicImage<T>::zeroed(w, 1);
  std::vector<std::uint8_t> nonzero(w, 7);
  extract_bright(src.cview(), sparse.view(), T(1), 1, /*dst_zeroed=*/true, nonzero.data());
  for (int x = 0; x < w; ++x) {
    INFO("pixel " << x);
    CHECK(bool(nonzero[x]) == cases[x].nonzero);
    CHECK(nonzero[x] <= 1);
    const T* d = sparse.pixel(x, 0);
    if (cases[x].bright) {
      for (int c = 0; c < 3; ++c)
        CHECK(std::memcmp(&d[c], &src.pixel(x, 0)[c], sizeof(T)) == 0);
      CHECK(d[3] == T(1));
    } else {  // left alone: +0 everywhere, alpha included
      for (int c = 0; c < 4; ++c) CHECK((d[c] == T(0) && !std::signbit(d[c])));
    }
  }
  // Each case alone among dark pixels, at every position of rows of 1 to 13 pixels: the sweep
  // into a zeroed image takes whole groups of pixels at once and the rest one by one, so a
  // bright pixel must be found wherever it sits in a group or in the tail.
  const T dark_value = T(0.25);  // luminance 0.25: not bright, written nowhere, nonzero 0
  for (std::size_t ci = 0; ci < cases.size(); ++ci)
    for (int width = 1; width <= 13; ++width)
      for (int at = 0; at < width; ++at) {
        BasicImage<T> row(width, 1, dark_value);
        T* p = row.pixel(at, 0);
        p[0] = cases[ci].r;
        p[1] = cases[ci].g;
        p[2] = cases[ci].b;
        BasicImage<T> into = BasicImage<T>::zeroed(width, 1);
        std::vector<std::uint8_t> mask(width, 7);
        extract_bright(row.cview(), into.view(), T(1), 1, true, mask.data());
        for (int x = 0; x < width; ++x) {
          const bool is_case = x == at;
          INFO("case " << ci << ", width " << width << ", at " << at << ", pixel " << x);
          REQUIRE(int(mask[x]) == int(is_case && cases[ci].nonzero));
          const T* d = into.pixel(x, 0);
          if (is_case && cases[ci].bright) {
            for (int c = 0; c < 3; ++c) REQUIRE(std::memcmp(&d[c], &p[c], sizeof(T)) == 0);
            REQUIRE(d[3] == T(1));
          } else {
            for (int c = 0; c < 4; ++c) REQUIRE((d[c] == T(0) && !std::signbit(d[c])));
          }
        }
      }
  // Below a negative threshold black is bright but writes +0: not in the nonzero mask; -0 is.
  BasicImage<T> dark(2, 1, T(0));
  dark.pixel(1, 0)[0] = T(-0.0);
  BasicImage<T> out = BasicImage<T>::zeroed(2, 1);
  std::vector<std::uint8_t> nz(2, 7);
  extract_bright(dark.cview(), out.view(), T(-1), 1, true, nz.data());
  CHECK(nz[0] == 0);
  CHECK(nz[1] == 1);
  CHECK(out.pixel(0, 0)[3] == T(1));  // bright: written, alpha 1
  CHECK(std::signbit(out.pixel(1, 0)[0]));
}

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

TEST_CASE("the threshold-tie scene: exactly one band of three is bright", "[stages]") {
  const Image tie = make_scene("threshold-tie");  // 96x32; band 1 is x in [32, 64)
  BloomParams p;
  for (Precision prec : {Precision::f32, Precision::f64}) {
    p.precision = prec;
    CHECK(make_plan(p, tie.cview()).facts.bright_pixels == 32u * 32u);
  }
}

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

TEST_CASE("a run into a buffer of its own gives the bits of a run in the scene's buffer",
          "[stages]") {
  // Out of place the finishing stages stream their stores (finish_kernels.inc); in place they
  // store as usual. Odd widths leave every other row 16- but not 32-byte aligned; the second
  // run writes into the first's output buffer, as the Python module hands it back.
  for (const char* name : {"demo", "constant", "noise"})
    for (const int w : {257, 320}) {
      const Image scene = make_scene(name, w, 75);
      for (PlanMode mode : {PlanMode::full, PlanMode::adaptive}) {
        BloomParams p;
        p.plan = mode;
        const Plan plan = make_plan(p, scene.cview());
        const StageTrace own = execute(plan, Image(scene));
        StageTrace apart = execute(plan, scene.cview(), Image());
        INFO(name << " " << w << " " << to_string(mode));
        CHECK(test::bit_identical(own.final_image().cview(), apart.final_image().cview()));
        Image reused = std::move(apart.stages.back().image);
        const float* buffer = reused.data();
        const StageTrace again = execute(plan, scene.cview(), std::move(reused));
        CHECK(again.final_image().data() == buffer);
        CHECK(test::bit_identical(own.final_image().cview(), again.final_image().cview()));
      }
    }
}

TEST_CASE("output_in_given_buffer: the output is in the buffer handed over, wherever it says so",
          "[stages]") {
  // Every plan, blur, storage and method, a sparse and a dense scene, one with NaN (sanitised
  // in place first): where output_in_given_buffer is true, the output's buffer is the scene's
  // (taken over) or the output buffer's (given), and its bits are those of a run on a copy;
  // where it is false (mip, f64, kept stages) the run still gives those bits.
  Image nan_scene = make_scene("demo", 96, 64);
  nan_scene.data()[4 * (10 * 96 + 7)] = std::numeric_limits<float>::quiet_NaN();
  const std::vector<std::pair<const char*, Image>> scenes = {
      {"demo", make_scene("demo", 96, 64)}, {"constant", make_scene("constant", 96, 64)},
      {"nan", nan_scene}};
  int handed = 0;
  for (const auto& [name, scene] : scenes)
    for (Method method : {Method::gaussian, Method::mip})
      for (Precision precision : {Precision::f32, Precision::f64})
        for (PlanMode mode : {PlanMode::full, PlanMode::adaptive})
          for (BlurImpl blur : {BlurImpl::fast, BlurImpl::reference, BlurImpl::approx})
            for (Storage storage : {Storage::f32, Storage::f16})
              for (bool keep : {false, true}) {
                BloomParams p;
                p.method = method;
                p.precision = precision;
                p.plan = mode;
                p.blur = blur;
                p.storage = storage;
                ExecuteOptions eo;
                eo.keep_all = keep;
                const Plan plan = make_plan(p, scene.cview());
                const StageTrace copy = execute(plan, scene.cview(), eo);
                Image owned = scene;
                const float* scene_buffer = owned.data();
                const StageTrace in_place = execute(plan, std::move(owned), eo);
                Image out = Image::uninitialised(96, 64);
                const float* out_buffer = out.data();
                const StageTrace apart = execute(plan, scene.cview(), std::move(out), eo);
                INFO(name << " " << to_string(method) << " " << to_string(precision) << " "
                          << to_string(mode) << " " << to_string(blur) << " "
                          << to_string(storage) << " keep " << keep);
                CHECK(test::bit_identical(copy.final_image().cview(),
                                          in_place.final_image().cview()));
                CHECK(test::bit_identical(copy.final_image().cview(),
                                          apart.final_image().cview()));
                if (output_in_given_buffer(p, eo)) {
                  ++handed;
                  CHECK(in_place.final_image().data() == scene_buffer);
                  CHECK(apart.final_image().data() == out_buffer);
                }
              }
  CHECK(handed == 3 * 2 * 3 * 2);  // f32, gaussian, not kept: every scene, plan, blur, storage
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

TEST_CASE("a dense scene: at least 10% of the pixels bright, on at least half the rows",
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

  // From the scan: the demo with a low threshold is dense, at the default one it is not; the
  // full plan never marks it (it tracks nothing).
  const Image demo = make_scene("demo", 320, 180);
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
  CHECK_FALSE(has(ts, "bright+blur.1-10+composite+tonemap+output"));
  CHECK(has(ts, "blur.1"));
}

TEST_CASE("tone map against 1 - exp(-x) closed forms", "[stages]") {
  ImageF64 h = one_pixel<double>(1.0, 2.0, 1e-10), m(1, 1);
  tonemap(h.cview(), m.view(), 1.0, 1);
  CHECK(m.pixel(0, 0)[0] == Approx(0.6321205588285577).epsilon(1e-15));
  CHECK(m.pixel(0, 0)[1] == Approx(0.8646647167633873).epsilon(1e-15));
  // f64 uses -expm1: full relative precision for tiny x (1 - exp(-x) would cancel to 0).
  CHECK(m.pixel(0, 0)[2] == Approx(9.999999999500001e-11).epsilon(1e-14));

  Image hf = one_pixel<float>(1.0f, 2.0f, 1e-10f), mf(1, 1);
  tonemap(hf.cview(), mf.view(), 1.0f, 1);
  CHECK(mf.pixel(0, 0)[0] == Approx(0.6321205588285577).epsilon(2e-7));
  CHECK(mf.pixel(0, 0)[1] == Approx(0.8646647167633873).epsilon(2e-7));
  // 1 - expf(-1e-10f) would cancel to 0; the f32 path's series keeps it (stages.cpp).
  CHECK(mf.pixel(0, 0)[2] == Approx(9.999999999500001e-11).epsilon(2e-7));
  // Exposure scales the argument: x = 0.5 * 2 = 1.
  ImageF64 e = one_pixel<double>(0.5, 0.5, 0.5);
  tonemap(e.cview(), m.view(), 2.0, 1);
  CHECK(m.pixel(0, 0)[0] == Approx(0.6321205588285577).epsilon(1e-15));
}

TEST_CASE("f32 tone map keeps relative precision over 40 decades of x", "[stages]") {
  // Against -expm1 in double (an independent evaluation): relative error below 4 ULP for
  // x = hdr * exposure from 1e-30 to 20, both signs below 0.5 (negative HDR input).
  double worst = 0;
  for (double x = 1e-30; x < 20; x *= 1.07) {
    for (double sx : {x, -x}) {
      if (sx < -0.5) continue;
      const float h = static_cast<float>(sx);
      Image in = test::constant_image(1, 1, h), out(1, 1);
      tonemap(in.cview(), out.view(), 1.0f, 1);
      const double truth = -std::expm1(-double(h));
      worst = std::max(worst, std::fabs(out.pixel(0, 0)[0] - truth) / std::fabs(truth));
    }
  }
  CHECK(worst < 4 * 5.96e-8);
}

TEST_CASE("gamma against pow closed forms, negatives clamp to 0, gamma 1 is the identity",
          "[stages]") {
  ImageF64 x = one_pixel<double>(0.5, 0.25, -0.5, 0.75), y(1, 1);
  encode_output(x.cview(), y.view(), 2.2, 1);
  CHECK(y.pixel(0, 0)[0] == Approx(0.7297400528407231).epsilon(1e-15));  // 0.5^(1/2.2)
  CHECK(y.pixel(0, 0)[1] == Approx(0.5325205447199813).epsilon(1e-15));  // 0.25^(1/2.2)
  CHECK(y.pixel(0, 0)[2] == 0.0);
  CHECK(y.pixel(0, 0)[3] == 0.75);  // alpha carried through
  encode_output(x.cview(), y.view(), 1.0, 1);
  CHECK(y.pixel(0, 0)[0] == 0.5);
  CHECK(y.pixel(0, 0)[1] == 0.25);

  Image xf = one_pixel<float>(0.5f, 0.25f, 0.0f), yf(1, 1);
  encode_output(xf.cview(), yf.view(), 2.2f, 1);
  CHECK(yf.pixel(0, 0)[0] == Approx(0.7297400528407231).epsilon(3e-7));
  CHECK(yf.pixel(0, 0)[2] == 0.0f);
}

TEST_CASE("composite adds strength * bloom and keeps the scene's alpha", "[stages]") {
  Image s = one_pixel<float>(1.0f, 0.0f, -1.0f, 0.5f), b = one_pixel<float>(3.0f, 4.0f, 2.0f),
        d(1, 1);
  composite(s.cview(), b.cview(), d.view(), 0.5f, 1);
  CHECK(d.pixel(0, 0)[0] == 2.5f);
  CHECK(d.pixel(0, 0)[1] == 2.0f);
  CHECK(d.pixel(0, 0)[2] == 0.0f);
  CHECK(d.pixel(0, 0)[3] == 0.5f);
}

TEST_CASE("non-finite policies zero, clamp (per storage), propagate, and their counts", "[stages]") {
  Image src(2, 1);
  const float in[8] = {NAN, INFINITY, -INFINITY, 1.0f, -2.0f, 0.5f, 3.0f, NAN};
  std::copy(in, in + 8, src.data());
  Image dst(2, 1);
  NonFiniteCounts c = sanitize(src.cview(), dst.view(), NonFinite::zero, Storage::f32, 1);
  CHECK((c.nan == 2 && c.pos_inf == 1 && c.neg_inf == 1));
  const float zero[8] = {0, 0, 0, 1, -2, 0.5f, 3, 0};
  for (int i = 0; i < 8; ++i) CHECK(dst.data()[i] == zero[i]);

  sanitize(src.cview(), dst.view(), NonFinite::clamp, Storage::f32, 1);
  CHECK(dst.data()[0] == 0.0f);
  CHECK(dst.data()[1] == 0x1p120f);  // the range guard, 2^120
  CHECK(dst.data()[2] == -0x1p120f);
  sanitize(src.cview(), dst.view(), NonFinite::clamp, Storage::f16, 1);
  CHECK(dst.data()[1] == 65504.0f);
  CHECK(dst.data()[2] == -65504.0f);

  sanitize(src.cview(), dst.view(), NonFinite::propagate, Storage::f32, 1);
  CHECK(std::isnan(dst.data()[0]));
  CHECK(dst.data()[1] == INFINITY);
  CHECK(dst.data()[4] == -2.0f);
}

TEST_CASE("sanitize over clean and dirty rows, in place and not: every value and count",
          "[stages]") {
  // sanitize leaves a row without NaN, Inf or a value beyond 2^120 as it is (in place it writes
  // nothing there). Rows here: clean (with -0, denormals and 2^120 itself), or one special
  // anywhere in them, first or last value included; the expected values are the policy read
  // value by value, the counts a classification written here.
  const int w = 13, h = 29;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-4.0f, 4.0f);
  const float specials[] = {NAN, INFINITY, -INFINITY, 1.7e38f, -3e37f};
  const float clean[] = {-0.0f, 1e-45f, 0x1p120f, -0x1p120f};
  Image src(w, h);
  for (int y = 0; y < h; ++y) {
    float* r = src.view().row(y);
    for (int i = 0; i < 4 * w; ++i) r[i] = u(rng);
    r[(y * 7) % (4 * w)] = clean[y % 4];
    if (y % 3 == 1) r[y % 2 ? 0 : 4 * w - 1] = specials[y % 5];
    if (y % 3 == 2) r[(y * 11) % (4 * w)] = specials[(y + 2) % 5];
  }
  NonFiniteCounts want;
  for (float v : src.values()) {
    if (std::isnan(v)) ++want.nan;
    else if (std::isinf(v)) ++(v > 0 ? want.pos_inf : want.neg_inf);
    else if (std::fabs(v) > 0x1p120f) ++want.out_of_range;
  }
  REQUIRE(want.total() + want.out_of_range > 10u);
  for (NonFinite policy : {NonFinite::zero, NonFinite::clamp, NonFinite::propagate})
    for (Storage storage : {Storage::f32, Storage::f16})
      for (bool in_place : {true, false})
        for (int threads : {1, 2}) {
          Image dst = in_place ? src : Image(w, h, 7.0f);
          const NonFiniteCounts c =
              sanitize(in_place ? dst.cview() : src.cview(), dst.view(), policy, storage, threads);
          INFO("policy " << int(policy) << " storage " << int(storage) << " in place " << in_place
                         << " threads " << threads);
          CHECK((c.nan == want.nan && c.pos_inf == want.pos_inf && c.neg_inf == want.neg_inf &&
                 c.out_of_range == want.out_of_range));
          bool same = true;
          for (std::size_t i = 0; i < src.values().size(); ++i) {
            const float v = src.values()[i], got = dst.values()[i];
            float expect = v;
            if (std::isnan(v)) expect = policy == NonFinite::propagate ? v : 0.0f;
            else if (std::isinf(v))
              expect = policy == NonFinite::propagate ? v
                       : policy == NonFinite::zero    ? 0.0f
                       : std::copysign(storage == Storage::f16 ? 65504.0f : 0x1p120f, v);
            else if (std::fabs(v) > 0x1p120f) expect = std::copysign(0x1p120f, v);
            same = same && (std::isnan(expect) ? std::isnan(got)
                                               : std::memcmp(&expect, &got, 4) == 0);
          }
          CHECK(same);
        }
}

TEST_CASE("finite values beyond 2^120 are clamped to it and counted, under every policy",
          "[stages]") {
  Image src(1, 1), dst(1, 1);
  const float in[4] = {1.7e38f, -3.0e37f, 0x1p120f, 1.0f};
  std::copy(in, in + 4, src.data());
  for (NonFinite policy : {NonFinite::zero, NonFinite::clamp, NonFinite::propagate}) {
    const NonFiniteCounts c = sanitize(src.cview(), dst.view(), policy, Storage::f32, 1);
    CHECK(c.out_of_range == 2u);  // 2^120 itself is in range
    CHECK(c.total() == 0u);
    CHECK(dst.data()[0] == 0x1p120f);
    CHECK(dst.data()[1] == -0x1p120f);
    CHECK(dst.data()[2] == 0x1p120f);
    CHECK(dst.data()[3] == 1.0f);
  }
}

TEST_CASE("f16 storage rounds every stored value", "[stages]") {
  Image img = one_pixel<float>(1.0f + 1.0f / 4096, 65519.0f, 70000.0f, 0.1f);
  store(img.view(), Storage::f16, HalfRounding::nearest_even, 1);
  CHECK(img.pixel(0, 0)[0] == 1.0f);       // 1 + 2^-12 is below the tie 1 + 2^-11
  CHECK(img.pixel(0, 0)[1] == 65504.0f);
  CHECK(img.pixel(0, 0)[2] == INFINITY);   // above 65520: overflows when stored as half
  CHECK(img.pixel(0, 0)[3] == 0.0999755859375f);  // half(0.1) = 1638 * 2^-14
  Image keep = one_pixel<float>(0.1f, 0.2f, 0.3f);
  store(keep.view(), Storage::f32, HalfRounding::nearest_even, 1);
  CHECK(keep.pixel(0, 0)[0] == 0.1f);
}

TEST_CASE("PNG codes: round(clamp(x, 0, 1) * 255)", "[stages]") {
  CHECK(quantize_8bit(-1.0f) == 0);
  CHECK(quantize_8bit(0.5f / 255) == 1);  // 0.5 rounds away from zero
  CHECK(quantize_8bit(0.49f / 255) == 0);
  CHECK(quantize_8bit(0.5f) == 128);      // 127.5 -> 128
  CHECK(quantize_8bit(1.0f) == 255);
  CHECK(quantize_8bit(7.0f) == 255);
  CHECK(quantize_8bit(NAN) == 0);
}

TEST_CASE("parameters are validated, not clamped", "[params]") {
  BloomParams p;
  REQUIRE_NOTHROW(validate(p));
  auto bad = [](auto mutate) {
    BloomParams q;
    mutate(q);
    return q;
  };
  CHECK_THROWS_WITH(validate(bad([](BloomParams& q) { q.gamma = 0; })), Catch::Contains("--gamma"));
  CHECK_THROWS_WITH(validate(bad([](BloomParams& q) { q.exposure = -1; })),
                    Catch::Contains("--exposure"));
  CHECK_THROWS_WITH(validate(bad([](BloomParams& q) { q.threshold = NAN; })),
                    Catch::Contains("--threshold"));
  CHECK_THROWS_WITH(validate(bad([](BloomParams& q) { q.passes = -1; })),
                    Catch::Contains("--passes"));
  CHECK_THROWS_WITH(validate(bad([](BloomParams& q) { q.strength = INFINITY; })),
                    Catch::Contains("--strength"));
  CHECK_THROWS_WITH(parse_kernel("gauss"), Catch::Contains("discrete9, linear5"));
  CHECK_THROWS_WITH(parse_nonfinite("ignore"), Catch::Contains("zero, clamp, propagate, error"));
}

TEST_CASE("prefault makes pages resident and leaves every value as it was", "[stages]") {
  // 64 pages of a fresh anonymous mapping, one written with a pattern, the range starting and
  // ending inside a page: after prefault the pages wholly inside the range are resident (mincore;
  // checked where the kernel has MADV_POPULATE_WRITE, without it the call does nothing), and
  // every byte still reads as before: the pattern or zero.
  const std::size_t pg = std::size_t(::sysconf(_SC_PAGESIZE)), npages = 64;
  void* m = ::mmap(nullptr, npages * pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1,
                   0);
  REQUIRE(m != MAP_FAILED);
  auto* bytes = static_cast<unsigned char*>(m);
  std::memset(bytes + 10 * pg, 0xA5, pg);
  bloomref::prefault(bytes + 100, npages * pg - 200);
  std::vector<unsigned char> in_core(npages);
  REQUIRE(::mincore(m, npages * pg, in_core.data()) == 0);
  std::size_t resident_inside = 0;
  for (std::size_t i = 1; i + 1 < npages; ++i) resident_inside += in_core[i] & 1;
#ifdef MADV_POPULATE_WRITE
  // Whether this kernel has the call: asked of a page of its own.
  void* probe = ::mmap(nullptr, pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  REQUIRE(probe != MAP_FAILED);
  const bool kernel_has_it = ::madvise(probe, pg, MADV_POPULATE_WRITE) == 0;
  ::munmap(probe, pg);
  if (kernel_has_it) CHECK(resident_inside == npages - 2);
#endif
  std::size_t as_before = 0;
  for (std::size_t i = 0; i < npages * pg; ++i)
    as_before += bytes[i] == ((i / pg == 10) ? 0xA5 : 0);
  CHECK(as_before == npages * pg);
  ::munmap(m, npages * pg);
}

TEST_CASE("a freed large image buffer serves the next image of its size, with that image's values",
          "[stages]") {
  // A 2048x1024 RGBA float image (32 MiB) written whole, then freed: the next image of that size
  // gets the same memory, still resident (mincore: a buffer handed back to the kernel and mapped
  // afresh would have no page resident before it is written); freed again, it serves
  // Image::zeroed, which reads all zero over that dirty memory.
  const int w = 2048, h = 1024;
  const std::size_t bytes = std::size_t(w) * h * bloomref::kChannels * sizeof(float);
  const std::size_t pg = std::size_t(::sysconf(_SC_PAGESIZE));
  const void* first = nullptr;
  {
    Image a = Image::uninitialised(w, h);
    std::fill(a.data(), a.data() + a.pixel_count() * bloomref::kChannels, -3.25f);
    first = a.data();
  }
  Image b = Image::uninitialised(w, h);
  CHECK(static_cast<const void*>(b.data()) == first);
  {
    const auto begin = (reinterpret_cast<std::uintptr_t>(b.data()) + pg - 1) / pg * pg;
    const std::size_t n = (reinterpret_cast<std::uintptr_t>(b.data()) + bytes - begin) / pg;
    std::vector<unsigned char> in_core(n);
    REQUIRE(::mincore(reinterpret_cast<void*>(begin), n * pg, in_core.data()) == 0);
    std::size_t resident = 0;
    for (unsigned char v : in_core) resident += v & 1;
    CHECK(resident == n);
  }
  b = Image();
  const Image z = Image::zeroed(w, h);
  CHECK(static_cast<const void*>(z.data()) == first);
  CHECK(std::count(z.data(), z.data() + z.pixel_count() * bloomref::kChannels, 0.0f) ==
        std::ptrdiff_t(z.pixel_count() * bloomref::kChannels));
}

namespace {
// Whether every mapping of this process that overlaps [begin, end) is advised for transparent
// huge pages ("hg" among its VmFlags in /proc/self/smaps, proc(5)); false where none overlaps.
bool huge_advised(std::uintptr_t begin, std::uintptr_t end) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool overlaps = false, any = false, all = true;
  while (std::getline(smaps, line)) {
    unsigned long lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (line.rfind("VmFlags:", 0) == 0) {
      if (overlaps) {
        any = true;
        all = all && (line + " ").find(" hg ") != std::string::npos;
      }
    } else if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      overlaps = lo < end && begin < hi;
    }
  }
  return any && all;
}
}  // namespace

TEST_CASE("advise_huge_pages: new buffers of 4 MiB or more advised for huge pages, whole 2 MiB "
          "pages",
          "[stages]") {
  // An image of 6 MiB (under the 16 MiB of kept buffers: always a new one), before and after
  // the call: only after it are its whole 2 MiB pages advised (the kernel's own record of the
  // mappings, not the allocator's); one just under 4 MiB never is.
  if (::access("/sys/kernel/mm/transparent_hugepage", F_OK) != 0) {
    WARN("this kernel has no transparent huge pages: nothing to check");
    return;
  }
  constexpr std::uintptr_t huge = std::uintptr_t(2) << 20;
  const auto inside = [&](const Image& img) {
    const auto b = reinterpret_cast<std::uintptr_t>(img.data());
    const std::uintptr_t first = (b + huge - 1) / huge * huge;
    const std::uintptr_t last = (b + img.pixel_count() * sizeof(float) * 4) / huge * huge;
    return std::make_pair(first, last);
  };
  const Image before = Image::uninitialised(1024, 384);  // 6 MiB
  const auto [b0, b1] = inside(before);
  REQUIRE(b1 - b0 >= huge);
  CHECK_FALSE(huge_advised(b0, b1));
  bloomref::advise_huge_pages(true);
  const Image after = Image::uninitialised(1024, 384);
  const Image small = Image::uninitialised(1024, 255);  // 16 KiB under 4 MiB
  bloomref::advise_huge_pages(false);
  const auto [a0, a1] = inside(after);
  REQUIRE(a1 - a0 >= huge);
  CHECK(huge_advised(a0, a1));
  const auto [s0, s1] = inside(small);
  if (s0 < s1) CHECK_FALSE(huge_advised(s0, s1));
  // Off again: the next buffer is not advised.
  const Image later = Image::uninitialised(1024, 384);
  const auto [l0, l1] = inside(later);
  CHECK_FALSE(huge_advised(l0, l1));
}

TEST_CASE("zero_lazily and Image::zeroed give zero bytes over dirty memory, any alignment",
          "[stages]") {
  // Dirty heap memory (written with a pattern) at offsets that are not page-aligned, sizes below,
  // at and across page boundaries: every byte in the range becomes 0, the bytes around it keep
  // the pattern.
  const std::size_t page = 4096;
  std::vector<unsigned char> buf(8 * page + 64);
  for (std::size_t off : {std::size_t(0), std::size_t(1), std::size_t(63), page - 3, page}) {
    for (std::size_t n : {std::size_t(0), std::size_t(5), page, page + 7, 3 * page + 100,
                          6 * page}) {
      std::fill(buf.begin(), buf.end(), 0xA5);
      bloomref::zero_lazily(buf.data() + off, n);
      std::size_t zero = 0, kept = 0;
      for (std::size_t i = 0; i < buf.size(); ++i) {
        const bool inside = i >= off && i < off + n;
        zero += inside && buf[i] == 0;
        kept += !inside && buf[i] == 0xA5;
      }
      INFO("offset " << off << " bytes " << n);
      CHECK(zero == n);
      CHECK(kept == buf.size() - n);
    }
  }
  // Pages never written stay unwritten (the point of "lazily"): 64 fresh pages of an anonymous
  // mapping with one written in the middle (resident, dirty); after zero_lazily only that one is
  // resident (mincore, before anything reads the others), and every byte reads as zero.
  {
    const std::size_t pg = std::size_t(::sysconf(_SC_PAGESIZE)), npages = 64;
    void* m = ::mmap(nullptr, npages * pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS,
                     -1, 0);
    REQUIRE(m != MAP_FAILED);
    auto* bytes = static_cast<unsigned char*>(m);
    std::memset(bytes + 10 * pg, 0xA5, pg);
    bloomref::zero_lazily(bytes, npages * pg);
    std::vector<unsigned char> in_core(npages);
    REQUIRE(::mincore(m, npages * pg, in_core.data()) == 0);
    std::size_t resident = 0;
    for (unsigned char v : in_core) resident += v & 1;
    CHECK(resident <= 1);
    CHECK(std::count(bytes, bytes + npages * pg, 0) == std::ptrdiff_t(npages * pg));
    ::munmap(m, npages * pg);
  }
  for (int round = 0; round < 3; ++round) {
    {
      Image dirty(1024, 1024, -7.0f);  // 16 MiB: leaves dirty memory for the next allocation
    }
    const Image z = Image::zeroed(1024, 1024);
    CHECK(reinterpret_cast<std::uintptr_t>(z.data()) % 64 == 0);
    std::size_t nonzero = 0;
    for (float v : z.values()) nonzero += std::signbit(v) || v != 0.0f;
    CHECK(nonzero == 0);
  }
}

TEST_CASE("image buffers start on a cache line, the fill constructor fills, copies keep values",
          "[stages]") {
  for (auto [w, h] : {std::pair{1, 1}, {3, 7}, {1920, 1080}}) {
    Image img(w, h, 0.25f);
    CHECK(reinterpret_cast<std::uintptr_t>(img.data()) % 64 == 0);
    CHECK(std::count(img.values().begin(), img.values().end(), 0.25f) ==
          std::ptrdiff_t(img.values().size()));
    Image u = Image::uninitialised(w, h);
    CHECK(reinterpret_cast<std::uintptr_t>(u.data()) % 64 == 0);
    CHECK(u.values().size() == std::size_t(w) * h * kChannels);
    const Image copy = img;  // the allocator's copy: a new aligned buffer, same values
    CHECK(copy.data() != img.data());
    CHECK(reinterpret_cast<std::uintptr_t>(copy.data()) % 64 == 0);
    CHECK(copy.values() == img.values());
    ImageF64 d(w, h, -1.5);
    CHECK(reinterpret_cast<std::uintptr_t>(d.data()) % 64 == 0);
    CHECK(d.values().back() == -1.5);
  }
}
