// bloomref — the blur's tap tables (stages.h, blur_pass): where each of a pass's lookups falls,
// computed once per pass with exactly the arithmetic a per-pixel shader does, and the reference
// texel that sums them. Shared with the fast engine, which must give the same bits.
#pragma once

#include <cstddef>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"

namespace bloomref::detail {

// Taps of one output position along the blurred axis, in the shader's order:
// centre, +o1, -o1, +o2, -o2, ...
template <class T>
struct TapTable {
  int per_position = 0;
  std::vector<AxisTap<T>> taps;
  const AxisTap<T>* at(int x) const { return taps.data() + std::size_t(x) * per_position; }
};

TapTable<float> make_taps(int n, const Kernel& k, int bits, float);
TapTable<double> make_taps(int n, const Kernel& k, int bits, double);

/// The lookup across the blur for line x: the centre of texel x.
AxisTap<float> centre_tap(int x, int n, int bits, float);
AxisTap<double> centre_tap(int x, int n, int bits, double);

/// One texel of blur_pass, computed the reference way (RGB into d[0..2], d[3] = 1).
template <class T>
void blur_texel(BasicView<const T> src, bool horizontal, const AxisTap<T>* taps,
                const AxisTap<T>& other, const std::vector<T>& w, T* d);

}  // namespace bloomref::detail
