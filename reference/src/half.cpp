#include "bloomref/half.h"

#include <algorithm>
#include <cmath>

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

float round_to_half(float x, HalfRounding mode) { return round_half_impl(x, mode); }
double round_to_half(double x, HalfRounding mode) { return round_half_impl(x, mode); }

}  // namespace bloomref
