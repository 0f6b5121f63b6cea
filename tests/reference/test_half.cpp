// round_to_half against Imath's half (an independent, bit-level conversion).
#include <Imath/half.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "bloomref/half.h"
#include "test_util.h"

using namespace bloomref;

namespace {
float imath_round(float x) { return static_cast<float>(Imath::half(x)); }
}  // namespace

TEST_CASE("every half value and every tie between neighbours rounds as Imath does", "[half]") {
  int mismatches = 0;
  for (std::uint32_t bits = 0; bits < 0x7c00; ++bits) {  // all finite non-negative halves
    Imath::half h, next;
    h.setBits(static_cast<std::uint16_t>(bits));
    next.setBits(static_cast<std::uint16_t>(bits + 1));
    const float a = h, b = next;
    const float tie = bits + 1 < 0x7c00 ? a + (b - a) / 2 : 65520.0f;  // exact in float
    for (float x : {a, tie, std::nextafter(tie, 0.0f), std::nextafter(tie, INFINITY)}) {
      mismatches += !test::same_bits_nan_agnostic(round_to_half(x), imath_round(x));
      mismatches += !test::same_bits_nan_agnostic(round_to_half(-x), imath_round(-x));
    }
  }
  CHECK(mismatches == 0);
}

TEST_CASE("half boundaries: 65504, 65520, the smallest normal and denormal", "[half]") {
  CHECK(round_to_half(65504.0f) == 65504.0f);
  CHECK(round_to_half(65519.99f) == 65504.0f);
  CHECK(std::isinf(round_to_half(65520.0f)));  // the tie above 65504 rounds to even: Inf
  CHECK(round_to_half(-65520.0f) == -INFINITY);
  CHECK(round_to_half(6.103515625e-05f) == 6.103515625e-05f);   // 2^-14
  CHECK(round_to_half(5.9604644775390625e-08f) == 5.9604644775390625e-08f);  // 2^-24
  CHECK(round_to_half(2.98023223876953125e-08f) == 0.0f);  // 2^-25: tie to even (0)
  CHECK(round_to_half(4.4703483581542969e-08f) == 5.9604644775390625e-08f);  // 1.5 * 2^-25
  CHECK(std::signbit(round_to_half(-1e-30f)));  // sign of zero kept
  CHECK(std::isnan(round_to_half(NAN)));
  CHECK(round_to_half(INFINITY) == INFINITY);
  CHECK(round_to_half(1.7e38f) == INFINITY);
  for (float x : {65504.0f, 65519.99f, 65520.0f, 6.1e-5f, 6e-8f, 1.7e38f, -1.7e38f})
    CHECK(test::same_bits_nan_agnostic(round_to_half(x), imath_round(x)));
}

TEST_CASE("a million float bit patterns round as Imath does", "[half]") {
  std::uint32_t state = 12345;
  int mismatches = 0;
  for (int i = 0; i < 1000000; ++i) {
    state = state * 1664525u + 1013904223u;
    float x;
    std::memcpy(&x, &state, 4);
    mismatches += !test::same_bits_nan_agnostic(round_to_half(x), imath_round(x));
  }
  CHECK(mismatches == 0);
}

TEST_CASE("double rounds to half once, not through float", "[half]") {
  // 1 + 2^-11 is the tie between 1 and 1 + 2^-10. A hair above it must round up; through float
  // the hair is lost, the tie goes to even, and the result is 1 (double rounding).
  const double above_tie = 1.0 + std::ldexp(1.0, -11) + std::ldexp(1.0, -40);
  CHECK(round_to_half(above_tie) == 1.0 + std::ldexp(1.0, -10));
  CHECK(static_cast<float>(Imath::half(static_cast<float>(above_tie))) == 1.0f);
  for (float x : {0.1f, 1.5f, 65504.0f, 3.0e-6f, -7.25f})
    CHECK(round_to_half(static_cast<double>(x)) == static_cast<double>(round_to_half(x)));
}

TEST_CASE("toward zero truncates and saturates at 65504", "[half]") {
  const HalfRounding rtz = HalfRounding::toward_zero;
  CHECK(round_to_half(65535.0f, rtz) == 65504.0f);
  CHECK(round_to_half(1e30f, rtz) == 65504.0f);
  CHECK(round_to_half(-1e30f, rtz) == -65504.0f);
  // 1 + 1.9 * 2^-10 truncates to 1 + 2^-10 (nearest-even would give 1 + 2^-9).
  CHECK(round_to_half(1.0f + 1.9f * std::ldexp(1.0f, -10), rtz) == 1.0f + std::ldexp(1.0f, -10));
  CHECK(round_to_half(INFINITY, rtz) == INFINITY);
}

TEST_CASE("nearest-even with saturation: finite values never become Inf", "[half]") {
  const HalfRounding sat = HalfRounding::nearest_even_saturate;
  CHECK(round_to_half(65520.0f, sat) == 65504.0f);
  CHECK(round_to_half(-1.7e38f, sat) == -65504.0f);
  CHECK(round_to_half(INFINITY, sat) == INFINITY);  // Inf input stays Inf
  CHECK(round_to_half(1.0f + 1.5f * std::ldexp(1.0f, -10), sat) ==
        round_to_half(1.0f + 1.5f * std::ldexp(1.0f, -10)));  // below 65504: plain nearest-even
}
