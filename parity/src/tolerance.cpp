// The per-value bounds. Notation: u = 2^-24 (f32 unit roundoff), ULP of a float y <= 2^-23 |y|.
#include "tolerance.h"

#include <algorithm>
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
            if (!std::isfinite(t)) continue;
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

// Sub-texel coordinate error of a lookup on an axis of n texels, in texels: the shader's
// s = (x + 0.5) / n and d = 1 / n (division_ulps each), d * o and s +- d o (one rounding each),
// then the sampler's u = s * n - 0.5 (two roundings of values below n); plus one weight quantum
// when the device uses fixed-point weights (it may round where the oracle truncates).
double coordinate_error(int n, const DeviceProfile& p) {
  return n * kU * (2 * p.division_ulps + 4) +
         (p.subtexel_bits > 0 ? std::ldexp(1.0, -p.subtexel_bits) : 0.0);
}

// Fills an image by a per-value function, in parallel.
template <class F>
void fill_values(Image& out, int threads, F f) {
  parallel_rows(out.height(), threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < out.width(); ++x)
        for (int c = 0; c < 3; ++c) out.pixel(x, y)[c] = static_cast<float>(f(x, y, c));
  });
}

double sum(const std::vector<Term>& t) {
  double s = 0;
  for (const Term& x : t) s += x.value;
  return s;
}

// A stage whose bound is a sum of terms computed per value.
template <class F>
struct TermBounds : StageBounds {
  F f;
  int threads;
  TermBounds(F fn, int t) : f(std::move(fn)), threads(t) {}
  void fill(Image& bound) const override {
    fill_values(bound, threads, [&](int x, int y, int c) { return sum(f(x, y, c)); });
  }
  std::vector<Term> terms(int x, int y, int c) const override { return f(x, y, c); }
};

template <class F>
std::unique_ptr<StageBounds> make(F f, int threads) {
  return std::make_unique<TermBounds<F>>(std::move(f), threads);
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
  return make(
      [=](int x, int y, int c) {
        const double v = oracle.pixel(x, y)[c];
        return std::vector<Term>{{"storage", storage_term(v, ctx.storage, *ctx.profile)},
                                 {"denormal flush",
                                  ctx.profile->flush_denormals && std::fabs(v) < 0x1p-126
                                      ? std::fabs(v) : 0.0}};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> bright_bounds(ConstImageView sanitized, float threshold,
                                           BoundContext ctx) {
  return make(
      [=](int x, int y, int c) {
        const float* s = sanitized.pixel(x, y);
        // luminance: 3 products and 2 sums, fused or not: |dL| <= 4u sum |w_i c_i|.
        const double mags = std::fabs(0.2126 * s[0]) + std::fabs(0.7152 * s[1]) +
                            std::fabs(0.0722 * s[2]);
        const double l = luminance(s[0], s[1], s[2]);
        const bool tie = !ctx.profile->precise_luminance &&
                         std::fabs(l - threshold) <= 4 * kU * mags + denormal_floor(*ctx.profile);
        const double v = s[c];
        return std::vector<Term>{
            {"threshold within luminance rounding (either side is right)",
             tie ? std::max({std::fabs(s[0]), std::fabs(s[1]), std::fabs(s[2])}) : 0.0},
            {"storage", storage_term(v, ctx.storage, *ctx.profile)}};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> blur_bounds(ConstImageView src, ConstImageView oracle, Axis axis,
                                         const Kernel& k, BoundContext ctx) {
  auto win = std::make_shared<Window>(window_stats(src, axis, ctx.threads));
  const bool hz = axis == Axis::horizontal;
  const int n_along = hz ? src.width : src.height, n_across = hz ? src.height : src.width;
  const double delta = coordinate_error(n_along, *ctx.profile) +
                       coordinate_error(n_across, *ctx.profile);
  const int taps = k.taps();
  return make(
      [=](int x, int y, int c) {
        double coord = 0, arith = 0;
        const int pos = hz ? x : y;
        for (std::size_t i = 0; i < k.offsets_f64.size(); ++i)
          for (double sign : {1.0, -1.0}) {
            if (i == 0 && sign < 0) continue;
            const int b = tap_base(pos, sign * k.offsets_f64[i], n_along);
            const int bx = hz ? b : x, by = hz ? y : b;
            const double w = k.weights_f64[i];
            coord += w * delta * win->range.pixel(bx, by)[c];
            // The filter's lerp (3 roundings) and the tap sums (2 per tap): (3 + 2 T) u |t|.
            arith += w * (3 + 2 * taps) * kU * win->magnitude.pixel(bx, by)[c];
          }
        return std::vector<Term>{
            {"coordinate rounding (x local range)", coord},
            {"filter and accumulation rounding", arith},
            {"storage", storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile)},
            {"denormal flush", denormal_floor(*ctx.profile)}};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> composite_bounds(ConstImageView scene, ConstImageView bloom,
                                              ConstImageView oracle, float strength,
                                              BoundContext ctx) {
  return make(
      [=](int x, int y, int c) {
        const double s = scene.pixel(x, y)[c], b = bloom.pixel(x, y)[c];
        return std::vector<Term>{
            {"product and sum rounding", 2 * kU * (std::fabs(s) + std::fabs(strength * b))},
            {"storage", storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile)},
            {"denormal flush", denormal_floor(*ctx.profile)}};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> tonemap_bounds(ConstImageView hdr, ConstImageView oracle,
                                            float exposure, BoundContext ctx) {
  return make(
      [=](int x, int y, int c) {
        const double h = hdr.pixel(x, y)[c];
        const double a = -h * exposure;  // the argument of exp
        const double e = std::exp(a);
        return std::vector<Term>{
            {"exp: (3 + 2|x|) ULP (GLSL 4.50)", e * (3 + 2 * std::fabs(a)) * 2 * kU},
            {"argument rounding (x = -hdr * exposure)", e * std::fabs(a) * kU},
            {"1 - e rounding", (1 + e) * kU},
            {"storage", storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile)},
            {"denormal flush", denormal_floor(*ctx.profile)}};
      },
      ctx.threads);
}

std::unique_ptr<StageBounds> output_bounds(ConstImageView mapped, ConstImageView oracle,
                                           float gamma, BoundContext ctx) {
  return make(
      [=](int x, int y, int c) {
        const double m = mapped.pixel(x, y)[c];
        const double storage = storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile);
        if (!(m > 0))
          // pow(0, g) = exp2(g * log2(0)): exact 0 unless log2(0) is a large finite negative
          // (-149 at worst): 2^(-149 g) is below 1e-20 for gamma 2.2.
          return std::vector<Term>{{"pow at 0", std::exp2(-149.0 / gamma)}, {"storage", storage}};
        const double g = 1.0 / gamma;
        const double l = std::log2(m), t = g * l, o = std::exp2(t);
        const double dl = (m >= 0.5 && m <= 2.0) ? std::ldexp(1.0, -21) : 3 * 2 * kU * std::fabs(l);
        return std::vector<Term>{
            {"log2: 3 ULP, 2^-21 absolute in [0.5, 2] (GLSL 4.50)", o * std::log(2.0) * g * dl},
            {"1/gamma and g * log2 rounding",
             o * std::log(2.0) * std::fabs(t) * (1 + ctx.profile->division_ulps) * kU},
            {"exp2: (3 + 2|x|) ULP", o * (3 + 2 * std::fabs(t)) * 2 * kU},
            {"storage", storage}};
      },
      ctx.threads);
}

Image propagate_blur(ConstImageView error, Axis axis, const Kernel& k, int threads) {
  const Window win = window_stats(error, axis, threads);
  const bool hz = axis == Axis::horizontal;
  const int n = hz ? error.width : error.height;
  Image out(error.width, error.height, 0.0f);
  fill_values(out, threads, [&](int x, int y, int c) {
    double s = 0;
    for (std::size_t i = 0; i < k.offsets_f64.size(); ++i)
      for (double sign : {1.0, -1.0}) {
        if (i == 0 && sign < 0) continue;
        const int b = tap_base(hz ? x : y, sign * k.offsets_f64[i], n);
        s += k.weights_f64[i] * win.magnitude.pixel(hz ? b : x, hz ? y : b)[c];
      }
    return s;
  });
  return out;
}

}  // namespace bloomref::parity::detail
