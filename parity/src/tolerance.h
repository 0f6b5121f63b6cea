// Per-value bounds of each stage (internal to parity). Every function fills `bound` (RGB per
// pixel) for its stage given the stage's input; `terms_at` re-derives one value's bound as named
// terms for the report.
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/parity/compare.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"

namespace bloomref::parity::detail {

constexpr double kU = 5.9604644775390625e-08;  // 2^-24, the f32 unit roundoff

/// The storage term: what writing `v` to the stage's texture may change (f16: under one ULP
/// for toward-zero, half for nearest-even; f32: nothing).
double storage_term(double v, Storage s, const DeviceProfile& p);

/// Denormal flush floor: results below 2^-126 may become 0 in shader arithmetic.
double denormal_floor(const DeviceProfile& p);

struct StageBounds {
  /// Fills `bound` with the isolated bound of each value; `terms` (optional) for one value.
  virtual void fill(Image& bound) const = 0;
  virtual std::vector<Term> terms(int x, int y, int c) const = 0;
  /// Fills `rounding` with the part of each value's bound that rounding makes (storage, the
  /// arithmetic's ULPs): the rest is what sampling may change (coordinates, a threshold's
  /// band, Karis weights). The image gates measure errors beyond the rounding.
  virtual void fill_rounding(Image& rounding) const = 0;
  virtual ~StageBounds() = default;
};

/// Whether a term named `name` is rounding (StageBounds::fill_rounding), by the names the
/// bounds give their terms: the sampling terms are the coordinates', the threshold's and the
/// Karis weights'.
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

/// Fills an image's RGB by a per-value function, in parallel.
template <class F>
void fill_values(Image& out, int threads, F f) {
  parallel_rows(out.height(), threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < out.width(); ++x)
        for (int c = 0; c < 3; ++c) out.pixel(x, y)[c] = static_cast<float>(f(x, y, c));
  });
}

/// Up to five named terms per value; the names are fixed per stage, the values computed per
/// value by `f(x, y, c)`.
using Values = std::array<double, 5>;

template <class F>
struct TermBounds : StageBounds {
  std::vector<const char*> names;
  F f;
  int threads;
  TermBounds(std::vector<const char*> n, F fn, int t)
      : names(std::move(n)), f(std::move(fn)), threads(t) {}
  void fill(Image& bound) const override {
    fill_values(bound, threads, [&](int x, int y, int c) {
      double s = 0;
      for (double v : f(x, y, c)) s += v;
      return s;
    });
  }
  std::vector<Term> terms(int x, int y, int c) const override {
    const Values v = f(x, y, c);
    std::vector<Term> out;
    for (std::size_t i = 0; i < names.size(); ++i) out.push_back({names[i], v[i]});
    return out;
  }
  void fill_rounding(Image& rounding) const override {
    std::array<bool, 5> mask{};
    for (std::size_t i = 0; i < names.size(); ++i) mask[i] = rounding_term(names[i]);
    fill_values(rounding, threads, [&](int x, int y, int c) {
      const Values v = f(x, y, c);
      double s = 0;
      for (std::size_t i = 0; i < names.size(); ++i)
        if (mask[i]) s += v[i];
      return s;
    });
  }
};

template <class F>
std::unique_ptr<StageBounds> make_bounds(std::vector<const char*> names, F f, int threads) {
  return std::make_unique<TermBounds<F>>(std::move(names), std::move(f), threads);
}

struct BoundContext {
  const DeviceProfile* profile;
  Storage storage;
  int threads;
};

std::unique_ptr<StageBounds> input_bounds(ConstImageView oracle, BoundContext ctx);
std::unique_ptr<StageBounds> bright_bounds(ConstImageView sanitized, float threshold,
                                           BoundContext ctx);
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
std::unique_ptr<StageBounds> down_bounds(ConstImageView src, ConstImageView oracle,
                                         const Image* error, bool first, float threshold,
                                         bool karis, BoundContext ctx);
std::unique_ptr<StageBounds> up_bounds(ConstImageView small, ConstImageView current,
                                       ConstImageView oracle, const Image* small_error,
                                       const Image* current_error, BoundContext ctx);

/// The blur of an error image with the kernel's weights over each tap's window (end-to-end
/// propagation through one pass).
Image propagate_blur(ConstImageView error, Axis axis, const Kernel& k, int threads);

}  // namespace bloomref::parity::detail
