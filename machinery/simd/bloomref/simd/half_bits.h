// bloomref — the binary16 bit pattern of a float that is a binary16 value, and back (the fast
// finishing stages' table of finished values, finish_kernels.inc and finish_fast.cpp).
#pragma once

#include <cstdint>
#include <cstring>

#include "bloomref/simd/isa_namespace.h"  // each instruction set its own symbols

namespace bloomref::detail {
inline namespace BLOOMREF_ISA_NAMESPACE {

/// Whether x is exactly a binary16 value other than NaN (+-0, subnormal, normal, +-Inf); if so
/// `h` is its bit pattern. IEEE 754 binary16: sign, 5 exponent bits (bias 15), 10 fraction bits.
inline bool half_bits_of(float x, std::uint16_t& h) {
  std::uint32_t u;
  std::memcpy(&u, &x, sizeof u);
  const std::uint32_t sign = (u >> 16) & 0x8000u;
  const std::uint32_t exp = (u >> 23) & 0xffu;  // biased by 127
  const std::uint32_t frac = u & 0x7fffffu;
  if (exp == 0 && frac == 0) {  // +-0
    h = static_cast<std::uint16_t>(sign);
    return true;
  }
  if (exp == 0xffu) {  // +-Inf; NaN is not taken
    h = static_cast<std::uint16_t>(sign | 0x7c00u);
    return frac == 0;
  }
  if (exp >= 113 && exp <= 142) {  // 2^-14 .. 2^15: a normal binary16 if 10 fraction bits do
    h = static_cast<std::uint16_t>(sign | ((exp - 112) << 10) | (frac >> 13));
    return (frac & 0x1fffu) == 0;
  }
  if (exp >= 103 && exp <= 112) {  // 2^-24 .. 2^-15: a subnormal binary16 m 2^-24, m integral
    const std::uint32_t shift = 126 - exp;  // 14 .. 23
    const std::uint32_t m = 0x800000u | frac;
    h = static_cast<std::uint16_t>(sign | (m >> shift));
    return (m & ((1u << shift) - 1)) == 0;
  }
  return false;
}

/// The value of the binary16 bit pattern h, exactly (NaN patterns: a quiet NaN).
inline float half_value(std::uint16_t h) {
  const std::uint32_t sign = std::uint32_t(h & 0x8000u) << 16;
  const std::uint32_t exp = (h >> 10) & 0x1fu;
  const std::uint32_t frac = h & 0x3ffu;
  if (exp == 0) {  // +-frac 2^-24: exact in float
    const float v = static_cast<float>(frac) * 0x1p-24f;
    return sign ? -v : v;
  }
  const std::uint32_t u = exp == 31 ? sign | 0x7f800000u | (frac ? 0x400000u : 0u) | (frac << 13)
                                    : sign | ((exp + 112) << 23) | (frac << 13);
  float v;
  std::memcpy(&v, &u, sizeof v);
  return v;
}

}  // namespace BLOOMREF_ISA_NAMESPACE
}  // namespace bloomref::detail
