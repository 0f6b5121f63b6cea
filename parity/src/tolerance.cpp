// The per-value bounds. Notation: U = the profile's unit roundoff (2^-24 for f32 arithmetic,
// kU; 2^-11 for mediump), ULP of a float y <= 2^-23 |y|.
#include "tolerance.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <utility>
#include <vector>

#include "bloomref/parallel.h"

namespace bloomref::parity::detail {
namespace {

// One f16 ULP at v: 2^(max(e, -14) - 10) for |v| = m 2^e (1 <= m < 2), 2^-24 for 0 (the
// subnormal spacing). From the exponent bits, as ilogb and ldexp would give it for every finite
// double (a subnormal double's exponent is below -14 either way).
inline double ulp16(double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  const int e = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  const std::uint64_t out = std::uint64_t((v != 0 ? std::max(e, -14) : -14) - 10 + 1023) << 52;
  double r;
  std::memcpy(&r, &out, sizeof r);
  return r;
}

float* sized(std::vector<float>& v, std::size_t n) {
  if (v.size() < n) v.resize(n);
  return v.data();
}

}  // namespace

double storage_term(double v, Storage s, const DeviceProfile& p, int channel) {
  if (s == Storage::f32 || !std::isfinite(v)) return 0.0;
  if (s == Storage::r11g11b10) {
    // One quantum: nearest or toward zero (the oracle's own rounding is added where it is
    // judged). Denormals below 2^-14.
    // No sign: a negative value is stored as 0, |v| away.
    if (!(v > 0)) return std::fabs(v);
    int e = 0;
    std::frexp(v, &e);
    const double quantum = std::ldexp(1.0, std::max(e - 1, -14) - (channel == 2 ? 5 : 6));
    // Below 2^-14 the format's denormals, which a conversion may flush to 0: llvmpipe's upload
    // of floats into an R11F_G11F_B10F texture does (measured: CandleGlass.exr's 6.0e-5 read
    // back as 0 under --preset learnopengl-pbb --storage r11g11b10).
    return v < 0x1p-14 ? std::max(quantum, v) : quantum;
  }
  if (s == Storage::rgba8) {
    // GL 4.6, 2.3.5.2 lets a write take either of the two 255ths nearest to the value: from
    // the oracle's nearest, one and a half 255ths where the device's value is its own by up to
    // the bound (floor or ceil of it against the nearest of the oracle's). The oracle's value
    // is compared stored (stage_terms.cpp, with_oracle); beyond [0, 1], the distance to it.
    const double out = v < 0 ? -v : v > 1 ? v - 1 : 0.0;
    return 1.5 / 255.0 + out;
  }
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

namespace {

// Reads through texture() at interpolated coordinates (CompareOptions::interpolated_reads): a
// coordinate off the texel's centre by d texels blends in d of the neighbour on that side
// (LINEAR; clamp to edge: none beyond it), so d times the larger difference to a neighbour, per
// axis. These are the larger differences of texel (x, y), channel c, along x and along y; d is
// coordinate_error on each axis.
std::pair<double, double> neighbour_steps(ConstImageView v, int x, int y, int c) {
  const double m = v.pixel(x, y)[c];
  const double l = v.pixel(std::max(x - 1, 0), y)[c], r = v.pixel(std::min(x + 1, v.width - 1), y)[c];
  const double u = v.pixel(x, std::max(y - 1, 0))[c], d = v.pixel(x, std::min(y + 1, v.height - 1))[c];
  return {std::max(std::fabs(l - m), std::fabs(r - m)), std::max(std::fabs(u - m), std::fabs(d - m))};
}

// The reads' error of a texel's three channels (d times its neighbour steps per axis), kept for
// the texel last asked on this thread: the bounds ask for its channels one after another, and
// each needs all three (the luminance's change). `owner` names the bounds that made them: a
// number never given twice, so a texel of another image at the same place is made again.
struct TexelReads {
  std::uint64_t owner = 0;
  int x = -1, y = -1;
  double read[3] = {0, 0, 0};
};

const double* texel_reads(std::uint64_t owner, ConstImageView v, int x, int y, double dx,
                          double dy) {
  thread_local TexelReads t;
  if (t.owner != owner || t.x != x || t.y != y) {
    for (int k = 0; k < 3; ++k) {
      const auto [sx, sy] = neighbour_steps(v, x, y, k);
      t.read[k] = dx * sx + dy * sy;
    }
    t.owner = owner;
    t.x = x;
    t.y = y;
  }
  return t.read;
}

std::uint64_t new_owner() {
  static std::atomic<std::uint64_t> next{1};
  return next++;
}

}  // namespace

double encoded_threshold_band(const double v[3], const double d[3], const LumaRule& rule,
                              const DeviceProfile& p) {
  const double U = p.unit_roundoff;
  const LumaWeights<double> w = luma_weights<double>(rule.weights);
  const double g = rule.space == LumaSpace::gamma ? 1.0 / rule.gamma : 1.0 / 2.4;
  const double wc[3] = {w.r, w.g, w.b};
  double band = 0, mags = 0;
  for (int c = 0; c < 3; ++c) {
    const double x = std::max(v[c], 0.0);
    const double e = luma_encode(x, rule);
    // The reads' errors through the encode (monotonic): the larger move either way.
    const double spread = std::max(luma_encode(x + d[c], rule) - e,
                                   e - luma_encode(std::max(x - d[c], 0.0), rule));
    // The device's pow(x, g) = exp2(g log2 x): log2 3 ULP (2^-21 absolute in [0.5, 2]), the
    // product's rounding, exp2 (3 + 2|t|) ULP; at 0 or a denormal (flushed), up to 2^(-126 g).
    double dev;
    if (rule.space == LumaSpace::srgb && x <= 0.0031308) {
      dev = 2 * U * 12.92 * x;
    } else if (!(x > 0) || (p.flush_denormals && x < 0x1p-126)) {
      dev = std::pow(0x1p-126, g);
    } else {
      const double l = std::log2(x), t = g * l, o = std::exp2(t);
      const double dl = (x >= 0.5 && x <= 2.0) ? std::ldexp(1.0, -21) * (U / kU) : 3 * 2 * U * std::fabs(l);
      dev = o * std::log(2.0) * g * dl + o * std::log(2.0) * std::fabs(t) * (1 + p.division_ulps) * U +
            o * (3 + 2 * std::fabs(t)) * 2 * U;
      // sRGB: times 1.055, then the product's and the difference's rounding (fused or not).
      if (rule.space == LumaSpace::srgb) dev = 1.055 * dev + 2 * U * (1.055 * o + 0.055);
    }
    band += wc[c] * (spread + dev);
    mags += std::fabs(wc[c] * e);
  }
  return band + 4 * U * mags;  // the luminance's 3 products and 2 sums
}

std::unique_ptr<StageBounds> bright_bounds(ConstImageView sanitized, float threshold,
                                           BoundContext ctx, const LumaRule& luma) {
  const LumaWeights<double> wd = luma_weights<double>(luma.weights);
  const LumaWeights<float> wf = luma_weights<float>(luma.weights);
  const bool encoded = luma.space != LumaSpace::linear;
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  // A bright pass of the user's reads the scene with texture() at its interpolated texture
  // coordinate: each value may be off by a blend of its neighbours, and its luminance with it.
  const double dx = ctx.interpolated_reads ? coordinate_error(sanitized.width, *ctx.profile) : 0.0;
  const double dy = ctx.interpolated_reads ? coordinate_error(sanitized.height, *ctx.profile) : 0.0;
  const std::uint64_t owner = new_owner();
  return make_bounds(
      {"threshold within luminance rounding (either side is right)", "storage",
       "interpolated coordinates (x neighbour difference)"},
      [=](int x, int y, int c) {
        const float* s = sanitized.pixel(x, y);
        // luminance: 3 products and 2 sums, fused or not: |dL| <= 4u sum |w_i c_i|.
        const double mags = std::fabs(wd.r * s[0]) + std::fabs(wd.g * s[1]) +
                            std::fabs(wd.b * s[2]);
        const double l = encoded ? threshold_luminance(s[0], s[1], s[2], luma)
                                 : luminance(s[0], s[1], s[2], wf);
        static constexpr double none[3] = {0, 0, 0};
        const double* read =
            dx > 0 || dy > 0 ? texel_reads(owner, sanitized, x, y, dx, dy) : none;
        const double read_l = wd.r * read[0] + wd.g * read[1] + wd.b * read[2];
        double band = (ctx.profile->precise_luminance ? 0.0 : 4 * U * mags) + read_l;
        if (encoded) {
          const double v[3] = {s[0], s[1], s[2]};
          band = encoded_threshold_band(v, read, luma, *ctx.profile);
        }
        const bool tie = (band > 0 || !ctx.profile->precise_luminance) &&
                         std::fabs(l - threshold) <= band + denormal_floor(*ctx.profile);
        const double v = s[c];
        // Either side of the threshold is right in the band: the value's own read error is
        // then within its magnitude, taken whole.
        return Values{tie ? std::max({std::fabs(s[0]), std::fabs(s[1]), std::fabs(s[2])}) + read[c] : 0.0,
                      storage_term(v, ctx.storage, *ctx.profile), tie || !(l > threshold) ? 0.0 : read[c]};
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
        bases_(std::make_shared<BlurTaps>(
            axis, axis == Axis::horizontal ? src.width : src.height, k)) {
    threads = ctx.threads;
    const bool hz = axis == Axis::horizontal;
    delta_ = coordinate_error(hz ? src.width : src.height, *ctx.profile) +
             coordinate_error(hz ? src.height : src.width, *ctx.profile);
    // Each tap of an 8-bit source may be filtered in 8-bit fixed point: per unit of its weight.
    if (ctx.unorm8_reads) {
      double total = 0;
      for (std::size_t i = 0; i < k.weights_f64.size(); ++i)
        total += (i == 0 ? 1 : 2) * std::fabs(k.weights_f64[i]);
      read8_ = unorm8_read_term * total;
    }
  }

  void rows(int y0, int y1, float* bound, float* rounding) const override {
    const int w = src_.width;
    const std::size_t row = std::size_t(w) * kChannels;
    Sums& s = scratch();
    float* range = sized(s.range, std::size_t(y1 - y0) * row);
    float* magnitude = sized(s.magnitude, std::size_t(y1 - y0) * row);
    if (s.shapes.size() < std::size_t(y1 - y0)) s.shapes.resize(std::size_t(y1 - y0));
    bases_->sums(src_, y0, y1, range, magnitude, s.shapes.data());
    for (int y = y0; y < y1; ++y) {
      const std::size_t at = std::size_t(y - y0) * row;
      const BlurTaps::RowShape& sh = s.shapes[std::size_t(y - y0)];
      float* b = bound ? bound + at : nullptr;
      float* r = rounding ? rounding + at : nullptr;
      if (ctx_.storage == Storage::f32) {
        // The terms of f32 storage are those of the sums alone: outside the row's shape, one
        // texel's, copied.
        const std::size_t x0 = std::size_t(sh.x0) * kChannels, x1 = std::size_t(sh.x1) * kChannels;
        terms_row<true>(range + at + x0, magnitude + at + x0, oracle_.row(y) + x0, x1 - x0,
                        b ? b + x0 : nullptr, r ? r + x0 : nullptr);
        if (sh.x0 > 0 || sh.x1 < w) {
          float cb[kChannels], cr[kChannels];
          terms_row<true>(sh.range.data(), sh.magnitude.data(), oracle_.row(y), kChannels,
                          b ? cb : nullptr, r ? cr : nullptr);
          if (b) sh.fill_outside(b, w, cb);
          if (r) sh.fill_outside(r, w, cr);
        }
      } else {
        // The storage term needs every texel's oracle value: the sums are made whole first.
        sh.fill_outside(range + at, w, sh.range.data());
        sh.fill_outside(magnitude + at, w, sh.magnitude.data());
        terms_row<false>(range + at, magnitude + at, oracle_.row(y), row, b, r);
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
    std::vector<BlurTaps::RowShape> shapes;
  };
  static Sums& scratch() {
    thread_local Sums s;
    return s;
  }
  // The terms of values() over n values of a row (alpha too: its results are not read), summed
  // into the bound and its rounding part (either may be null). With f32 storage the storage term
  // is 0: the loops then vectorise.
  template <bool F32>
  void terms_row(const float* range, const float* magnitude, const float* o, std::size_t n,
                 float* bound, float* rounding) const {
    const double U = ctx_.profile->unit_roundoff;  // one operation's rounding
    const double filter = (3 + 2 * taps_) * U, denormal = denormal_floor(*ctx_.profile);
    const double delta = delta_, read8 = read8_;
    const Storage st = ctx_.storage;
    const DeviceProfile& p = *ctx_.profile;
    if (bound)
      for (std::size_t i = 0; i < n; ++i) {
        const double v2 = F32 ? 0.0 : storage_term(o[i], st, p);
        bound[i] = static_cast<float>(0.0 + delta * range[i] + filter * magnitude[i] + v2 + denormal + read8);
      }
    if (rounding)
      for (std::size_t i = 0; i < n; ++i) {
        const double v2 = F32 ? 0.0 : storage_term(o[i], st, p);
        rounding[i] = static_cast<float>(0.0 + filter * magnitude[i] + v2 + denormal);
      }
  }

  // The terms from the weighted window sums: the filter's lerp (3 roundings) and the tap sums
  // (2 per tap): (3 + 2 T) u |t|.
  Values values(float range, float magnitude, float oracle) const {
    const double U = ctx_.profile->unit_roundoff;  // one operation's rounding
    return Values{delta_ * range + read8_, (3 + 2 * taps_) * U * magnitude,
                  storage_term(oracle, ctx_.storage, *ctx_.profile), denormal_floor(*ctx_.profile), 0};
  }

  ConstImageView src_, oracle_;
  BoundContext ctx_;
  int taps_;
  double delta_ = 0, read8_ = 0;  // read8_: 8-bit filtering over the taps
  std::shared_ptr<const BlurTaps> bases_;
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
  // Reads through texture() at interpolated coordinates (neighbour_steps): d is
  // coordinate_error, the rounding of s * n - 0.5 and the weight quantum.
  const double dx = ctx.interpolated_reads ? coordinate_error(scene.width, *ctx.profile) : 0.0;
  const double dy = ctx.interpolated_reads ? coordinate_error(scene.height, *ctx.profile) : 0.0;
  // 8-bit inputs may be filtered in 8-bit fixed point, and an 8-bit composite may be a blend
  // into the scene's target (Bevy's): the blend unit's 8-bit arithmetic.
  const double eight = (ctx.unorm8_reads ? unorm8_read_term * (1 + std::fabs(strength)) : 0.0) +
                       (ctx.storage == Storage::rgba8 ? unorm8_blend_term : 0.0);
  return make_bounds(
      {"product and sum rounding", "storage", "denormal flush",
       "interpolated coordinates (x neighbour difference), 8-bit lookups and blend"},
      [=](int x, int y, int c) {
        const double s = scene.pixel(x, y)[c], b = bloom.pixel(x, y)[c];
        double reads = eight;
        if (dx > 0 || dy > 0) {
          const auto [sx, sy] = neighbour_steps(scene, x, y, c);
          const auto [bx, by] = neighbour_steps(bloom, x, y, c);
          reads += dx * (sx + std::fabs(strength) * bx) + dy * (sy + std::fabs(strength) * by);
        }
        return Values{2 * U * (std::fabs(s) + std::fabs(strength * b)),
                      storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile),
                      denormal_floor(*ctx.profile), reads};
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
          Values v{0, std::fabs(a) * U * 1.7, (3 * 7 + 1) * U * std::fabs(m),
                   storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile),
                   denormal_floor(*ctx.profile)};
          if (ctx.direct_exp) {
            // 1 - exp(x) computed directly: exp's (3 + 2|x|) ULP at e = exp(x) in (0.6, 1.7),
            // absolute, whatever the size of the result (1 - e itself is exact there, Sterbenz).
            const double e = std::exp(a);
            v[0] = e * (3 + 2 * std::fabs(a)) * 2 * U;
            v[1] = std::max(v[1], e * std::fabs(a) * U);
          }
          return v;
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
      taps_(std::make_shared<BlurTaps>(axis, axis == Axis::horizontal ? error.width : error.height, k)) {}

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
