// The gain gates (internal to parity): signed sums of a stage's error against budgets derived
// from the profile, beside the per-value bounds. docs/design.md, "Gain gates", derives them.
//
// Per value the bound must hold whatever the signs of the device's errors; a sum can use more.
// A lookup of an honest device is still a convex combination of the texels around it: its
// position is off from the oracle's by a small shift, which moves weight between neighbours
// and creates no energy. Summed over a region, the error of a pass is therefore at most the
// shift times the image's differences, with their signs (BlurDeviation), plus the rounding
// terms, plus what stages without capture carry in (their own sums: a blur conserves a sum
// except near the edges, where clamp-to-edge gives a texel more or less than its weight).
#pragma once

#include <array>
#include <memory>
#include <utility>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/kernel.h"
#include "bloomref/parity/profile.h"
#include "bloomref/stages.h"

namespace bloomref::parity::detail {

/// How far a device's lookup position may be from the oracle's on an axis of n texels, below
/// (`minus`) and above (`plus`), in texels, for a lookup whose exact fraction (position within
/// the texel span, 0 on a centre) is `fraction`. The oracle rounds the bilinear fraction to
/// subtexel_bits (none: float weights); the device may truncate or round it to as few as
/// subtexel_bits_min bits, and its coordinates carry the float error of coordinate_error
/// (tolerance.h).
struct AxisShift {
  double minus = 0, plus = 0;
  /// The oracle's own lookup sits exactly at the reference position (a fraction on its weight
  /// grid, weights quantized): the device's deviation from it is one-sided as the shifts say.
  /// Otherwise the oracle itself moves within the shifts too, and a device below it may be as
  /// far as the rise and the fall together (BlurDeviation makes up and down their sum).
  bool exact_reference = false;
  double most() const { return minus > plus ? minus : plus; }
};
AxisShift lookup_shift(int n, const DeviceProfile& p, double fraction);

/// Per channel: an upper bound on a signed sum of errors (`up`) and on its negation (`down`).
struct SignedBudget {
  std::array<double, 3> up{}, down{};
  void add(const SignedBudget& b, double scale = 1.0);
  void add_both(const std::array<double, 3>& v, double scale = 1.0);  ///< to up and down
  static SignedBudget infinite();  ///< no budget derived: the per-value bounds' sum applies
};

/// The signed deviation of a blur pass's lookups: for each output value, the largest amount by
/// which the device's weighted taps may exceed the oracle's (`up`) or fall short of them
/// (`down`) when every lookup position moves within the axes' AxisShift. Exact for the
/// bilinear interpolant: its extremes over a rectangle of positions lie on the rectangle's
/// corners and the texel lines inside it. Valid while a shift is under one texel (usable()).
class BlurDeviation {
 public:
  BlurDeviation(ConstImageView src, Axis axis, const Kernel& k, const DeviceProfile& p);
  bool usable() const { return usable_; }
  /// Rows [y0, y1) of up and down, RGBA rows of the source's width (alpha unused).
  void rows(int y0, int y1, float* up, float* down) const;
  /// The most a shift moves weight on either axis: max over both axes of (minus + plus).
  double shift_sum() const;

 private:
  void deviation(int x, int y, double u_along, const AxisShift& along, float* up,
                 float* down) const;
  std::pair<int, int> centred_row(int y, float* up, float* down) const;
  ConstImageView src_;
  Axis axis_;
  const Kernel* kernel_;
  std::vector<double> offsets_, weights_;  // every tap, its exact offset and weight
  std::vector<AxisShift> tap_shift_;       // along the axis, per tap (its fraction's)
  AxisShift along_, across_;               // on a texel centre
  bool usable_ = true;
};

/// |W(t) - 1| along an axis of n texels, where W(t) is the total weight the oracle's pass gives
/// texel t over all outputs (1 away from the edges; clamp-to-edge makes it more or less within
/// the kernel's reach of an edge). The sum of a pass's output is the sum of W times its input.
std::vector<double> edge_weight_excess(int n, const Kernel& k);

/// Sum over the image of |W - 1| (edge_weight_excess along the pass's axis) times `e`, per
/// channel: how much a pass may change the sum of an error bounded by `e` value by value.
std::array<double, 3> edge_leak(ConstImageView e, Axis axis, const std::vector<double>& excess);

}  // namespace bloomref::parity::detail
