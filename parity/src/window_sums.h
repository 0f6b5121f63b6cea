// The local window statistics of an image along a blur pass and their sums over the pass's taps
// (internal to parity): what the blur's bounds and the end-to-end propagation through a pass
// are made of (tolerance.cpp), for bands of rows.
#pragma once

#include <array>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/kernel.h"
#include "bloomref/stages.h"

namespace bloomref::parity::detail {

/// A pass's taps: for each position along its axis, the base texel of every tap (centre, +o1,
/// -o1, ...: floor of its exact position, clamped) and its weight, computed once per pass.
class BlurTaps {
 public:
  static constexpr int kMaxTaps = 16;
  BlurTaps(Axis axis, int n, const Kernel& k);
  /// Rows [y0, y1) of sum over taps of weight x (local range, and local magnitude) of `src`
  /// around the tap's base texel (RGBA rows; range_sum may be null). The window of a tap based
  /// at p is [p-1, p+2] along the axis (linear5 taps sit between p and p+1), [q-1, q+1] across
  /// it, clamped; range is max - min and magnitude max |t| over its finite texels (+Inf with a
  /// NaN or Inf among them). Each sum in double, tap by tap in the kernel's order, rounded to
  /// float once.
  void sums(ConstImageView src, int y0, int y1, float* range_sum, float* magnitude_sum) const;

  /// Where a row of sums differs from texel to texel: columns [x0, x1); every other texel has
  /// `range` and `magnitude` (RGBA).
  struct RowShape {
    int x0 = 0, x1 = 0;
    std::array<float, 4> range{}, magnitude{};
    /// Writes the RGBA texel c over the columns of a row of w outside [x0, x1).
    void fill_outside(float* row, int w, const float* c) const;
  };
  /// As above, but writes each row only over its shape's columns and describes the rest in
  /// shapes[y - y0].
  void sums(ConstImageView src, int y0, int y1, float* range_sum, float* magnitude_sum,
            RowShape* shapes) const;

 private:
  void weighted_sums(const float* const* src, const double* w, std::size_t n, float* out) const;
  void along_row(const float* stat, int x0, int x1, float* out) const;

  Axis axis = Axis::horizontal;
  int taps = 0;
  std::vector<int> base;
  std::vector<double> weight;
  // Positions [inner0, inner1) have every tap at a fixed offset from them (offset[k]: none
  // clamped at an edge).
  int inner0 = 0, inner1 = 0;
  std::vector<int> offset;
  int reach0 = 0, reach1 = 0;  // the least and the greatest offset
};

}  // namespace bloomref::parity::detail
