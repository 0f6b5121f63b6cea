// bloomref — the few vector helpers the blur kernels share (GCC/Clang vector extensions: the
// same IEEE operation in every lane). A texel is 4 lanes, RGBA.
#pragma once

#include <cstddef>
#include <cstring>

namespace bloomref::detail {

typedef float v4f __attribute__((vector_size(16)));
typedef int v4i __attribute__((vector_size(16)));

/// Unaligned load of a vector from p.
template <class V>
inline V load(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// RGB kept, alpha set to exactly 1 (what every blur writes); I is V's integer twin.
template <class V, class I>
inline V with_alpha_one(V r) {
  I keep, one;
  for (int l = 0; l < int(sizeof(V) / 4); ++l) {
    keep[l] = (l % 4 == 3) ? 0 : -1;
    one[l] = (l % 4 == 3) ? 0x3f800000 : 0;
  }
  return reinterpret_cast<V>((reinterpret_cast<I>(r) & keep) | one);
}

/// n texels of (0, 0, 0, 1), texel j at out + j * step floats: what a blur gives where every
/// texel it reads is +0 (the adaptive plan's left-out texels).
inline void fill_zero_alpha_one(float* out, int n, std::ptrdiff_t step) {
  for (int j = 0; j < n; ++j) {
    float* d = out + j * step;
    d[0] = d[1] = d[2] = 0.0f;
    d[3] = 1.0f;
  }
}

}  // namespace bloomref::detail
