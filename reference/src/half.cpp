#include "bloomref/half.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace bloomref {
namespace {

// Half has 10 fraction bits; its quantum at binade e (>= -14) is 2^(e-10), and 2^-24 below the
// normal range. Dividing by a power of two is exact, so rounding the quotient to an integer
// (nearbyint: the current mode, round-to-nearest-even by default) rounds the value exactly once.
template <class T>
T round_half_impl(T x, HalfRounding mode) {
  if (!std::isfinite(x) || x == T(0)) return x;
  const T a = std::fabs(x);
  if (mode == HalfRounding::nearest_even && a >= T(65520)) return std::copysign(T(INFINITY), x);
  if (mode == HalfRounding::nearest_even_saturate && a >= T(65504)) return std::copysign(T(65504), x);
  if (mode == HalfRounding::toward_zero && a >= T(65504)) return std::copysign(T(65504), x);
  const int e = std::max(std::ilogb(a), -14);
  const T quantum = std::ldexp(T(1), e - 10);
  const T q = a / quantum;
  const T r = (mode == HalfRounding::toward_zero ? std::trunc(q) : std::nearbyint(q)) * quantum;
  return std::copysign(r, x);
}

}  // namespace

// The float version works on the bits, as it is called for every value f16 storage stores and
// the arithmetic one is far slower (docs/design.md, "Half rounding is arithmetic"); tests check
// it against Imath over every half, every tie between halves and a million random floats.
float round_to_half(float x, HalfRounding mode) {
  std::uint32_t b;
  std::memcpy(&b, &x, 4);
  const std::uint32_t sign = b & 0x80000000u, a = b & 0x7fffffffu;
  if (a >= 0x7f800000u || a == 0) return x;  // NaN, Inf, +-0
  if (a >= 0x477fe000u) {                     // |x| >= 65504
    if (mode == HalfRounding::nearest_even && a >= 0x477ff000u) return std::copysign(INFINITY, x);
    return std::copysign(65504.0f, x);        // below 65520 every mode gives 65504
  }
  if (a < 0x38800000u) return round_half_impl(x, mode);  // |x| < 2^-14: the denormal quantum
  std::uint32_t r = mode == HalfRounding::toward_zero
                        ? a & ~0x1fffu                                   // keep 10 mantissa bits
                        : (a + 0x0fffu + ((a >> 13) & 1u)) & ~0x1fffu;   // nearest, ties to even
  r |= sign;
  float out;
  std::memcpy(&out, &r, 4);
  return out;
}
double round_to_half(double x, HalfRounding mode) { return round_half_impl(x, mode); }

double round_to_packed(double v, int mantissa_bits, bool toward_zero) {
  if (std::isnan(v)) return v;
  if (!(v > 0)) return 0.0;
  const double top = std::ldexp(2.0 - std::ldexp(1.0, -mantissa_bits), 15);
  if (v >= top) return top;
  int e = 0;
  std::frexp(v, &e);  // v = f 2^e, f in [0.5, 1)
  const double q = std::ldexp(1.0, std::max(e - 1, -14) - mantissa_bits);  // denormals below 2^-14
  const double n = toward_zero ? std::floor(v / q) : std::round(v / q);
  return std::min(n * q, top);
}

namespace {

template <class T>
T unorm8(T x) {
  if (!(x > T(0))) return T(0);  // also NaN
  if (x >= T(1)) return T(1);
  return std::round(x * T(255)) / T(255);
}

}  // namespace

float round_to_unorm8(float x) { return unorm8(x); }
double round_to_unorm8(double x) { return unorm8(x); }

}  // namespace bloomref
