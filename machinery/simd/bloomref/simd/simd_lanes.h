// bloomref — the few vector helpers the kernels share (GCC/Clang vector extensions: the
// same IEEE operation in every lane). A texel is 4 lanes, RGBA, or 3, RGB (fill_zero_texels).
#pragma once

#include <cstddef>
#include <cstring>

#include "bloomref/simd/isa_namespace.h"  // each instruction set its own symbols
#include "bloomref/simd/vector_shuffle.h"

namespace bloomref::detail {
inline namespace BLOOMREF_ISA_NAMESPACE {

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

/// n consecutive texels of zero RGB, `channels` floats a texel: (0, 0, 0, 1) each for 4 (RGBA),
/// (0, 0, 0) for 3 (the fused blur's intermediate rows).
inline void fill_zero_texels(float* out, int n, int channels) {
  if (channels == 4) fill_zero_alpha_one(out, n, 4);
  else std::memset(out, 0, std::size_t(n) * channels * sizeof(float));
}

}  // namespace BLOOMREF_ISA_NAMESPACE
}  // namespace bloomref::detail
