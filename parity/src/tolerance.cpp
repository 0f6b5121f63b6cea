// The per-value bounds. Notation: U = the profile's unit roundoff (2^-24 for f32 arithmetic,
// kU; 2^-11 for mediump), ULP of a float y <= 2^-23 |y|.
#include "tolerance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

#include "bloomref/parallel.h"

namespace bloomref::parity::detail {
namespace {

double ulp16(double v) {
  const double a = std::fabs(v);
  const int e = a > 0 ? std::max(std::ilogb(a), -14) : -14;
  return std::ldexp(1.0, e - 10);
}

// A NaN or Inf texel where a lookup may touch it makes the lookup's result unpinned: the GL
// formula (1 - a) t0 + a t1 turns 0 * Inf into NaN, llvmpipe computes t0 + a (t1 - t0) (Inf -
// Inf = NaN, measured on BrightRingsNanInf.exr), the oracle leaves zero weights out. Such values
// get an infinite bound ("the footprint holds NaN/Inf"): where NaN/Inf appear is compared, not
// which of them. The window magnitude carries it as +Inf.
//
// Local range (max - min) and magnitude (max |t|) of each channel over the texels a tap based
// at texel p may touch once its coordinate is a little off: [p-1, p+2] along the blurred axis
// (linear5 taps sit between p and p+1), [q-1, q+1] across it.
struct Window {
  Image range, magnitude;
};

Window window_stats(ConstImageView src, Axis axis, int threads) {
  const int w = src.width, h = src.height;
  const bool hz = axis == Axis::horizontal;
  // Pass 1 along the axis: min, max, max|.| over [p-1, p+2].
  Image lo(w, h), hi(w, h), mag(w, h);
  parallel_rows(h, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          float mn = INFINITY, mx = -INFINITY, ma = 0;
          for (int d = -1; d <= 2; ++d) {
            const int xx = hz ? std::clamp(x + d, 0, w - 1) : x;
            const int yy = hz ? y : std::clamp(y + d, 0, h - 1);
            const float t = src.pixel(xx, yy)[c];
            if (!std::isfinite(t)) {
              ma = INFINITY;  // a NaN/Inf texel in the footprint: see nonfinite_footprint
              continue;
            }
            mn = std::min(mn, t);
            mx = std::max(mx, t);
            ma = std::max(ma, std::fabs(t));
          }
          lo.pixel(x, y)[c] = mn;
          hi.pixel(x, y)[c] = mx;
          mag.pixel(x, y)[c] = ma;
        }
  });
  // Pass 2 across: [q-1, q+1].
  Window out{Image(w, h, 0.0f), Image(w, h, 0.0f)};
  parallel_rows(h, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          float mn = INFINITY, mx = -INFINITY, ma = 0;
          for (int d = -1; d <= 1; ++d) {
            const int xx = hz ? x : std::clamp(x + d, 0, w - 1);
            const int yy = hz ? std::clamp(y + d, 0, h - 1) : y;
            mn = std::min(mn, lo.pixel(xx, yy)[c]);
            mx = std::max(mx, hi.pixel(xx, yy)[c]);
            ma = std::max(ma, mag.pixel(xx, yy)[c]);
          }
          out.range.pixel(x, y)[c] = mx >= mn ? mx - mn : 0.0f;
          out.magnitude.pixel(x, y)[c] = ma;
        }
  });
  return out;
}

// A tap's base texel along the axis: floor of its exact position, clamped.
int tap_base(int pos, double offset, int n) {
  return std::clamp(static_cast<int>(std::floor(pos + offset)), 0, n - 1);
}

// For each position along the axis, the base texel of every tap (centre, +o1, -o1, ...) and its
// weight: computed once per pass instead of per value.
struct TapBases {
  int taps = 0;
  std::vector<int> base;
  std::vector<double> weight;
};

TapBases tap_bases(int n, const Kernel& k) {
  TapBases t;
  t.taps = k.taps();
  for (int pos = 0; pos < n; ++pos)
    for (std::size_t i = 0; i < k.offsets_f64.size(); ++i)
      for (double sign : {1.0, -1.0}) {
        if (i == 0 && sign < 0) continue;
        t.base.push_back(tap_base(pos, sign * k.offsets_f64[i], n));
        t.weight.push_back(k.weights_f64[i]);
      }
  return t;
}

// out(x, y) = sum over taps of weight * img(tap base), per channel (img: a window statistic).
Image weighted_tap_sum(ConstImageView img, Axis axis, const TapBases& t, int threads) {
  const bool hz = axis == Axis::horizontal;
  Image out(img.width, img.height, 0.0f);
  parallel_rows(img.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < img.width; ++x) {
        const int pos = hz ? x : y;
        double acc[3] = {0, 0, 0};
        for (int k = 0; k < t.taps; ++k) {
          const int b = t.base[std::size_t(pos) * t.taps + k];
          const float* v = hz ? img.pixel(b, y) : img.pixel(x, b);
          for (int c = 0; c < 3; ++c) acc[c] += t.weight[std::size_t(pos) * t.taps + k] * v[c];
        }
        float* o = out.pixel(x, y);
        for (int c = 0; c < 3; ++c) o[c] = static_cast<float>(acc[c]);
      }
  });
  return out;
}

}  // namespace

double storage_term(double v, Storage s, const DeviceProfile& p) {
  if (s == Storage::f32 || !std::isfinite(v)) return 0.0;
  // Toward zero loses up to one ULP; nearest-even half of one.
  return (p.half_toward_zero ? 1.0 : 0.5) * ulp16(v);
}

double denormal_floor(const DeviceProfile& p) {
  return p.flush_denormals ? std::ldexp(1.0, -120) : 0.0;
}

std::unique_ptr<StageBounds> input_bounds(ConstImageView oracle, BoundContext ctx) {
  return make_bounds(
      {"storage", "denormal flush"},
      [=](int x, int y, int c) {
        const double v = oracle.pixel(x, y)[c];
        return Values{storage_term(v, ctx.storage, *ctx.profile),
                      ctx.profile->flush_denormals && std::fabs(v) < 0x1p-126 ? std::fabs(v) : 0.0};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> bright_bounds(ConstImageView sanitized, float threshold,
                                           BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  return make_bounds(
      {"threshold within luminance rounding (either side is right)", "storage"},
      [=](int x, int y, int c) {
        const float* s = sanitized.pixel(x, y);
        // luminance: 3 products and 2 sums, fused or not: |dL| <= 4u sum |w_i c_i|.
        const double mags = std::fabs(0.2126 * s[0]) + std::fabs(0.7152 * s[1]) +
                            std::fabs(0.0722 * s[2]);
        const double l = luminance(s[0], s[1], s[2]);
        const bool tie = !ctx.profile->precise_luminance &&
                         std::fabs(l - threshold) <= 4 * U * mags + denormal_floor(*ctx.profile);
        const double v = s[c];
        return Values{tie ? std::max({std::fabs(s[0]), std::fabs(s[1]), std::fabs(s[2])}) : 0.0,
                      storage_term(v, ctx.storage, *ctx.profile)};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> blur_bounds(ConstImageView src, ConstImageView oracle, Axis axis,
                                         const Kernel& k, BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  const bool hz = axis == Axis::horizontal;
  const int n_along = hz ? src.width : src.height, n_across = hz ? src.height : src.width;
  const Window win = window_stats(src, axis, ctx.threads);
  const TapBases bases = tap_bases(n_along, k);
  // sum_k w_k * (local range at tap k) and sum_k w_k * (local magnitude at tap k).
  auto range = std::make_shared<Image>(weighted_tap_sum(win.range.cview(), axis, bases, ctx.threads));
  auto magnitude =
      std::make_shared<Image>(weighted_tap_sum(win.magnitude.cview(), axis, bases, ctx.threads));
  const double delta = coordinate_error(n_along, *ctx.profile) +
                       coordinate_error(n_across, *ctx.profile);
  const int taps = k.taps();
  return make_bounds(
      {"coordinate rounding (x local range)",
       "filter and accumulation rounding (Inf: NaN/Inf in the footprint)", "storage",
       "denormal flush"},
      [=](int x, int y, int c) {
        // The filter's lerp (3 roundings) and the tap sums (2 per tap): (3 + 2 T) u |t|.
        return Values{delta * range->pixel(x, y)[c],
                      (3 + 2 * taps) * U * magnitude->pixel(x, y)[c],
                      storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile),
                      denormal_floor(*ctx.profile)};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> composite_bounds(ConstImageView scene, ConstImageView bloom,
                                              ConstImageView oracle, float strength,
                                              BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  return make_bounds(
      {"product and sum rounding", "storage", "denormal flush"},
      [=](int x, int y, int c) {
        const double s = scene.pixel(x, y)[c], b = bloom.pixel(x, y)[c];
        return Values{2 * U * (std::fabs(s) + std::fabs(strength * b)),
                      storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile),
                      denormal_floor(*ctx.profile)};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> tonemap_bounds(ConstImageView hdr, ConstImageView oracle,
                                            float exposure, BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  return make_bounds(
      {"exp: (3 + 2|x|) ULP (GLSL 4.50)", "argument rounding (x = -hdr * exposure)",
       "1 - e rounding (series below |x| = 0.5)", "storage", "denormal flush"},
      [=](int x, int y, int c) {
        const double h = hdr.pixel(x, y)[c];
        const double a = -h * exposure;  // the argument of exp
        if (std::fabs(a) < 0.5) {
          // The series path (stages.cpp): 7 Horner steps of 3 roundings each, and the rounding
          // of the argument (slope ~1 there). Both sides run it `precise`, so usually 0.
          const double m = -std::expm1(a);
          return Values{0, std::fabs(a) * U * 1.7, (3 * 7 + 1) * U * std::fabs(m),
                        storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile),
                        denormal_floor(*ctx.profile)};
        }
        const double e = std::exp(a);
        return Values{e * (3 + 2 * std::fabs(a)) * 2 * U, e * std::fabs(a) * U, (1 + e) * U,
                      storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile),
                      denormal_floor(*ctx.profile)};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> output_bounds(ConstImageView mapped, ConstImageView oracle,
                                           float gamma, BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  return make_bounds(
      {"pow at 0 or a denormal (Inf: max(NaN, 0) is not pinned)", "log2: 3 ULP, 2^-21 absolute in [0.5, 2] (GLSL 4.50)",
       "1/gamma and g * log2 rounding", "exp2: (3 + 2|x|) ULP", "storage"},
      [=](int x, int y, int c) {
        const double m = mapped.pixel(x, y)[c];
        const double storage = storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile);
        // GLSL's max(NaN, 0) may be 0 (llvmpipe) or NaN (the oracle): either is right.
        if (std::isnan(m)) return Values{INFINITY, 0, 0, 0, 0};
        if (!(m > 0))
          // pow(0, g) = exp2(g * log2(0)): exact 0 unless log2(0) is a large finite negative
          // (-149 at worst): 2^(-149 g) is below 1e-20 for gamma 2.2.
          return Values{std::exp2(-149.0 / gamma), 0, 0, 0, storage};
        const double g = 1.0 / gamma;
        // A denormal input may be flushed (read as 0) or fed to log2 as its nearest normal: the
        // result lies between 0 and pow(2^-126, g) (measured: llvmpipe compute gives 4.2e-18
        // for m ~ 1e-41, where the truth is 3.4e-19).
        if (ctx.profile->flush_denormals && m < 0x1p-126)
          return Values{std::pow(0x1p-126, g), 0, 0, 0, storage};
        const double l = std::log2(m), t = g * l, o = std::exp2(t);
        const double dl = (m >= 0.5 && m <= 2.0) ? std::ldexp(1.0, -21) * (U / kU) : 3 * 2 * U * std::fabs(l);
        return Values{0, o * std::log(2.0) * g * dl,
                      o * std::log(2.0) * std::fabs(t) * (1 + ctx.profile->division_ulps) * U,
                      o * (3 + 2 * std::fabs(t)) * 2 * U, storage};
      },
      ctx.threads);
}

Image propagate_blur(ConstImageView error, Axis axis, const Kernel& k, int threads) {
  const Window win = window_stats(error, axis, threads);
  const int n = axis == Axis::horizontal ? error.width : error.height;
  return weighted_tap_sum(win.magnitude.cview(), axis, tap_bases(n, k), threads);
}

}  // namespace bloomref::parity::detail
