// The f32 oracle's exp and pow (stages.h: oracle_exp, oracle_pow) against an independent
// evaluation -- the C library's double exp and pow rounded to float -- and the fast finishing
// stages (tonemap_fast, encode_output_fast, finish_fast) against the staged reference, bit for
// bit, on hostile values.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

#include <Imath/half.h>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "test_util.h"

using namespace bloomref;

namespace {

std::uint32_t bits(float x) {
  std::uint32_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}

/// Distance in units in the last place between two finite floats of the same sign (the
/// ordered-integer trick); a large number for anything else.
std::int64_t ulps(float a, float b) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b) ? 0 : 1 << 30;
  if (a == b) return 0;
  if (std::signbit(a) != std::signbit(b)) return 1 << 30;
  return std::llabs(std::int64_t(bits(a)) - std::int64_t(bits(b)));
}

float from_bits(std::uint32_t u) {
  float x;
  std::memcpy(&x, &u, sizeof x);
  return x;
}

struct Agreement {
  std::int64_t n = 0, differ = 0, worst = 0;
  void add(float ours, float truth) {
    ++n;
    const std::int64_t d = ulps(ours, truth);
    if (d) ++differ;
    worst = std::max(worst, d);
  }
};

}  // namespace

TEST_CASE("oracle_exp is the correctly rounded exp on sampled floats", "[stages][oracle-math]") {
  // Every float bit pattern is equally likely, restricted to the arguments whose exp is neither
  // 0 nor Inf nor within the series branch's |x| < 0.5 only: [-104, 89] covers subnormal
  // results and the overflow edge.
  std::mt19937 rng(7);
  Agreement a;
  for (int i = 0; i < 400000; ++i) {
    const float x = from_bits(rng());
    if (!(std::fabs(x) <= 104.0f) || x > 89.0f) continue;
    a.add(oracle_exp(x), static_cast<float>(std::exp(static_cast<double>(x))));
  }
  // Uniform over [-104, 89] too (the bit sampling above is dense near 0).
  std::uniform_real_distribution<float> u(-104.0f, 89.0f);
  for (int i = 0; i < 400000; ++i) {
    const float x = u(rng);
    a.add(oracle_exp(x), static_cast<float>(std::exp(static_cast<double>(x))));
  }
  INFO(a.n << " values, " << a.differ << " differ, worst " << a.worst << " ulp");
  CHECK(a.n > 500000);
  CHECK(a.worst <= 1);
  CHECK(a.differ <= 2);  // the method's 1e-15 relative error: expected ~0.1 in this many
}

TEST_CASE("oracle_exp's special values and overflow edges", "[stages][oracle-math]") {
  const float inf = std::numeric_limits<float>::infinity();
  CHECK(oracle_exp(0.0f) == 1.0f);
  CHECK(oracle_exp(-0.0f) == 1.0f);
  CHECK(oracle_exp(inf) == inf);
  CHECK(bits(oracle_exp(-inf)) == bits(0.0f));
  CHECK(std::isnan(oracle_exp(std::numeric_limits<float>::quiet_NaN())));
  CHECK(oracle_exp(1e30f) == inf);
  CHECK(bits(oracle_exp(-1e30f)) == bits(0.0f));
  // ln(FLT_MAX) = 88.7228391...: the largest float below it has a finite exp, the next one
  // rounds to Inf (truth: the double exp rounded to float); e^-103.97 is the smallest
  // subnormal's neighbourhood.
  for (float x : {88.72283f, 88.72284f, 88.7229f, -87.33654f, -87.33655f, -103.2789f,
                  -103.972f, -103.98f, -104.0f, 1.0f, -1.0f, 0.5f, -0.5f}) {
    INFO("x = " << x);
    CHECK(bits(oracle_exp(x)) == bits(static_cast<float>(std::exp(double(x)))));
  }
  CHECK(oracle_exp(1.0f) == 2.71828182845904523536f);
}

TEST_CASE("oracle_pow is the correctly rounded pow on sampled floats", "[stages][oracle-math]") {
  std::mt19937 rng(11);
  for (float y : {1.0f / 2.2f, 1.0f / 2.4f, 1.0f / 1.8f, 0.5f, 2.2f, 3.0f, -1.0f, -0.45f, 7.5f}) {
    Agreement a;
    for (int i = 0; i < 150000; ++i) {
      // Positive floats of every binade (bit sampling), and the display range (0, 1].
      const float x = i % 2 ? from_bits(rng() & 0x7fffffffu)
                            : std::uniform_real_distribution<float>(0.0f, 1.0f)(rng);
      if (!std::isfinite(x)) continue;
      a.add(oracle_pow(x, y), static_cast<float>(std::pow(double(x), double(y))));
    }
    INFO("y = " << y << ": " << a.n << " values, " << a.differ << " differ, worst " << a.worst
                << " ulp");
    CHECK(a.worst <= 1);
    CHECK(a.differ <= 2);
  }
}

TEST_CASE("oracle_pow's special cases are IEEE pow's for x >= 0", "[stages][oracle-math]") {
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float xs[] = {0.0f, -0.0f, 1.0f, inf, nan, 1e-45f, 3.4e38f, 0.5f, 2.0f};
  const float ys[] = {1.0f / 2.2f, 1.0f, 3.0f, 2.0f, -1.0f, -3.0f, -2.0f, 0.0f, -0.0f,
                      inf, -inf, nan, 1e30f, -1e30f, 0.5f, 1e-30f};
  for (float y : ys)
    for (float x : xs) {
      INFO("pow(" << x << ", " << y << ")");
      // Truth: the C library's double pow (IEEE's special cases), rounded to float.
      const float truth = static_cast<float>(std::pow(double(x), double(y)));
      const float ours = oracle_pow(x, y);
      if (std::isnan(truth)) CHECK(std::isnan(ours));
      else CHECK(bits(ours) == bits(truth));
    }
  CHECK(std::isnan(oracle_pow(-0.5f, 1.0f / 2.2f)));  // documented: x < 0 is NaN
}

namespace {

// Values that take every branch: the series (|x| < 0.5) and exp branches of the tone map, both
// signs, -0, subnormals, 1e38, +-Inf, NaN; display values in [0, 1] for the output stage.
Image hostile(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float special[] = {-0.0f, 0.0f, 1e-45f, 1e-40f, 1e38f, -1e38f,
                           std::numeric_limits<float>::infinity(),
                           -std::numeric_limits<float>::infinity(),
                           std::numeric_limits<float>::quiet_NaN(), 0.25f, 0.5f, 1.0f};
  Image img(w, h);
  for (float& v : img.values()) {
    const float r = u(rng);
    if (r < 0.45f) v = std::ldexp(u(rng), int(u(rng) * 60.0f) - 40);
    else if (r < 0.6f) v = -std::ldexp(u(rng), int(u(rng) * 20.0f) - 10);
    else if (r < 0.9f) v = u(rng);
    else v = special[int(u(rng) * 12.0f) % 12];
  }
  return img;
}

}  // namespace

TEST_CASE("the fast finishing stages give the staged reference's bits", "[stages][oracle-math]") {
  unsigned seed = 1;
  for (auto [w, h] : {std::pair{1, 1}, {3, 1}, {5, 3}, {17, 9}, {640, 3}, {1, 37}}) {
    for (float exposure : {1.0f, 0.37f, 8.0f}) {
      const float gamma = exposure == 1.0f ? 2.2f : exposure == 8.0f ? 1.0f : 2.4f;
      const float strength = 0.04f * exposure;
      const Image scene = hostile(w, h, seed++), bloom = hostile(w, h, seed++);
      // Reference: the three stages one after the other.
      Image composed(w, h), mapped(w, h), out(w, h), encoded(w, h);
      composite(scene.cview(), bloom.cview(), composed.view(), strength, 1);
      tonemap(composed.cview(), mapped.view(), exposure, 1);
      encode_output(mapped.cview(), out.view(), gamma, 1);
      encode_output(scene.cview(), encoded.view(), gamma, 1);  // raw values: < 0, > 1, NaN
      Image scene_mapped(w, h);
      tonemap(scene.cview(), scene_mapped.view(), exposure, 1);
      for (BlurIsa isa : test::isas())
        for (int threads : {1, 2}) {
          INFO(w << "x" << h << " exposure " << exposure << " gamma " << gamma << " "
                 << blur_isa_name(isa) << " threads " << threads);
          Image t(w, h);
          tonemap_fast(scene.cview(), t.view(), exposure, threads, isa);
          CHECK(test::bit_identical(t.cview(), scene_mapped.cview()));
          Image e(w, h);
          encode_output_fast(scene.cview(), e.view(), gamma, threads, isa);
          CHECK(test::bit_identical(e.cview(), encoded.cview()));
          Image f(w, h);
          finish_fast(scene.cview(), bloom.cview(), f.view(), strength, exposure, gamma,
                      threads, isa);
          CHECK(test::bit_identical(f.cview(), out.cview()));
          Image in_place = scene;  // dst = scene, as the executor runs it
          finish_fast(in_place.cview(), bloom.cview(), in_place.view(), strength, exposure,
                      gamma, threads, isa);
          CHECK(test::bit_identical(in_place.cview(), out.cview()));
          if (threads == 1) {
            // finish_fast_rows over row segments of 1, 7 and 160 pixels in turn (the fused
            // blur's sink hands over strips of rows), in place.
            Image seg = scene;
            for (int x0 = 0, k = 0; x0 < w; ++k) {
              const int x1 = std::min(w, x0 + (k % 3 == 0 ? 1 : k % 3 == 1 ? 7 : 160));
              std::vector<float*> d(std::size_t(h), nullptr);
              std::vector<const float*> b(std::size_t(h), nullptr);
              for (int y = 0; y < h; ++y) {
                d[std::size_t(y)] = seg.view().row(y) + 4 * x0;
                b[std::size_t(y)] = bloom.cview().row(y) + 4 * x0;
              }
              finish_fast_rows(d.data(), b.data(), d.data(), h, x1 - x0, strength, exposure,
                               gamma, isa);
              x0 = x1;
            }
            CHECK(test::bit_identical(seg.cview(), out.cview()));
          }
        }
    }
  }
}

TEST_CASE("the fast tone map's 8- and 16-lane series and mixed vectors give the reference's bits",
          "[stages][oracle-math]") {
  // Mostly dark values (|h| < 0.5: the series, 8 or 16 lanes at a time where all take it) with a
  // bright, negative or non-finite value now and then (that vector's halves go through exp's
  // lanes), on rows whose RGB values are not a whole number of vectors (641 * 3 = 1923).
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float odd[] = {3.0f, 0.75f, -0.6f, 40.0f, std::numeric_limits<float>::infinity(),
                       std::numeric_limits<float>::quiet_NaN()};
  Image scene(641, 4), bloom(641, 4);
  int odd_count = 0;
  for (float& v : scene.values()) {
    v = u(rng) * 0.45f;
    if (u(rng) < 0.01f) v = odd[odd_count++ % 6];
  }
  for (float& v : bloom.values()) v = u(rng) * 0.1f;
  REQUIRE(odd_count > 20);
  Image mapped(641, 4), composed(641, 4), out(641, 4);
  tonemap(scene.cview(), mapped.view(), 1.0f, 1);
  composite(scene.cview(), bloom.cview(), composed.view(), 0.04f, 1);
  tonemap(composed.cview(), out.view(), 1.0f, 1);
  encode_output(out.cview(), out.view(), 2.2f, 1);
  for (BlurIsa isa : test::isas()) {
    INFO(blur_isa_name(isa));
    Image t(641, 4), f(641, 4);
    tonemap_fast(scene.cview(), t.view(), 1.0f, 1, isa);
    CHECK(test::bit_identical(t.cview(), mapped.cview()));
    finish_fast(scene.cview(), bloom.cview(), f.view(), 0.04f, 1.0f, 2.2f, 2, isa);
    CHECK(test::bit_identical(f.cview(), out.cview()));
  }
}

TEST_CASE("the finishing stages with the bloom's support read the bloom only inside it",
          "[stages][oracle-math]") {
  // Bloom +0 outside a few spans per row (as the adaptive plan leaves it); the scene hostile
  // (-0, NaN, +-Inf, negatives). With the support the bits are those of the full composite;
  // and a value planted outside the support is not read (the result is the same as without it,
  // and differs from reading it).
  const int w = 97, h = 6;
  const Image scene = hostile(w, h, 123);
  Image bloom = hostile(w, h, 321);
  RowSpans support(h);
  support[1] = {{0, 5}, {40, 41}, {90, 97}};
  support[3] = {{10, 60}};
  support[5] = {{0, 97}};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool inside = false;
      for (const Span& s : support[y]) inside = inside || (x >= s.x0 && x < s.x1);
      if (!inside)
        for (int c = 0; c < 3; ++c) bloom.view().pixel(x, y)[c] = 0.0f;
    }
  for (float strength : {1.0f, 0.04f, -0.5f}) {
    INFO("strength " << strength);
    Image full(w, h);
    finish_fast(scene.cview(), bloom.cview(), full.view(), strength, 1.0f, 2.2f, 1);
    for (BlurIsa isa : test::isas()) {
      Image spans(w, h);
      finish_fast(scene.cview(), bloom.cview(), spans.view(), strength, 1.0f, 2.2f, 2, isa,
                  &support);
      CHECK(test::bit_identical(full.cview(), spans.cview()));
    }
    Image planted = bloom;
    planted.view().pixel(20, 1)[0] = 100.0f;  // row 1, between its spans
    planted.view().pixel(3, 0)[2] = 50.0f;    // row 0, which has none
    Image read(w, h), skipped(w, h);
    finish_fast(scene.cview(), planted.cview(), read.view(), strength, 1.0f, 2.2f, 1);
    finish_fast(scene.cview(), planted.cview(), skipped.view(), strength, 1.0f, 2.2f, 1,
                BlurIsa::best, &support);
    CHECK(test::bit_identical(skipped.cview(), full.cview()));
    CHECK_FALSE(test::bit_identical(read.cview(), full.cview()));
  }
  RowSpans short_support(h - 1);
  Image out(w, h);
  CHECK_THROWS_AS(finish_fast(scene.cview(), bloom.cview(), out.view(), 1.0f, 1.0f, 2.2f, 1,
                              BlurIsa::best, &short_support),
                  ParamError);
  // Spans outside the row, empty, or overlapping are refused, not read past the row's end.
  for (const std::vector<Span>& bad : {std::vector<Span>{{90, 98}}, std::vector<Span>{{-1, 3}},
                                       std::vector<Span>{{5, 5}},
                                       std::vector<Span>{{0, 10}, {9, 20}}}) {
    RowSpans s(h);
    s[2] = bad;
    CHECK_THROWS_AS(finish_fast(scene.cview(), bloom.cview(), out.view(), 1.0f, 1.0f, 2.2f, 1,
                                BlurIsa::best, &s),
                    ParamError);
  }
}

TEST_CASE("the fast output stage gives the reference's bits for every kind of exponent",
          "[stages][oracle-math]") {
  // 1 / gamma = 1/2.2, 1, 3 (odd: pow(-0, 3) = -0), 2, -1, +Inf, -Inf, 0, NaN: each of
  // oracle_pow's special-case branches in vector lanes.
  const float inf = std::numeric_limits<float>::infinity();
  const Image scene = hostile(29, 5, 77);
  for (float gamma : {2.2f, 1.0f, 1.0f / 3.0f, 0.5f, -1.0f, 0.0f, -0.0f, inf,
                      std::numeric_limits<float>::quiet_NaN()}) {
    Image ref(29, 5);
    encode_output(scene.cview(), ref.view(), gamma, 1);
    for (BlurIsa isa : test::isas()) {
      INFO("gamma " << gamma << " " << blur_isa_name(isa));
      Image fast(29, 5);
      encode_output_fast(scene.cview(), fast.view(), gamma, 1, isa);
      CHECK(test::bit_identical(fast.cview(), ref.cview()));
    }
  }
}

TEST_CASE("the fast finishing stages are not vacuous: one ulp off is caught",
          "[stages][oracle-math]") {
  const Image scene = hostile(33, 7, 5);
  Image ref(33, 7), fast(33, 7);
  tonemap(scene.cview(), ref.view(), 1.0f, 1);
  tonemap_fast(scene.cview(), fast.view(), std::nextafter(1.0f, 2.0f), 1);
  CHECK_FALSE(test::bit_identical(ref.cview(), fast.cview()));
  encode_output(scene.cview(), ref.view(), 2.2f, 1);
  encode_output_fast(scene.cview(), fast.view(), std::nextafter(2.2f, 3.0f), 1);
  CHECK_FALSE(test::bit_identical(ref.cview(), fast.cview()));
}

namespace {

/// Whether v is exactly a binary16 value other than NaN, by Imath's conversion (independent of
/// the library's bit-level test): v survives the round trip through half bit for bit.
bool is_binary16(float v) {
  if (std::isnan(v)) return false;
  const float back = static_cast<float>(Imath::half(v));
  return bits(back) == bits(v);
}

}  // namespace

TEST_CASE("the finishing stages' kept tables: parameters that share the exposure or the gamma "
          "get their own", "[stages][oracle-math]") {
  // finish_fast keeps the table of finished binary16 values between calls, by kernel, exposure
  // and 1 / gamma. Parameter sets here share one of the two with the set before them; each
  // output against the staged reference, after the others have been kept.
  const int w = 400, h = 400;  // 160,000 pixels, none in the support: the table pays
  std::mt19937 rng(31);
  Image scene(w, h), bloom(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* px = scene.view().pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        Imath::half v;
        v.setBits(static_cast<std::uint16_t>(rng() % 0x7c00u));  // finite, non-negative
        px[c] = static_cast<float>(v);
      }
      px[3] = 1.0f;
    }
  const RowSpans none(h);
  for (int round = 0; round < 2; ++round)
    for (auto [exposure, gamma] : {std::pair{1.0f, 2.2f}, std::pair{1.0f, 1.0f},
                                   std::pair{0.37f, 1.0f}, std::pair{0.37f, 2.2f}}) {
      Image composed(w, h), ref(w, h);
      composite(scene.cview(), bloom.cview(), composed.view(), 1.0f, 1);
      tonemap(composed.cview(), ref.view(), exposure, 1);
      encode_output(ref.cview(), ref.view(), gamma, 1);
      for (BlurIsa isa : test::isas()) {
        INFO("round " << round << " exposure " << exposure << " gamma " << gamma << " "
                      << blur_isa_name(isa));
        Image out(w, h);
        CHECK(finish_fast(scene.cview(), bloom.cview(), out.view(), 1.0f, exposure, gamma, 2,
                          isa, &none) == std::size_t(w) * h);
        CHECK(test::bit_identical(out.cview(), ref.cview()));
      }
    }
}

TEST_CASE("the finishing stages take binary16 sums from a table with the staged reference's "
          "bits",
          "[stages][oracle-math]") {
  // 523 x 300 = 156,900 pixels, over 2^17 of them outside the support: the scene runs through
  // every binary16 bit pattern in turn (NaN, +-Inf, +-0, subnormals included); a quarter of the
  // pixels get one value that is not binary16 (one ulp above a binary16 value, or a float in
  // (0, 1)); the support has a few spans on most rows (odd ends: the two-pixel vectors and the
  // one-pixel tails), none on some, the whole row on one. Expected: the staged reference's
  // bits, and exactly the pixels whose three composite sums s + strength * b (b = +0 outside
  // the support) are binary16 values (Imath's round trip) finished from the table.
  const int w = 523, h = 300;
  std::mt19937 rng(29);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image scene(w, h), bloom(w, h);
  std::uint32_t pattern = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* px = scene.view().pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        Imath::half v;
        v.setBits(static_cast<std::uint16_t>(pattern++ & 0xffffu));
        px[c] = static_cast<float>(v);
      }
      px[3] = u(rng);
      if (u(rng) < 0.25f) {
        const int c = int(u(rng) * 3.0f) % 3;
        px[c] = u(rng) < 0.5f ? std::nextafter(px[c], std::numeric_limits<float>::infinity())
                              : u(rng);
      }
    }
  REQUIRE(pattern > 65536 * 7);
  // And on rows without spans, values at the edges of binary16: 2^e (1 + f) for every binade
  // from below the smallest subnormal to above the largest normal, f from one float ulp to one
  // binary16 ulp of a normal, both signs (binary16 or not depending on e and f).
  std::vector<float> edges;
  for (int e = -27; e <= 16; ++e)
    for (float f : {0x1p-23f, 0x1p-13f, 0x1p-12f, 0x1p-11f, 0x1p-10f, 0.0f}) {
      edges.push_back(std::ldexp(1.0f + f, e));
      edges.push_back(-std::ldexp(1.0f + f, e));
    }
  for (std::size_t i = 0; i < edges.size(); ++i)
    scene.view().pixel(int(i / 3) % w, 3 + 7 * int(i / 3 / w))[i % 3] = edges[i];
  RowSpans support(h);
  for (int y = 0; y < h; ++y) {
    if (y % 7 == 3) continue;  // no span
    if (y == 100) {
      support[y] = {{0, w}};
      continue;
    }
    int x = int(u(rng) * 40.0f);
    while (x + 2 < w && support[y].size() < 4) {
      const int len = 1 + int(u(rng) * 30.0f);
      support[y].push_back({x, std::min(w, x + len)});
      x += len + 1 + int(u(rng) * 150.0f);
    }
  }
  // Inside the support a third of the bloom's pixels are +0 (texels the support holds that no
  // bright pixel reached), a third are 2^-100 (below half an ulp of every normal scene value:
  // the sum is the scene's value), a third are in [0, 3) (a sum almost never binary16).
  for (int y = 0; y < h; ++y)
    for (const Span& s : support[y])
      for (int x = s.x0; x < s.x1; ++x) {
        const float r = u(rng);
        for (int c = 0; c < 4; ++c)
          bloom.view().pixel(x, y)[c] = r < 1.0f / 3 ? 0.0f : r < 2.0f / 3 ? 0x1p-100f : u(rng) * 3.0f;
      }
  for (auto [strength, exposure, gamma] : {std::tuple{1.0f, 1.0f, 2.2f},
                                           std::tuple{-0.5f, 0.37f, 1.0f},
                                           std::tuple{0.5f, 0.37f, 1.0f},  // -0 + +0 = +0
                                           std::tuple{0.04f, 8.0f, 0.5f}}) {
    std::size_t expected = 0, outside = 0, expected_outside = 0, inside = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        bool in = false;
        for (const Span& s : support[y]) in = in || (x >= s.x0 && x < s.x1);
        (in ? inside : outside) += 1;
        // The composite's sum: scene + strength * bloom, the bloom +0 outside the support.
        const float* px = scene.cview().pixel(x, y);
        const float* b = bloom.cview().pixel(x, y);
        bool all = true;
        for (int c = 0; c < 3; ++c)
          all = all && is_binary16(px[c] + strength * (in ? b[c] : 0.0f));
        expected += all;
        expected_outside += all && !in;
      }
    REQUIRE(outside > (std::size_t(1) << 17));
    REQUIRE(expected_outside > outside / 2);
    REQUIRE(expected_outside < outside);
    // Inside: about two thirds of three quarters of the pixels (the +0 and 2^-100 blooms on
    // binary16 scene values), not all.
    REQUIRE(expected - expected_outside > inside / 3);
    REQUIRE(expected - expected_outside < inside * 3 / 4);
    Image composed(w, h), ref(w, h);
    composite(scene.cview(), bloom.cview(), composed.view(), strength, 1);
    tonemap(composed.cview(), ref.view(), exposure, 1);
    encode_output(ref.cview(), ref.view(), gamma, 1);
    for (BlurIsa isa : test::isas()) {
      INFO("strength " << strength << " exposure " << exposure << " gamma " << gamma << " "
                       << blur_isa_name(isa));
      Image out = scene;  // in place, as the executor runs it
      const std::size_t from_table = finish_fast(out.cview(), bloom.cview(), out.view(),
                                                 strength, exposure, gamma, 2, isa, &support);
      CHECK(from_table == expected);
      CHECK(test::bit_identical(out.cview(), ref.cview()));
      Image apart(w, h);  // into another image: alpha is carried over from the scene
      CHECK(finish_fast(scene.cview(), bloom.cview(), apart.view(), strength, exposure, gamma, 1,
                        isa, &support) == expected);
      CHECK(test::bit_identical(apart.cview(), ref.cview()));
    }
  }
  // No table where it would not pay: a float scene (no binary16 values to speak of), or too
  // few pixels outside the support. The bits are the reference's either way.
  Image floats = scene;
  for (float& v : floats.values()) v = u(rng) * 4.0f;
  RowSpans most(h, std::vector<Span>{{0, w - 300}});  // 300 x 300 = 90,000 < 2^17 outside
  for (auto [img, spans] : {std::pair{&floats, &support}, std::pair{&scene, &most}}) {
    Image bl(w, h);  // +0: every support holds the bloom
    Image composed(w, h), ref(w, h);
    composite(img->cview(), bl.cview(), composed.view(), 1.0f, 1);
    tonemap(composed.cview(), ref.view(), 1.0f, 1);
    encode_output(ref.cview(), ref.view(), 2.2f, 1);
    for (BlurIsa isa : test::isas()) {
      Image out(w, h);
      CHECK(finish_fast(img->cview(), bl.cview(), out.view(), 1.0f, 1.0f, 2.2f, 2, isa,
                        spans) == 0);
      CHECK(test::bit_identical(out.cview(), ref.cview()));
    }
  }
}
