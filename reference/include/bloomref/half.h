// bloomref — rounding to IEEE binary16 (what an RGBA16F render target stores).
//
// GL does not pin how a render-target write rounds float to half: round-to-nearest-even (Inf
// above 65519.99...) or toward zero (saturating at 65504). Both are modelled. The rounding is
// computed arithmetically (scale by a power of two, round to an integer, scale back), so it is
// exact for float and double inputs alike (no double rounding through float) and independent of
// Imath's bit-level conversion, against which the tests check it.
#pragma once

namespace bloomref {

/// nearest_even: IEEE (Inf from 65520 up); nearest_even_saturate: the same, but a finite value
/// never becomes Inf (beyond 65504 it stores 65504; what bloomref's CPU f16 storage does, so that
/// no +Inf and -Inf meet in a later sum); toward_zero: truncates and saturates (llvmpipe).
enum class HalfRounding { nearest_even, nearest_even_saturate, toward_zero };

constexpr double kHalfMax = 65504.0;
constexpr double kHalfMinNormal = 6.103515625e-05;    // 2^-14
constexpr double kHalfMinDenormal = 5.9604644775390625e-08;  // 2^-24

/// The value of the binary16 number `x` rounds to, returned in x's own type. NaN stays NaN,
/// +-Inf stays +-Inf, the sign of zero is kept.
float round_to_half(float x, HalfRounding mode = HalfRounding::nearest_even);
double round_to_half(double x, HalfRounding mode = HalfRounding::nearest_even);

/// One channel of an R11F_G11F_B10F write (GL 4.6, 2.3.4.3-4): an unsigned float with a 5-bit
/// exponent and `mantissa_bits` (6 for R and G, 5 for B); negative values become 0, NaN stays
/// NaN (the format has NaNs; llvmpipe keeps them, measured), values above the largest finite
/// one become it. Rounded to the nearest (ties away from zero)
/// or, `toward_zero`, truncated (llvmpipe, measured: 2.0234375 is stored as 2 in R).
double round_to_packed(double v, int mantissa_bits, bool toward_zero);

/// One channel of an RGBA8 write (GL 4.6, 2.3.5.2): clamped to [0, 1], then the nearest of the
/// 255ths (GL allows either of the two nearest; the bound allows for both, tolerance.cpp); NaN
/// becomes 0. Computed in x's own type.
float round_to_unorm8(float x);
double round_to_unorm8(double x);

}  // namespace bloomref
