// Per-value bounds of each stage (internal to parity). Every function gives its stage's bound
// given the stage's input, as rows of a band (StageBounds::rows) or one value's named terms for
// the report (StageBounds::terms).
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/mip.h"
#include "bloomref/parity/compare.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"
#include "window_sums.h"

namespace bloomref::parity::detail {

constexpr double kU = 5.9604644775390625e-08;  // 2^-24, the f32 unit roundoff

/// The storage term: what writing `v` to the stage's texture may change (f16: under one ULP
/// for toward-zero, half for nearest-even; f32: nothing).
/// What storing `v` may change it by: up to one ULP of the format (half of one when the profile
/// rounds to the nearest only). R11F_G11F_B10F: one quantum of channel `channel`'s mantissa (6
/// bits for R and G, 5 for B; the coarser where the channel is not known). RGBA8: 1.5 255ths
/// (either of the two nearest against the oracle's nearest) plus any distance outside [0, 1].
double storage_term(double v, Storage s, const DeviceProfile& p, int channel = 2);

/// Denormal flush floor: results below 2^-126 may become 0 in shader arithmetic.
double denormal_floor(const DeviceProfile& p);

/// Under an encoded --luma-space, the band around the threshold within which either side is
/// right, for the threshold's luminance of v (values each off by at most d from what the device
/// read): the reads' errors carried through the encode, the device's pow (GLSL's bounds, as
/// output_bounds takes them) and the luminance's rounding.
double encoded_threshold_band(const double v[3], const double d[3], const LumaRule& rule,
                              const DeviceProfile& p);

/// The rows a band of a stage works on: RGBA rows of `width` texels packed one after the other
/// (alpha unused), row y0 first. The bounds below fill such rows band by band, so that a stage's
/// bound is never held whole unless a caller asks for it (fill).
struct StageBounds {
  /// Rows [y0, y1) of the bound (the sum of the terms) and of its rounding part (the terms
  /// rounding_term names: storage, the arithmetic's ULPs; the rest is what sampling may change:
  /// coordinates, a threshold's band, Karis weights). Either may be null. Called from several
  /// threads at once on disjoint bands.
  virtual void rows(int y0, int y1, float* bound, float* rounding) const = 0;
  /// One value's bound as named terms (for the report's worst values).
  virtual std::vector<Term> terms(int x, int y, int c) const = 0;
  virtual ~StageBounds() = default;
  /// The whole bound, or its rounding part, into an image of the stage's size, on `threads`.
  void fill(Image& bound) const;
  void fill_rounding(Image& rounding) const;
  int threads = 0;
};

/// Whether a term named `name` is rounding (StageBounds::rows), by the names the bounds give
/// their terms: the sampling terms are the coordinates', the threshold's and the Karis weights'.
inline bool rounding_term(const char* name) {
  const std::string n(name);
  return n.find("coordinate") == std::string::npos && n.find("threshold") == std::string::npos &&
         n.find("Karis") == std::string::npos;
}

/// Sub-texel coordinate error of a lookup on an axis of n texels, in texels: the shader's
/// s = (x + 0.5) / n and d = 1 / n (division_ulps each), d * o and s +- d o (one rounding each),
/// then the sampler's u = s * n - 0.5 (two roundings of values below n); plus one weight quantum
/// when the device uses fixed-point weights (it may round where the oracle truncates; the
/// coarsest quantum it may use, subtexel_bits_min).
inline double coordinate_error(int n, const DeviceProfile& p) {
  const int bits = p.subtexel_bits_min > 0 ? p.subtexel_bits_min : p.subtexel_bits;
  return n * p.unit_roundoff * (2 * p.division_ulps + 4) + (bits > 0 ? std::ldexp(1.0, -bits) : 0.0);
}

/// Up to five named terms per value; the names are fixed per stage, the values computed per
/// value by `f(x, y, c)`.
using Values = std::array<double, 5>;

/// Bounds whose terms are a function of the value's position: `f(x, y, c)` gives them, or
/// `f(x, y)` those of the texel's three channels at once (where a channel's terms need the
/// others'). The bound sums all five in order, the rounding part the rounding ones (in double,
/// then rounded to float once).
template <class F>
struct TermBounds : StageBounds {
  static constexpr bool kPerTexel = std::is_invocable_v<const F&, int, int>;
  Values at(int x, int y, int c) const {
    if constexpr (kPerTexel) return f(x, y)[std::size_t(c)];
    else return f(x, y, c);
  }
  std::vector<const char*> names;
  F f;
  int width;
  std::array<bool, 5> rounding_mask{};
  TermBounds(std::vector<const char*> n, F fn, int w, int t)
      : names(std::move(n)), f(std::move(fn)), width(w) {
    threads = t;
    for (std::size_t i = 0; i < names.size(); ++i) rounding_mask[i] = rounding_term(names[i]);
  }
  void rows(int y0, int y1, float* bound, float* rounding) const override {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < width; ++x) {
        const std::size_t at = (std::size_t(y - y0) * width + x) * kChannels;
        std::array<Values, 3> texel{};
        if constexpr (kPerTexel) texel = f(x, y);
        for (int c = 0; c < 3; ++c) {
          Values v;
          if constexpr (kPerTexel) v = texel[std::size_t(c)];
          else v = f(x, y, c);
          if (bound) {
            double s = 0;
            for (double t : v) s += t;
            bound[at + c] = static_cast<float>(s);
          }
          if (rounding) {
            double s = 0;
            for (std::size_t i = 0; i < names.size(); ++i)
              if (rounding_mask[i]) s += v[i];
            rounding[at + c] = static_cast<float>(s);
          }
        }
      }
  }
  std::vector<Term> terms(int x, int y, int c) const override {
    const Values v = at(x, y, c);
    std::vector<Term> out;
    for (std::size_t i = 0; i < names.size(); ++i) out.push_back({names[i], v[i]});
    return out;
  }
};

template <class F>
std::unique_ptr<StageBounds> make_bounds(std::vector<const char*> names, F f, int width,
                                         int threads) {
  return std::make_unique<TermBounds<F>>(std::move(names), std::move(f), width, threads);
}

struct BoundContext {
  const DeviceProfile* profile;
  Storage storage;
  int threads;
  bool direct_exp = false;          // CompareOptions::direct_exp_tonemap
  bool interpolated_reads = false;  // CompareOptions::interpolated_reads
  /// The stage's lookups read an 8-bit normalised stage (--storage or --chain-storage rgba8):
  /// each filtered lookup may be off by unorm8_read_term (a filter in 8-bit fixed point), and
  /// a stage blended into such a target by unorm8_blend_term (the blend unit's 8-bit
  /// arithmetic).
  bool unorm8_reads = false;
};

/// What one GL_LINEAR lookup of an 8-bit normalised texture may be off by, per unit of its
/// weight: its result rounded to a 255th and its weights to 8 bits (llvmpipe filters RGBA8 in
/// 8-bit fixed point), two 255ths. docs/design.md, "8-bit levels".
constexpr double unorm8_read_term = 2.0 / 255.0;
/// What blending into an 8-bit normalised level may add: the source and the constant factors
/// converted to 8 bits before the blend equation, three 255ths.
constexpr double unorm8_blend_term = 3.0 / 255.0;

std::unique_ptr<StageBounds> input_bounds(ConstImageView oracle, BoundContext ctx);
std::unique_ptr<StageBounds> bright_bounds(ConstImageView sanitized, float threshold,
                                           BoundContext ctx, const LumaRule& luma = {});
std::unique_ptr<StageBounds> blur_bounds(ConstImageView src, ConstImageView oracle, Axis axis,
                                         const Kernel& k, BoundContext ctx);
std::unique_ptr<StageBounds> composite_bounds(ConstImageView scene, ConstImageView bloom,
                                              ConstImageView oracle, float strength,
                                              BoundContext ctx);
std::unique_ptr<StageBounds> tonemap_bounds(ConstImageView hdr, ConstImageView oracle,
                                            float exposure, BoundContext ctx);
std::unique_ptr<StageBounds> output_bounds(ConstImageView mapped, ConstImageView oracle,
                                           float gamma, BoundContext ctx);

/// Mip chain (mip_bounds.cpp). `error` images (end to end) may be null (isolated).
/// up.1 under LevelCombine::sum: the levels it adds (down.2 .. down.K), their errors (null or
/// one per level), the factors, radius and strength of `p`.
std::unique_ptr<StageBounds> sum_bounds(const std::vector<ConstImageView>& levels,
                                        ConstImageView oracle,
                                        const std::vector<const Image*>& errors,
                                        const BloomParams& p, BoundContext ctx);
/// `opt`: the stage's own options (downsample_options): its threshold and Karis form.
std::unique_ptr<StageBounds> down_bounds(ConstImageView src, ConstImageView oracle,
                                         const Image* error, const DownsampleOptions& opt,
                                         BoundContext ctx);
/// `blend`: how up.k adds the tent to the current level (plain for the bloom stage).
std::unique_ptr<StageBounds> up_bounds(ConstImageView small, ConstImageView current,
                                       ConstImageView oracle, const Image* small_error,
                                       const Image* current_error, LevelBlend blend,
                                       BoundContext ctx,
                                       UpsampleFilter filter = UpsampleFilter::tent);

/// The blur of an error image with the kernel's weights over each tap's window (end-to-end
/// propagation through one pass): sum_k w_k * (largest magnitude in tap k's window).
class BlurPropagation {
 public:
  BlurPropagation(ConstImageView error, Axis axis, const Kernel& k);
  ~BlurPropagation();
  /// Rows [y0, y1) of the propagated error (StageBounds' row layout).
  void rows(int y0, int y1, float* out) const;

 private:
  ConstImageView error_;
  Axis axis_;
  std::shared_ptr<const BlurTaps> taps_;
};

/// BlurPropagation of the whole image, on `threads`.
Image propagate_blur(ConstImageView error, Axis axis, const Kernel& k, int threads);

}  // namespace bloomref::parity::detail
