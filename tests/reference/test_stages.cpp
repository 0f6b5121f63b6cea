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

TEST_CASE("the threshold-tie scene: exactly one band of three is bright", "[stages]") {
  const Image tie = make_scene("threshold-tie");  // 96x32; band 1 is x in [32, 64)
  BloomParams p;
  for (Precision prec : {Precision::f32, Precision::f64}) {
    p.precision = prec;
    CHECK(make_plan(p, tie.cview()).facts.bright_pixels == 32u * 32u);
  }
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
