// What the commands that time the pipeline share (bench, run --repeat): the median of the timed
// runs, and the check that a timed run gave the reference run's bits.
#pragma once

#include <algorithm>
#include <cstring>
#include <vector>

#include "bloomref/image.h"

namespace bloomref::cli {

/// Median of v (the mean of the two middle values for an even count).
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Whether a and b hold the same values, bit for bit.
inline bool same_bits(const Image& a, const Image& b) {
  return a.values().size() == b.values().size() &&
         std::memcmp(a.data(), b.data(), a.values().size() * sizeof(float)) == 0;
}

}  // namespace bloomref::cli
