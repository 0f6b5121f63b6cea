// Per-value bounds of each stage (internal to parity). Every function fills `bound` (RGB per
// pixel) for its stage given the stage's input; `terms_at` re-derives one value's bound as named
// terms for the report.
#pragma once

#include <memory>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/parity/compare.h"
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
  virtual ~StageBounds() = default;
};

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
