// The tolerance model's per-value bounds (parity/src/tolerance.h) against values computed by
// hand from the model's stated terms: u = 2^-24 (f32 unit roundoff), f16 ULP 2^(e - 10) with
// the exponent floored at -14, GLSL 4.50's precision table (profile.h), discrete9's weights
// 924, 792, 495, 220, 66 over 4070. Needs no GL.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/parity/profile.h"
#include "bloomref/stages.h"
#include "judge.h"
#include "stage_terms.h"
#include "tolerance.h"

using namespace bloomref;
using namespace bloomref::parity;
namespace tol = bloomref::parity::detail;  // the tolerance model
using tol::BoundContext;

namespace {

constexpr double u = 0x1p-24;

// A profile whose half writes round to nearest-even only (the llvmpipe profile accepts toward
// zero, which loses up to a whole ULP).
DeviceProfile nearest_even_profile() {
  DeviceProfile p = profile_llvmpipe();
  p.half_toward_zero = false;
  p.half_nearest_even = true;
  return p;
}

// A w x 1 image whose RGB all hold values[x] (alpha 1).
Image row(const std::vector<float>& values) {
  Image img(static_cast<int>(values.size()), 1);
  for (std::size_t x = 0; x < values.size(); ++x) {
    float* p = img.pixel(static_cast<int>(x), 0);
    p[0] = p[1] = p[2] = values[x];
    p[3] = 1;
  }
  return img;
}

// The value of the term whose name starts with `prefix`.
double term(const std::vector<Term>& terms, const std::string& prefix) {
  for (const Term& t : terms)
    if (t.name.rfind(prefix, 0) == 0) return t.value;
  FAIL("no term named " << prefix << "...");
  return 0;
}

double total(const std::vector<Term>& terms) {
  double s = 0;
  for (const Term& t : terms) s += t.value;
  return s;
}

// Window statistics are stored as floats: weight sums such as 781 / 4070 carry one float
// rounding, so sums of them match the hand value within a few 2^-24 relative.
bool close(double got, double want) { return std::fabs(got - want) <= 4 * u * std::fabs(want); }

}  // namespace

TEST_CASE("f16 storage: half an ULP (2^-11 relative at 1) for nearest-even, one for toward zero",
          "[parity][bounds]") {
  const DeviceProfile ne = nearest_even_profile(), tz = profile_llvmpipe();
  // Binade [1, 2): ULP 2^-10.
  CHECK(tol::storage_term(1.0, Storage::f16, ne) == 0x1p-11);
  CHECK(tol::storage_term(1.5, Storage::f16, ne) == 0x1p-11);
  CHECK(tol::storage_term(1.0, Storage::f16, tz) == 0x1p-10);
  // [2, 4): ULP 2^-9; [4, 8): 2^-8; the sign does not matter.
  CHECK(tol::storage_term(3.0, Storage::f16, ne) == 0x1p-10);
  CHECK(tol::storage_term(-4.0, Storage::f16, ne) == 0x1p-9);
  // Below the smallest normal half (2^-14) the ULP stays 2^-24 (the subnormal spacing).
  CHECK(tol::storage_term(0x1p-20, Storage::f16, ne) == 0x1p-25);
  CHECK(tol::storage_term(0.0, Storage::f16, tz) == 0x1p-24);
  // f32 storage is the oracle's own: nothing. A non-finite value has no ULP.
  CHECK(tol::storage_term(1.0, Storage::f32, tz) == 0.0);
  CHECK(tol::storage_term(INFINITY, Storage::f16, tz) == 0.0);
}

TEST_CASE("denormal floor and coordinate error follow the profile", "[parity][bounds]") {
  CHECK(tol::denormal_floor(profile_llvmpipe()) == 0x1p-120);
  DeviceProfile keeps = profile_llvmpipe();
  keeps.flush_denormals = false;
  CHECK(tol::denormal_floor(keeps) == 0.0);
  // n u (2 * 2.5 + 4): 1024 * 2^-24 * 9 = 9 * 2^-14, in texels; fixed-point weights of 8 bits
  // add one weight quantum 2^-8.
  CHECK(tol::coordinate_error(1024, profile_llvmpipe()) == 9 * 0x1p-14);
  CHECK(tol::coordinate_error(1024, profile_nvidia_like()) == 9 * 0x1p-14 + 0x1p-8);
}

TEST_CASE("input: storage plus the value itself where it is a denormal", "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();
  const Image img = row({1.0f, 0x1p-130f});
  const auto b = tol::input_bounds(img.cview(), BoundContext{&p, Storage::f16, 1});
  CHECK(total(b->terms(0, 0, 0)) == 0x1p-10);          // toward zero: one ULP at 1
  CHECK(total(b->terms(1, 0, 0)) == 0x1p-24 + 0x1p-130);  // subnormal half ULP + flushed value
}

TEST_CASE("bright: a tie band only when the luminance is not computed `precise`",
          "[parity][bounds]") {
  DeviceProfile p = profile_llvmpipe();
  const Image img = row({2.0f});
  const float at = luminance(2.0f, 2.0f, 2.0f);
  const auto precise = tol::bright_bounds(img.cview(), at, BoundContext{&p, Storage::f32, 1});
  CHECK(total(precise->terms(0, 0, 1)) == 0.0);
  p.precise_luminance = false;
  // |L - threshold| = 0 is within 4u sum|w_i c_i|: either side is right, so the bound is the
  // largest channel, 2. A threshold far away (0.5) has no band.
  const auto tie = tol::bright_bounds(img.cview(), at, BoundContext{&p, Storage::f32, 1});
  CHECK(total(tie->terms(0, 0, 1)) == 2.0);
  const auto far = tol::bright_bounds(img.cview(), 0.5f, BoundContext{&p, Storage::f32, 1});
  CHECK(total(far->terms(0, 0, 1)) == 0.0);
}

TEST_CASE("bright read at interpolated coordinates: a blend of the neighbours and a wider tie",
          "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();  // luminance `precise`: no rounding band
  // Along x only (one row): a texel off its centre by d texels blends in d of a neighbour, so
  // its value may move by d times the larger difference to one: here 4 - 0.
  const Image img = row({0.0f, 4.0f, 0.5f});
  const double d = tol::coordinate_error(3, p);
  BoundContext reads{&p, Storage::f32, 1};
  reads.interpolated_reads = true;
  const auto b = tol::bright_bounds(img.cview(), 1.0f, reads);
  CHECK(term(b->terms(1, 0, 0), "interpolated") == d * 4.0);
  CHECK(term(b->terms(1, 0, 0), "threshold") == 0.0);
  // Below the threshold and not within the reads' luminance of it: 0 either way.
  CHECK(total(b->terms(2, 0, 0)) == 0.0);
  // A threshold within the reads' luminance change (sum_i w_i d |step_i| = 3.5 d for the
  // texel of 0.5) of the texel's luminance: either side is right.
  const float l = luminance(0.5f, 0.5f, 0.5f);
  const auto tie = tol::bright_bounds(img.cview(), static_cast<float>(l - d), reads);
  CHECK(term(tie->terms(2, 0, 0), "threshold") == 0.5 + d * 3.5);
  // Without interpolated reads (bloomref's own shaders), none of it.
  const auto exact = tol::bright_bounds(img.cview(), 1.0f, BoundContext{&p, Storage::f32, 1});
  CHECK(total(exact->terms(1, 0, 0)) == 0.0);
}

TEST_CASE("blur: coordinate term from the local range, rounding from the magnitude",
          "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();
  const BoundContext ctx{&p, Storage::f32, 1};
  const Kernel& k = kernel_discrete9();
  // A constant row: no range, so no coordinate term; every tap's magnitude 1 and the weights sum
  // to (924 + 2 (792 + 495 + 220 + 66)) / 4070 = 1, so the filter and sum rounding is
  // (3 + 2 * 9) u = 21u; plus the denormal floor 2^-120.
  {
    const Image flat = row({1, 1, 1, 1, 1, 1, 1, 1});
    const auto b = tol::blur_bounds(flat.cview(), flat.cview(), Axis::horizontal, k, ctx);
    const auto t = b->terms(3, 0, 0);
    CHECK(term(t, "coordinate") == 0.0);
    CHECK(close(term(t, "filter"), 21 * u));
    CHECK(term(t, "storage") == 0.0);
    CHECK(term(t, "denormal") == 0x1p-120);
  }
  // A step, 0 for x < 4 and 1 from x = 4, 8 texels wide and 1 high: the coordinate error is
  // (8 + 1) u 9 = 81u texels (coordinate_error along and across). A tap based at texel b may
  // touch [b - 1, b + 2]: its range is 1 for b in {2, 3, 4}, its magnitude 1 for b >= 2.
  const Image step = row({0, 0, 0, 0, 1, 1, 1, 1});
  const auto b = tol::blur_bounds(step.cview(), step.cview(), Axis::horizontal, k, ctx);
  // x = 0: taps at 0, +1..+4 and -1..-4 (clamped to 0); bases 2, 3, 4 are the +2, +3, +4 taps:
  // range and magnitude both weigh (495 + 220 + 66) / 4070 = 781 / 4070.
  const auto t0 = b->terms(0, 0, 0);
  CHECK(close(term(t0, "coordinate"), 81 * u * 781 / 4070));
  CHECK(close(term(t0, "filter"), 21 * u * 781 / 4070));
  // x = 7: +1..+4 clamp to 7, -1..-4 at 6, 5, 4, 3. Range: -3 (base 4) and -4 (base 3), so
  // (220 + 66) / 4070; magnitude: every base is >= 2, so 1.
  const auto t7 = b->terms(7, 0, 0);
  CHECK(close(term(t7, "coordinate"), 81 * u * 286 / 4070));
  CHECK(close(term(t7, "filter"), 21 * u));
  // fill() writes the sum of the terms.
  Image bound(8, 1);
  b->fill(bound);
  CHECK(close(bound.pixel(0, 0)[0], (81 + 21) * u * 781 / 4070 + 0x1p-120));
}

TEST_CASE("8-bit sources: each lookup two 255ths per unit of weight, a blend three more",
          "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();
  BoundContext eight{&p, Storage::f32, 1};
  eight.unorm8_reads = true;
  const Kernel& k = kernel_discrete9();
  // A constant row, so no coordinate term of its own: the coordinate term is the 8-bit
  // filtering alone, 2/255 times the weights' sum, (924 + 2 (792 + 495 + 220 + 66)) / 4070 = 1.
  const Image flat = row({1, 1, 1, 1, 1, 1, 1, 1});
  const auto b = tol::blur_bounds(flat.cview(), flat.cview(), Axis::horizontal, k, eight);
  CHECK(close(term(b->terms(3, 0, 0), "coordinate"), 2.0 / 255));
  Image bound(8, 1);
  b->fill(bound);
  CHECK(close(bound.pixel(3, 0)[0], 2.0 / 255 + 21 * u + 0x1p-120));
  // The composite: both lookups, the bloom's weighted by the strength 0.25, 2/255 x 1.25; and
  // stored in 8 bits (a blend into the scene's target may be), 3/255 more besides the storage
  // term (1.5/255 at a value within [0, 1], tolerance.cpp).
  const Image scene = row({0.5f, 0.5f}), bloom = row({0.25f, 0.25f});
  const Image sum = row({0.5625f, 0.5625f});
  const auto c = tol::composite_bounds(scene.cview(), bloom.cview(), sum.cview(), 0.25f, eight);
  CHECK(close(term(c->terms(0, 0, 0), "interpolated"), 2.0 / 255 * 1.25));
  BoundContext stored = eight;
  stored.storage = Storage::rgba8;
  const auto d = tol::composite_bounds(scene.cview(), bloom.cview(), sum.cview(), 0.25f, stored);
  CHECK(close(term(d->terms(0, 0, 0), "interpolated"), 2.0 / 255 * 1.25 + 3.0 / 255));
  CHECK(close(term(d->terms(0, 0, 0), "storage"), 1.5 / 255));
  // Without 8-bit reads, neither.
  const BoundContext plain{&p, Storage::f32, 1};
  const auto e = tol::composite_bounds(scene.cview(), bloom.cview(), sum.cview(), 0.25f, plain);
  CHECK(term(e->terms(0, 0, 0), "interpolated") == 0.0);
}

// An image of one value `background` but in short spans of some rows (at either edge too, and
// a NaN in one), and, when `odd_row`, one row of another value: the bounds take the windows
// that reach no span as one (window_sums.cpp), which must be what each of them is.
void sparse_image(Image& img, float background, bool odd_row) {
  const int w = img.width(), h = img.height();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) img.pixel(x, y)[c] = background;
  for (int y = 0; y < h; y += 3) {
    const int x0 = y == 0 ? 0 : y == 3 ? w - 2 : (y * 7) % w;
    for (int x = x0; x < std::min(w, x0 + 3); ++x)
      for (int c = 0; c < 3; ++c)
        img.pixel(x, y)[c] = static_cast<float>((x * 5 + y * 3 + c) % 7) + 0.5f;
  }
  if (h > 6) img.pixel(std::min(w - 1, 4), 6)[2] = NAN;
  if (odd_row)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) img.pixel(x, h / 2 + 1)[c] = 2.0f;
}

TEST_CASE("blur bounds at every texel of small images: the windows written out plainly",
          "[parity][bounds]") {
  // The model (tolerance.cpp): a tap based at texel b = clamp(floor(pos +- o_i)) touches
  // [b - 1, b + 2] along the axis and [q - 1, q + 1] across, clamped; its range is max - min and
  // its magnitude max |t| over the finite texels there (+Inf with a NaN/Inf among them). The
  // coordinate term is delta x sum_i w_i range_i, the filter term (3 + 2T) u x sum_i w_i
  // magnitude_i (each sum in double, rounded to float). Computed here texel by texel, on every
  // size from 1 to 6 along both axes (edges everywhere), both kernels, with one NaN texel and
  // one row of one value (whose windows the bounds take as one), and on sparse images.
  const DeviceProfile p = profile_llvmpipe();
  const BoundContext ctx{&p, Storage::f32, 3};
  for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()})
    for (Axis axis : {Axis::horizontal, Axis::vertical})
      for (int shape = 0; shape < 36 + 6; ++shape) {
          // Every size to 6 x 6, then sparse images (sparse_image).
          const bool sparse = shape >= 36;
          const int sizes[6][2] = {{40, 9}, {9, 40}, {37, 23}, {23, 37}, {64, 64}, {64, 64}};
          const int w = sparse ? sizes[shape - 36][0] : 1 + shape % 6;
          const int h = sparse ? sizes[shape - 36][1] : 1 + shape / 6;
          Image img(w, h);
          if (sparse) {
            sparse_image(img, shape == 41 ? 0.0f : 0.25f, shape != 40);
          } else {
            for (int y = 0; y < h; ++y)
              for (int x = 0; x < w; ++x)
                for (int c = 0; c < 3; ++c)
                  img.pixel(x, y)[c] =
                      static_cast<float>(((y == 1 ? c : x * 7 + y * 13 + c * 5) % 11) - 3) / 4;
            if (w * h > 4) img.pixel(w / 2, h / 2)[1] = NAN;
          }
          const bool hz = axis == Axis::horizontal;
          const int n = hz ? w : h;
          const double delta = tol::coordinate_error(w, p) + tol::coordinate_error(h, p);
          auto window = [&](int bx, int by, int c, bool range) {
            float mn = INFINITY, mx = -INFINITY, ma = 0;
            for (int a = -1; a <= 2; ++a)
              for (int q = -1; q <= 1; ++q) {
                const int xx = std::clamp(bx + (hz ? a : q), 0, w - 1);
                const int yy = std::clamp(by + (hz ? q : a), 0, h - 1);
                const float t = img.pixel(xx, yy)[c];
                if (!std::isfinite(t)) {
                  ma = INFINITY;
                  continue;
                }
                mn = std::min(mn, t);
                mx = std::max(mx, t);
                ma = std::max(ma, std::fabs(t));
              }
            return range ? (mx >= mn ? mx - mn : 0.0f) : ma;
          };
          const auto b = tol::blur_bounds(img.cview(), img.cview(), axis, *k, ctx);
          Image filled(w, h);
          b->fill(filled);
          for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
              for (int c = 0; c < 3; ++c) {
                double range = 0, magnitude = 0;
                for (std::size_t i = 0; i < k->offsets_f64.size(); ++i)
                  for (double sign : {1.0, -1.0}) {
                    if (i == 0 && sign < 0) continue;
                    const int pos = hz ? x : y;
                    const int base = std::clamp(int(std::floor(pos + sign * k->offsets_f64[i])), 0, n - 1);
                    range += k->weights_f64[i] * window(hz ? base : x, hz ? y : base, c, true);
                    magnitude += k->weights_f64[i] * window(hz ? base : x, hz ? y : base, c, false);
                  }
                const auto t = b->terms(x, y, c);
                INFO(k->taps() << " taps, " << (hz ? "horizontal " : "vertical ") << w << "x" << h
                               << " at (" << x << ", " << y << ", " << c << ")");
                CHECK(term(t, "coordinate") == delta * static_cast<float>(range));
                const double filter = (3 + 2 * k->taps()) * u * static_cast<float>(magnitude);
                if (std::isinf(magnitude)) CHECK(std::isinf(term(t, "filter")));
                else CHECK(term(t, "filter") == filter);
                CHECK(filled.pixel(x, y)[c] == static_cast<float>(total(t)));
              }
        }
}

TEST_CASE("an error propagated through one blur pass is its windowed, weighted magnitude",
          "[parity][bounds]") {
  // An error of 1 at x = 4 of 8: a tap based at b sees it when 4 is in [b - 1, b + 2], so for
  // b in 2..5.
  const Image err = row({0, 0, 0, 0, 1, 0, 0, 0});
  const Image out = tol::propagate_blur(err.cview(), Axis::horizontal, kernel_discrete9(), 1);
  // x = 4: bases 4 (w0), 5 and 3 (w1 each), 2 (the -2 tap, w2): (924 + 2 * 792 + 495) / 4070.
  CHECK(close(out.pixel(4, 0)[0], 3003.0 / 4070));
  // x = 0: bases 2, 3, 4 (the +2, +3, +4 taps): 781 / 4070; x = 7: bases 5, 4, 3 (-2, -3, -4).
  CHECK(close(out.pixel(0, 0)[0], 781.0 / 4070));
  CHECK(close(out.pixel(7, 0)[0], 781.0 / 4070));
  // Vertically, a 1-texel-wide column sees the same sums along y.
  Image col(1, 8);
  col.pixel(0, 4)[1] = 1;
  const Image down = tol::propagate_blur(col.cview(), Axis::vertical, kernel_discrete9(), 1);
  CHECK(close(down.pixel(0, 4)[1], 3003.0 / 4070));
}

TEST_CASE("composite and tone map bounds", "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();
  const BoundContext ctx{&p, Storage::f32, 1};
  // s + strength b: one product, one sum: 2u (|s| + |strength b|) = 2u (1 + 0.5 * 2) = 4u.
  const Image s = row({1}), b = row({2});
  const auto c = tol::composite_bounds(s.cview(), b.cview(), s.cview(), 0.5f, ctx);
  CHECK(term(c->terms(0, 0, 0), "product") == 4 * u);
  // exp branch at a = -hdr * exposure = -1: e = exp(-1); exp's (3 + 2|a|) ULP = 5 ULP <= 10 e u,
  // the argument's rounding e |a| u, 1 - e's rounding (1 + e) u: (12 e + 1) u, plus 2^-120.
  const Image one = row({1});
  const auto tm = tol::tonemap_bounds(one.cview(), one.cview(), 1.0f, ctx);
  const double e = std::exp(-1.0);
  CHECK(close(total(tm->terms(0, 0, 0)), (12 * e + 1) * u + 0x1p-120));
  // Series branch at |a| = 0.25 < 0.5: no exp term; argument 0.25 * 1.7 u; 22 Horner roundings
  // of m = 1 - exp(-0.25).
  const Image quarter = row({0.25f});
  const auto ts = tol::tonemap_bounds(quarter.cview(), quarter.cview(), 1.0f, ctx);
  const auto t = ts->terms(0, 0, 0);
  CHECK(term(t, "exp") == 0.0);
  CHECK(close(term(t, "argument"), 0.25 * 1.7 * u));
  CHECK(close(term(t, "1 - e"), 22 * u * -std::expm1(-0.25)));
}

TEST_CASE("a user's implementation: direct 1 - exp(x), composite inputs read at interpolated "
          "coordinates", "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();
  const BoundContext user{&p, Storage::f32, 1, true, true};
  SECTION("1 - exp(x) computed directly below |a| = 0.5: exp's ULPs near 1, absolute") {
    // a = -0.001: exp's (3 + 2|a|) ULP at e = exp(-0.001), counted as 2u e each: 2u e (3.002),
    // about 6e-7 on a result of 1e-3; the series alone allowed 22u of it (1.3e-9).
    const Image small = row({0.001f});
    const auto t = tol::tonemap_bounds(small.cview(), small.cview(), 1.0f, user)->terms(0, 0, 0);
    const double e = std::exp(-0.001);
    CHECK(close(term(t, "exp"), 2 * u * e * 3.002));
    CHECK(close(term(t, "argument"), 1.7 * 0.001 * u));  // the larger of 1.7 |a| u and e |a| u
    const BoundContext spec{&p, Storage::f32, 1};
    CHECK(term(tol::tonemap_bounds(small.cview(), small.cview(), 1.0f, spec)->terms(0, 0, 0),
               "exp") == 0.0);
  }
  SECTION("interpolated reads: the coordinate error times the larger neighbour step, per axis") {
    // A 3 x 3 scene: 0 everywhere but 8 at the centre; bloom 0 but 2 at the top-right corner.
    // At the centre (1, 1): the scene's steps are 8 on both axes, the bloom's 0: the term is
    // d(3) 8 + d(3) 8 with d(n) = n u (2 * 2.5 + 4) = 27u (the profile's 2.5-ULP division).
    Image scene(3, 3, 0.0f), bloom(3, 3, 0.0f);
    scene.pixel(1, 1)[0] = 8;
    bloom.pixel(2, 0)[0] = 2;
    const float strength = 0.5f;
    const auto c = tol::composite_bounds(scene.cview(), bloom.cview(), scene.cview(), strength, user);
    CHECK(term(c->terms(1, 1, 0), "interpolated") == 27 * u * 8 * 2);
    // At (2, 1): the scene's x step is 8 (to the centre), y step 0; the bloom's y step is 2
    // (to (2, 0)), scaled by the strength: 27u (8 + 0.5 * 2).
    CHECK(term(c->terms(2, 1, 0), "interpolated") == 27 * u * (8 + 0.5 * 2));
    // Clamp to edge: (0, 0) has neighbours only inside; none differ. Green is 0 everywhere.
    CHECK(term(c->terms(0, 0, 0), "interpolated") == 0.0);
    CHECK(term(c->terms(1, 1, 1), "interpolated") == 0.0);
    // texelFetch (bloomref's own shaders): no such term.
    const BoundContext own{&p, Storage::f32, 1};
    CHECK(term(tol::composite_bounds(scene.cview(), bloom.cview(), scene.cview(), strength, own)
                   ->terms(1, 1, 0), "interpolated") == 0.0);
  }
}

TEST_CASE("output: the bound follows pow's slope towards black", "[parity][bounds]") {
  const DeviceProfile p = profile_llvmpipe();
  const BoundContext ctx{&p, Storage::f32, 1};
  // gamma 2, so out = exp2(0.5 log2 m).
  // m = 1 (log2 within [0.5, 2]: 2^-21 absolute): out = 1, t = 0: log2 term ln2 * 0.5 * 2^-21,
  // no rounding of g * log2 (t = 0), exp2 (3 + 0) * 2u.
  {
    const Image m = row({1});
    const auto b = tol::output_bounds(m.cview(), m.cview(), 2.0f, ctx);
    CHECK(close(total(b->terms(0, 0, 0)), std::log(2.0) * 0x1p-22 + 6 * u));
  }
  // m = 2^-20: log2 m = -20 (3 ULP: 6u * 20 = 120u), t = -10, out = 2^-10. log2 term
  // 2^-10 ln2 0.5 * 120u = 60 ln2 2^-34; g * log2 rounding 2^-10 ln2 * 10 * 3.5u = 35 ln2 2^-34;
  // exp2 2^-10 (3 + 20) 2u = 46 * 2^-34. Relative to the output that is (95 ln2 + 46) 2^-24,
  // growing with |log2 m| where m = 1 gave (ln2 2^2 + 6) 2^-24: the slope of the curve.
  {
    const Image m = row({0x1p-20f});
    const auto b = tol::output_bounds(m.cview(), m.cview(), 2.0f, ctx);
    const auto t = b->terms(0, 0, 0);
    CHECK(close(term(t, "log2"), 60 * std::log(2.0) * 0x1p-34));
    CHECK(close(term(t, "1/gamma"), 35 * std::log(2.0) * 0x1p-34));
    CHECK(close(term(t, "exp2"), 46 * 0x1p-34));
  }
  // At 0: pow(0, 0.5) may come out as 2^(-149 / 2) (log2(0) as -149). A denormal that the
  // device may flush: anything between 0 and pow(2^-126, 0.5) = 2^-63. NaN: unpinned.
  const Image edge = row({0.0f, 0x1p-130f, NAN});
  const auto b = tol::output_bounds(edge.cview(), edge.cview(), 2.0f, ctx);
  CHECK(close(total(b->terms(0, 0, 0)), std::exp2(-74.5)));
  CHECK(total(b->terms(1, 0, 0)) == 0x1p-63);
  CHECK(std::isinf(total(b->terms(2, 0, 0))));
}

TEST_CASE("an end-to-end bound carried through gamma covers the image of its interval",
          "[parity][bounds]") {
  // The width of [m - e, m + e] under x^(1/gamma), in long double: through_output must be at
  // least it, and (e at most 2^-10 of m, the mean value bound) within 0.11% of it; near black
  // (e beyond 2^-10 of m) the interval's image itself.
  // For e below m, as m^g ((1 + r)^g - (1 - r)^g) with r = e / m, through expm1 and log1p: the
  // two terms have opposite signs, so nothing cancels however small r is.
  const auto width = [](long double m, long double e, long double gamma) {
    const long double g = 1.0L / gamma, r = e / m;
    if (r >= 1) return std::pow(m + e, g);
    return std::pow(m, g) * (std::expm1(g * std::log1p(r)) - std::expm1(g * std::log1p(-r)));
  };
  int mean_value = 0;
  for (const double gamma : {2.2, 1.0, 0.5})
    for (const double m : {1e-30, 1e-6, 0.01, 0.5, 1.0, 3.7, 1e4})
      for (const double r : {0.0, 1e-12, 1e-7, 0x1p-11, 0x1p-10, 0x1p-9, 0.3, 1.0, 4.0}) {
        const double e = m * r;
        const long double want = width(m, e, gamma);
        const double got = tol::through_output(m, e, gamma);
        INFO("gamma " << gamma << " m " << m << " e " << e);
        // The float the result is rounded to: half a ULP below (2^-150 below FLT_MIN).
        CHECK(got >= static_cast<double>(want) * (1 - 0x1p-24) - 0x1p-150);
        if (r > 0 && r <= 0x1p-10) {
          ++mean_value;
          CHECK(got <= static_cast<double>(want) * 1.0011 + 0x1p-150);
        } else if (r > 0x1p-10) {
          // The ends through powf, moved outward by 2^-18 each: within 1% of the width.
          CHECK(got <= static_cast<double>(want) * 1.01 + 0x1p-150);
        }
      }
  CHECK(mean_value > 20);
  // Beyond the mean value bound, at random: never below the width, within 1% above it.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int below = 0, loose = 0;
  for (int i = 0; i < 20000; ++i) {
    const double gamma = std::array<double, 5>{2.2, 2.4, 1.8, 1.1, 1.0}[i % 5];
    const double m = std::pow(10.0, -35 + 65 * u(rng)), r = std::pow(2.0, -10 + 14 * u(rng));
    const long double want = width(m, m * r, gamma);
    const double got = tol::through_output(m, m * r, gamma);
    below += got < static_cast<double>(want) * (1 - 0x1p-24);
    loose += got > static_cast<double>(want) * 1.01;
  }
  CHECK(below == 0);
  CHECK(loose == 0);
  CHECK(std::isinf(tol::through_output(NAN, 1.0, 2.2)));
  CHECK(std::isinf(tol::through_output(1.0, INFINITY, 2.2)));
}

TEST_CASE("next_up and next_down step as std::nextafter does", "[parity]") {
  using bloomref::parity::detail::next_down;
  using bloomref::parity::detail::next_up;
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> values{0.0f, -0.0f, 1.0f, -1.0f, 3.5e-42f, -3.5e-42f, 0x1p-126f, -0x1p-126f,
                            std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::denorm_min(), -std::numeric_limits<float>::denorm_min(),
                            inf, -inf, 65504.0f, 0.1f};
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uint32_t> bits;
  for (int i = 0; i < 10000; ++i) {
    const std::uint32_t b = bits(rng);
    float v;
    std::memcpy(&v, &b, sizeof v);
    if (!std::isnan(v)) values.push_back(v);
  }
  for (float v : values) {
    INFO(v);
    const float up = std::nextafter(v, inf), down = std::nextafter(v, -inf);
    CHECK(next_up(v) == up);
    CHECK(std::signbit(next_up(v)) == std::signbit(up));
    CHECK(next_down(v) == down);
    CHECK(std::signbit(next_down(v)) == std::signbit(down));
  }
  CHECK(std::isnan(next_up(std::nanf(""))));
  CHECK(std::isnan(next_down(std::nanf(""))));
}

TEST_CASE("R11G11B10 overflow: each channel's largest value or Inf, nothing else",
          "[parity][bounds]") {
  // The largest finite values, by hand: (2 - 2^-m) 2^15 with m = 6 (R, G) and 5 (B).
  const double rg = (2.0 - 1.0 / 64) * 32768, b = (2.0 - 1.0 / 32) * 32768;
  REQUIRE(rg == 65024.0);
  REQUIRE(b == 64512.0);
  CHECK(tol::storage_limit(Storage::r11g11b10, 0) == rg);
  CHECK(tol::storage_limit(Storage::r11g11b10, 2) == b);
  const DeviceProfile p = profile_llvmpipe();
  const auto r11 = Storage::r11g11b10;
  // Beyond B's range, B saturates to 64512 (or overflows to Inf); 65024 is not a B value.
  CHECK(tol::special_case(66877.5, b, r11, p, 2048, 2) == 1);
  CHECK(tol::special_case(66877.5, INFINITY, r11, p, 2048, 2) == 1);
  CHECK(tol::special_case(66877.5, rg, r11, p, 2048, 2) == 0);
  CHECK(tol::special_case(66877.5, 60000, r11, p, 2048, 2) == 0);
  // R beyond its range saturates to 65024; 64512 there is a wrong value.
  CHECK(tol::special_case(69118.9, rg, r11, p, 2048, 0) == 1);
  CHECK(tol::special_case(69118.9, b, r11, p, 2048, 0) == 0);
  // Within R's range (above B's) a value is a number, judged against its bound.
  CHECK(tol::special_case(64800.0, 64768.0, r11, p, 2048, 0) == -1);
  CHECK(tol::special_case(64800.0, b, r11, p, 2048, 2) == 1);
  // Beyond the limit by less than the bound: the device's errors may leave it below, a number.
  CHECK(tol::special_case(64512.004, 63488.0, r11, p, 2048, 2) == -1);
  // Beyond it by more than the bound: the limit, Inf, or a mismatch.
  CHECK(tol::special_case(66000.0, 63488.0, r11, p, 0.5, 2) == 0);
  // f16 keeps its profile's rule: llvmpipe saturates to 65504.
  CHECK(tol::special_case(70000.0, 65504.0, Storage::f16, p, 32, 0) == 1);
  CHECK(tol::special_case(70000.0, 65024.0, Storage::f16, p, 32, 0) == 0);
}
