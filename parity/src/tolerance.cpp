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
// (linear5 taps sit between p and p+1), [q-1, q+1] across it. Computed for the rows a band's
// taps reach, in two passes: along the axis, then across. Min and max are exact, so the band's
// statistics are the whole image's.

// Pass 1 at one texel and channel: min, max and max |.| of the finite values among n values
// `stride` apart (a non-finite one makes the magnitude +Inf).
inline void along(const float* t, std::ptrdiff_t stride, int n, float& mn, float& mx, float& ma) {
  mn = INFINITY;
  mx = -INFINITY;
  ma = 0;
  for (int d = 0; d < n; ++d) {
    const float v = t[d * stride];
    if (!std::isfinite(v)) {
      ma = INFINITY;  // a NaN/Inf texel in the footprint: see above
      continue;
    }
    mn = std::min(mn, v);
    mx = std::max(mx, v);
    ma = std::max(ma, std::fabs(v));
  }
}

// Per-thread scratch of a band (reused band after band: stage-wide buffers would be mapped and
// faulted in afresh on every allocation).
struct WindowScratch {
  std::vector<float> lo, hi, mag;       // pass 1, RGBA rows
  std::vector<float> range, magnitude;  // the window statistics, RGBA rows
};

WindowScratch& window_scratch() {
  thread_local WindowScratch s;
  return s;
}

float* sized(std::vector<float>& v, std::size_t n) {
  if (v.size() < n) v.resize(n);
  return v.data();
}

// Window statistics of rows [r0, r1) of src into range / magnitude (RGBA rows; range may be
// null). Horizontal: pass 1 along x over [x-1, x+2] on rows [r0-1, r1+1), pass 2 across the rows
// y-1..y+1. Vertical: per row, pass 1 along y over [y-1, y+2], pass 2 across x-1..x+1. Edges
// clamp.
void window_rows(ConstImageView src, Axis axis, int r0, int r1, float* range, float* magnitude,
                 WindowScratch& s) {
  const int w = src.width, h = src.height;
  const std::size_t row = std::size_t(w) * kChannels;
  auto pass2 = [&](const float* lo[3], const float* hi[3], const float* ma[3], int step, int r) {
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        float mn = INFINITY, mx = -INFINITY, m = 0;
        for (int d = 0; d < 3; ++d) {
          const int xx = step ? std::clamp(x + d - 1, 0, w - 1) : x;
          const std::size_t at = std::size_t(xx) * kChannels + c;
          mn = std::min(mn, lo[d][at]);
          mx = std::max(mx, hi[d][at]);
          m = std::max(m, ma[d][at]);
        }
        const std::size_t o = std::size_t(r - r0) * row + std::size_t(x) * kChannels + c;
        if (range) range[o] = mx >= mn ? mx - mn : 0.0f;
        magnitude[o] = m;
      }
  };
  if (axis == Axis::horizontal) {
    const int p0 = std::max(r0 - 1, 0), p1 = std::min(r1 + 1, h);
    const std::size_t n = std::size_t(p1 - p0) * row;
    float *lo = sized(s.lo, n), *hi = sized(s.hi, n), *ma = sized(s.mag, n);
    for (int y = p0; y < p1; ++y) {
      const float* in = src.row(y);
      const std::size_t o = std::size_t(y - p0) * row;
      for (int x = 0; x < w; ++x) {
        const bool inner = x >= 1 && x + 2 < w;
        for (int c = 0; c < 3; ++c) {
          float* l = lo + o + std::size_t(x) * kChannels + c;
          float* g = hi + o + std::size_t(x) * kChannels + c;
          float* m = ma + o + std::size_t(x) * kChannels + c;
          if (inner) {
            along(in + std::size_t(x - 1) * kChannels + c, kChannels, 4, *l, *g, *m);
          } else {
            float t[4];
            for (int d = -1; d <= 2; ++d) t[d + 1] = in[std::size_t(std::clamp(x + d, 0, w - 1)) * kChannels + c];
            along(t, 1, 4, *l, *g, *m);
          }
        }
      }
    }
    for (int r = r0; r < r1; ++r) {
      const float *l[3], *g[3], *m[3];
      for (int d = 0; d < 3; ++d) {
        const std::size_t o = std::size_t(std::clamp(r + d - 1, 0, h - 1) - p0) * row;
        l[d] = lo + o;
        g[d] = hi + o;
        m[d] = ma + o;
      }
      pass2(l, g, m, 0, r);
    }
  } else {
    float *lo = sized(s.lo, row), *hi = sized(s.hi, row), *ma = sized(s.mag, row);
    for (int r = r0; r < r1; ++r) {
      const float* in[4];
      for (int d = -1; d <= 2; ++d) in[d + 1] = src.row(std::clamp(r + d, 0, h - 1));
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          const std::size_t at = std::size_t(x) * kChannels + c;
          const float t[4] = {in[0][at], in[1][at], in[2][at], in[3][at]};
          along(t, 1, 4, lo[at], hi[at], ma[at]);
        }
      const float *l[3] = {lo, lo, lo}, *g[3] = {hi, hi, hi}, *m[3] = {ma, ma, ma};
      pass2(l, g, m, 1, r);
    }
  }
}

}  // namespace

// For each position along the axis, the base texel of every tap (centre, +o1, -o1, ...: floor of
// its exact position, clamped) and its weight: computed once per pass instead of per value.
struct BlurPropagation::Taps {
  Axis axis = Axis::horizontal;
  int taps = 0;
  std::vector<int> base;
  std::vector<double> weight;

  Taps(Axis a, int n, const Kernel& k) : axis(a), taps(k.taps()) {
    for (int pos = 0; pos < n; ++pos)
      for (std::size_t i = 0; i < k.offsets_f64.size(); ++i)
        for (double sign : {1.0, -1.0}) {
          if (i == 0 && sign < 0) continue;
          base.push_back(std::clamp(static_cast<int>(std::floor(pos + sign * k.offsets_f64[i])), 0, n - 1));
          weight.push_back(k.weights_f64[i]);
        }
  }

  // sum over taps of weight * statistic(tap base), per channel, for rows [y0, y1) of src's
  // window statistics (range_sum may be null: magnitude only). RGBA rows.
  void sums(ConstImageView src, int y0, int y1, float* range_sum, float* magnitude_sum) const {
    const bool hz = axis == Axis::horizontal;
    const int w = src.width;
    // The window rows the band's taps read: its own (horizontal), or every tap's base row.
    int r0 = y0, r1 = y1;
    if (!hz) {
      r0 = *std::min_element(base.begin() + std::ptrdiff_t(y0) * taps, base.begin() + std::ptrdiff_t(y0 + 1) * taps);
      r1 = 1 + *std::max_element(base.begin() + std::ptrdiff_t(y1 - 1) * taps, base.begin() + std::ptrdiff_t(y1) * taps);
    }
    WindowScratch& s = window_scratch();
    const std::size_t row = std::size_t(w) * kChannels, n = std::size_t(r1 - r0) * row;
    float* range = range_sum ? sized(s.range, n) : nullptr;
    float* magnitude = sized(s.magnitude, n);
    window_rows(src, axis, r0, r1, range, magnitude, s);
    for (const auto& [stat, out] : {std::pair<const float*, float*>{range, range_sum},
                                    std::pair<const float*, float*>{magnitude, magnitude_sum}}) {
      if (!out) continue;
      for (int y = y0; y < y1; ++y)
        for (int x = 0; x < w; ++x) {
          const int pos = hz ? x : y;
          double acc[3] = {0, 0, 0};
          for (int k = 0; k < taps; ++k) {
            const int b = base[std::size_t(pos) * taps + k];
            const float* v = hz ? stat + std::size_t(y - r0) * row + std::size_t(b) * kChannels
                                : stat + std::size_t(b - r0) * row + std::size_t(x) * kChannels;
            for (int c = 0; c < 3; ++c) acc[c] += weight[std::size_t(pos) * taps + k] * v[c];
          }
          float* o = out + std::size_t(y - y0) * row + std::size_t(x) * kChannels;
          for (int c = 0; c < 3; ++c) o[c] = static_cast<float>(acc[c]);
        }
    }
  }
};

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
      oracle.width, ctx.threads);
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
      sanitized.width, ctx.threads);
}

namespace {

// A blur pass's bound: per value, the coordinate error times the weighted local range of the
// taps' windows, the filter's and the sums' rounding times their weighted magnitude, storage
// and the denormal floor.
class BlurBounds : public StageBounds {
 public:
  BlurBounds(ConstImageView src, ConstImageView oracle, Axis axis, const Kernel& k, BoundContext ctx)
      : src_(src), oracle_(oracle), ctx_(ctx), taps_(k.taps()),
        bases_(std::make_shared<BlurPropagation::Taps>(
            axis, axis == Axis::horizontal ? src.width : src.height, k)) {
    threads = ctx.threads;
    const bool hz = axis == Axis::horizontal;
    delta_ = coordinate_error(hz ? src.width : src.height, *ctx.profile) +
             coordinate_error(hz ? src.height : src.width, *ctx.profile);
  }

  void rows(int y0, int y1, float* bound, float* rounding) const override {
    const std::size_t n = std::size_t(y1 - y0) * src_.width * kChannels;
    Sums& s = scratch();
    float* range = sized(s.range, n);
    float* magnitude = sized(s.magnitude, n);
    bases_->sums(src_, y0, y1, range, magnitude);
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < src_.width; ++x) {
        const std::size_t at = (std::size_t(y - y0) * src_.width + x) * kChannels;
        for (int c = 0; c < 3; ++c) {
          const Values v = values(range[at + c], magnitude[at + c], oracle_.pixel(x, y)[c]);
          if (bound) bound[at + c] = static_cast<float>(0.0 + v[0] + v[1] + v[2] + v[3] + v[4]);
          if (rounding) rounding[at + c] = static_cast<float>(0.0 + v[1] + v[2] + v[3]);
        }
      }
  }

  std::vector<Term> terms(int x, int y, int c) const override {
    std::vector<float> range(std::size_t(src_.width) * kChannels),
        magnitude(std::size_t(src_.width) * kChannels);
    bases_->sums(src_, y, y + 1, range.data(), magnitude.data());
    const std::size_t at = std::size_t(x) * kChannels + c;
    const Values v = values(range[at], magnitude[at], oracle_.pixel(x, y)[c]);
    return {{"coordinate rounding (x local range)", v[0]},
            {"filter and accumulation rounding (Inf: NaN/Inf in the footprint)", v[1]},
            {"storage", v[2]},
            {"denormal flush", v[3]}};
  }

 private:
  struct Sums {
    std::vector<float> range, magnitude;
  };
  static Sums& scratch() {
    thread_local Sums s;
    return s;
  }
  // The terms from the weighted window sums: the filter's lerp (3 roundings) and the tap sums
  // (2 per tap): (3 + 2 T) u |t|.
  Values values(float range, float magnitude, float oracle) const {
    const double U = ctx_.profile->unit_roundoff;  // one operation's rounding
    return Values{delta_ * range, (3 + 2 * taps_) * U * magnitude,
                  storage_term(oracle, ctx_.storage, *ctx_.profile), denormal_floor(*ctx_.profile), 0};
  }

  ConstImageView src_, oracle_;
  BoundContext ctx_;
  int taps_;
  double delta_ = 0;
  std::shared_ptr<const BlurPropagation::Taps> bases_;
};

}  // namespace

std::unique_ptr<StageBounds> blur_bounds(ConstImageView src, ConstImageView oracle, Axis axis,
                                         const Kernel& k, BoundContext ctx) {
  return std::make_unique<BlurBounds>(src, oracle, axis, k, ctx);
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
      scene.width, ctx.threads);
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
      hdr.width, ctx.threads);
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
      mapped.width, ctx.threads);
}

BlurPropagation::BlurPropagation(ConstImageView error, Axis axis, const Kernel& k)
    : error_(error), axis_(axis),
      taps_(std::make_shared<Taps>(axis, axis == Axis::horizontal ? error.width : error.height, k)) {}

BlurPropagation::~BlurPropagation() = default;

void BlurPropagation::rows(int y0, int y1, float* out) const {
  taps_->sums(error_, y0, y1, nullptr, out);
}

Image propagate_blur(ConstImageView error, Axis axis, const Kernel& k, int threads) {
  const BlurPropagation p(error, axis, k);
  Image out(error.width, error.height, 0.0f);
  parallel_rows(error.height, threads, [&](int y0, int y1) { p.rows(y0, y1, out.pixel(0, y0)); });
  return out;
}

void StageBounds::fill(Image& bound) const {
  parallel_rows(bound.height(), threads,
                [&](int y0, int y1) { rows(y0, y1, bound.pixel(0, y0), nullptr); });
}

void StageBounds::fill_rounding(Image& rounding) const {
  parallel_rows(rounding.height(), threads,
                [&](int y0, int y1) { rows(y0, y1, nullptr, rounding.pixel(0, y0)); });
}

}  // namespace bloomref::parity::detail
