// bloomref — the f32 oracle's exp and pow, written once for any lane width.
//
// The f32 oracle used to call the C library's expf and powf. Those are not correctly rounded
// (glibc documents up to 1 ulp; other libraries differ), so the oracle's bits depended on the
// machine's libm, and a loop of library calls cannot be vectorised with the same bits. Here both
// functions are defined by IEEE basic operations only (+, -, *, /, conversions, bit moves; no
// fused multiply-add: the library is built with -ffp-contract=off), evaluated in double and
// rounded once to float. The same template runs as a scalar (D = double: the straightforward
// staged reference) and as vectors (GCC vector extensions: the fast stages), so the two give the
// same bits on every machine.
//
// Method (textbook argument reduction, e.g. Muller, "Elementary Functions", 3rd ed., ch. 11;
// Tang, "Table-driven implementation of the exponential function", ACM TOMS 15(2), 1989, without
// the table):
//   exp(x):  k = round(x / ln2), r = x - k ln2 (ln2 split in a 41-bit head, so k * head is exact,
//            and a tail), exp(r) by its Taylor series to r^12 (|r| <= 0.347: truncation
//            < 2e-16 relative), times 2^k built from bits.
//   pow(x, y) for x > 0: x = 2^e m with m in [sqrt(1/2), sqrt(2)), log m = 2 atanh(s) with
//            s = (m - 1) / (m + 1) (|s| <= 0.1716; series to s^19, truncation < 3e-17
//            relative); y e is exact in double, so t = y log2 x is split as
//            (y e - round(y e)) + y log2 m before its own round(); 2^t as above.
// Both keep the double result within ~1e-15 relative of the truth, so the float they return is
// the correctly rounded one except where the truth lies that close to a rounding boundary
// (measured in tests/reference/test_stages.cpp against the C library's double exp and pow).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "bloomref/simd/isa_namespace.h"  // each instruction set its own symbols

namespace bloomref::detail {
inline namespace BLOOMREF_ISA_NAMESPACE {

// Lane helpers: a scalar overload and a GCC-vector overload for every operation the templates
// need, so the same source is one lane or many.
inline std::uint64_t as_u64(double x) {
  std::uint64_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}
inline double as_f64(std::uint64_t u) {
  double x;
  std::memcpy(&x, &u, sizeof x);
  return x;
}
template <int N>
struct Lanes;
#define BLOOMREF_LANES(n)                                                            \
  template <>                                                                        \
  struct Lanes<n> {                                                                  \
    typedef float F __attribute__((vector_size(4 * n)));                             \
    typedef double D __attribute__((vector_size(8 * n)));                            \
    typedef std::uint64_t U __attribute__((vector_size(8 * n)));                     \
    static U bits(D x) { return reinterpret_cast<U>(x); }                            \
    static D from_bits(U u) { return reinterpret_cast<D>(u); }                       \
    static D widen(F x) { return __builtin_convertvector(x, D); }                    \
    static F narrow(D x) { return __builtin_convertvector(x, F); }                   \
  };
// -Wpsabi: GCC notes that 32-byte vector arguments pass differently without AVX; these
// functions are inline and never cross a compiled interface.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
BLOOMREF_LANES(4)
BLOOMREF_LANES(8)
#pragma GCC diagnostic pop
#undef BLOOMREF_LANES
template <>
struct Lanes<1> {
  typedef float F;
  typedef double D;
  typedef std::uint64_t U;
  static U bits(D x) { return as_u64(x); }
  static D from_bits(U u) { return as_f64(u); }
  static D widen(F x) { return x; }
  static F narrow(D x) { return static_cast<F>(x); }
};

/// Whether every lane of a comparison's result is true (one lane: the bool itself). The lanes
/// are and-ed without a branch per lane (a lane is all ones or all zeros).
inline bool all_lanes(bool m) { return m; }
template <class M>
inline bool all_lanes(const M& m) {
  // One sign-bit mask instruction where the vector is a whole register of 32-bit lanes (the
  // only masks the callers make: float comparisons; a lane is all ones or all zeros, so its sign
  // bit says which); the loop below extracts lane by lane.
#ifdef __AVX512F__
  if constexpr (sizeof(M) == 64 && sizeof(m[0]) == 4) {
    const __m512i x = reinterpret_cast<__m512i>(m);
    return _mm512_test_epi32_mask(x, x) == 0xffff;
  }
#endif
#ifdef __AVX__
  if constexpr (sizeof(M) == 32 && sizeof(m[0]) == 4)
    return _mm256_movemask_ps(reinterpret_cast<__m256>(m)) == 0xff;
#endif
#ifdef __SSE2__
  if constexpr (sizeof(M) == 16 && sizeof(m[0]) == 4)
    return _mm_movemask_ps(reinterpret_cast<__m128>(m)) == 0xf;
#endif
  constexpr int n = int(sizeof(M) / sizeof(m[0]));
  auto all = m[0];
  for (int i = 1; i < n; ++i) all &= m[i];
  return all != 0;
}

namespace oracle_math {
constexpr double kInvLn2 = 0x1.71547652b82fep+0;
constexpr double kLn2 = 0x1.62e42fefa39efp-1;
constexpr double kLn2Hi = 0x1.62e42fefa3000p-1;  // 41 significant bits: k * head exact, |k| < 2^12
constexpr double kLn2Lo = 0x1.3de6af278ece6p-42;  // ln 2 - head, to double precision
constexpr double kRound = 0x1.8p52;  // t + kRound - kRound = round-to-nearest-even(t), |t| < 2^51
constexpr std::uint64_t kRoundBits = 0x4338000000000000ull;
constexpr double kTwo52 = 0x1p52;
constexpr std::uint64_t kTwo52Bits = 0x4330000000000000ull;
constexpr std::uint64_t kSqrtHalfBits = 0x3fe6a09e667f3bcdull;  // sqrt(1/2) rounded
constexpr std::uint64_t kBias = 1023;
}  // namespace oracle_math

/// exp(r) for |r| <= 0.35: Taylor series to r^12, 1/k! as doubles, in Estrin's form (pairs,
/// then pairs of pairs: a short dependency chain, so vector lanes do not wait on each other).
template <class D>
inline D exp_series(D r) {
  const D r2 = r * r;
  const D r4 = r2 * r2;
  const D r8 = r4 * r4;
  const D p01 = 1.0 + r;
  const D p23 = 1.0 / 2.0 + r * (1.0 / 6.0);
  const D p45 = 1.0 / 24.0 + r * (1.0 / 120.0);
  const D p67 = 1.0 / 720.0 + r * (1.0 / 5040.0);
  const D p89 = 1.0 / 40320.0 + r * (1.0 / 362880.0);
  const D p1011 = 1.0 / 3628800.0 + r * (1.0 / 39916800.0);
  const D p03 = p01 + r2 * p23;
  const D p47 = p45 + r2 * p67;
  const D p811 = p89 + r2 * p1011;
  const D p812 = p811 + r4 * (1.0 / 479001600.0);
  return (p03 + r4 * p47) + r8 * p812;
}

/// 2^k as a double, k an integer in [-1022, 1023] held as the rounding trick's bits minus
/// kRoundBits (two's complement in 64 bits).
template <int N>
inline typename Lanes<N>::D pow2_from_k(typename Lanes<N>::U k) {
  return Lanes<N>::from_bits((k + oracle_math::kBias) << 52);
}

/// The oracle's exp of float lanes, as float lanes (NaN -> NaN, -inf -> 0, +inf -> inf).
template <int N>
inline typename Lanes<N>::F exp_f32(typename Lanes<N>::F xf) {
  using L = Lanes<N>;
  using D = typename L::D;
  using U = typename L::U;
  namespace om = oracle_math;
  const D x0 = L::widen(xf);
  // Outside [-160, 90] the float result is 0 or inf either way (e^-104 < 2^-150, e^89 > 2^128);
  // clamping keeps 2^k a normal double. NaN fails both tests and is passed through below.
  D x = x0 < -160.0 ? D{} - 160.0 : x0;
  x = x > 90.0 ? D{} + 90.0 : x;
  const D shifted = x * om::kInvLn2 + om::kRound;
  const D k = shifted - om::kRound;
  const U ki = L::bits(shifted) - om::kRoundBits;
  const D r = (x - k * om::kLn2Hi) - k * om::kLn2Lo;
  const D e = exp_series(r) * pow2_from_k<N>(ki);
  return L::narrow(x0 != x0 ? x0 : e);
}

/// The oracle's pow(x, y) for one y and float lanes x >= 0 (or NaN): IEEE pow's special cases
/// for those x (pow(+-0, y) as IEEE, odd integer y keeping the zero's sign); x < 0 gives NaN.
template <int N>
struct PowF32 {
  using L = Lanes<N>;
  using F = typename L::F;
  using D = typename L::D;
  using U = typename L::U;

  explicit PowF32(float y) : y_(y) {
    y_nan_ = y != y;
    y_zero_ = y == 0.0f;
    y_pos_ = y > 0.0f;
    y_inf_ = y == __builtin_inff() || y == -__builtin_inff();
    const double yd = y;  // odd integers: |y| < 2^24, y integral, y / 2 not
    y_odd_ = std::fabs(yd) < 0x1p24 && yd == std::trunc(yd) && std::fmod(yd, 2.0) != 0.0;
  }

  // The evaluation in four steps, so that a caller can run each step over a block of values
  // before the next (pow_blocks below): one value's steps form a dependency chain of ~150 cycles
  // that leaves most of a core's vector units idle, while a step run over a block of
  // independent values keeps them busy. Same operations on every value either way.

  /// Step 1: x = 2^e m, m in [sqrt(1/2), sqrt(2)), and s = (m - 1) / (m + 1).
  struct Reduced {
    D s, e;
  };
  static Reduced reduce(F xf) {
    namespace om = oracle_math;
    const D x = L::widen(xf);  // float subnormals are normal doubles
    // The exponent read after moving the binade edge from 1 to sqrt(1/2). For x > 0 finite
    // every step is exact.
    const U ix = L::bits(x);
    const U eb = (ix - om::kSqrtHalfBits + (om::kBias << 52)) >> 52;  // e + 1023
    const D m = L::from_bits(ix - ((eb - om::kBias) << 52));
    const D e = L::from_bits(eb | om::kTwo52Bits) - om::kTwo52 - double(om::kBias);
    return {(m - 1.0) / (m + 1.0), e};
  }

  /// Step 2: t = y log2 x split as k + g (k an integer as the rounding trick's bits, |g| <= 1/2),
  /// and t_rough = t in one rounding, which decides overflow and underflow.
  struct Split {
    D g;
    U k;
    D t_rough;
  };
  Split split(D s, D e) const {
    namespace om = oracle_math;
    const double y = y_;
    const D z = s * s;
    // q = 1/3 + z/5 + ... + z^8/19 in Estrin's form.
    const D z2 = z * z;
    const D z4 = z2 * z2;
    const D z8 = z4 * z4;
    const D q01 = 1.0 / 3.0 + z * (1.0 / 5.0);
    const D q23 = 1.0 / 7.0 + z * (1.0 / 9.0);
    const D q45 = 1.0 / 11.0 + z * (1.0 / 13.0);
    const D q67 = 1.0 / 15.0 + z * (1.0 / 17.0);
    const D q = ((q01 + z2 * q23) + z4 * (q45 + z2 * q67)) + z8 * (1.0 / 19.0);
    const D log_m = 2.0 * s + 2.0 * s * (z * q);  // ln m
    const D ylog2m = y * (log_m * om::kInvLn2);
    // t = y e + y log2 m, y e exact. Where |t| > 160 the float result is 0 or inf; the other
    // lanes have |y| <= 320 (or e = 0), so |y e| < 2^51 and the rounding trick holds.
    const D ye = y * e;
    const D t_rough = ye + ylog2m;
    const D ye_s = ye + om::kRound;
    const D ke = ye_s - om::kRound;
    const D f = (ye - ke) + ylog2m;
    const D f_s = f + om::kRound;
    const D g = f - (f_s - om::kRound);  // |g| <= 1/2
    const U k = (L::bits(ye_s) - om::kRoundBits) + (L::bits(f_s) - om::kRoundBits);
    return {g, k, t_rough};
  }

  /// Step 3: 2^t = e^(g ln 2) 2^k.
  static D power(D g, U k) {
    return exp_series(g * oracle_math::kLn2) * pow2_from_k<N>(k);
  }

  /// Step 4: overflow, underflow and IEEE pow's special cases for these x (y is fixed per
  /// call, so they are chosen once), rounded to float.
  F finish(F xf, D t_rough, D pw) const {
    const D x = L::widen(xf);
    const D inf = D{} + __builtin_inf(), nan = D{} + __builtin_nan(""), one = D{} + 1.0;
    const auto over = t_rough > 130.0;
    const D out_of_range = over ? inf : D{};
    D r = over | (t_rough < -160.0) ? out_of_range : pw;
    const D at_zero = y_pos_ ? (y_odd_ ? x : D{}) : (y_odd_ ? 1.0 / x : inf);
    const D at_inf = y_pos_ ? inf : D{};
    if (y_inf_) r = y_pos_ ? (x < 1.0 ? D{} : inf) : (x < 1.0 ? inf : D{});  // by side of 1
    r = x == 0.0 ? at_zero : r;
    r = x == __builtin_inf() ? at_inf : r;
    r = x < 0.0 ? nan : r;
    r = x != x ? x : r;
    r = y_nan_ ? nan : r;
    r = x == 1.0 ? one : r;  // pow(1, y) = 1, also for y NaN
    r = y_zero_ ? one : r;   // pow(x, 0) = 1, also for x NaN
    return L::narrow(r);
  }

  F operator()(F xf) const {
    const Reduced a = reduce(xf);
    const Split b = split(a.s, a.e);
    return finish(xf, b.t_rough, power(b.g, b.k));
  }

 private:
  float y_;
  bool y_nan_, y_zero_, y_pos_, y_inf_, y_odd_;
};

/// pow over n floats in place, n a multiple of N: each of PowF32's steps runs over a block of
/// values before the next, the intermediate lanes held in a few KiB on the stack (L1), which
/// keeps the vector units busy where one value at a time leaves them waiting on its chain. The
/// same operations on every value as PowF32::operator(), so the same bits (tests/
/// test_oracle_math.cpp; docs/design.md, "The finishing stages are vectorised in double lanes,
/// with the oracle's bits").
template <int N>
inline void pow_blocks(const PowF32<N>& pow, float* p, std::size_t n) {
  using L = Lanes<N>;
  using F = typename L::F;
  using D = typename L::D;
  using U = typename L::U;
  constexpr std::size_t kBlock = 256;
  static_assert(kBlock % N == 0);
  D s[kBlock / N], e[kBlock / N], g[kBlock / N], t[kBlock / N];
  U k[kBlock / N];
  for (std::size_t base = 0; base < n; base += kBlock) {
    const std::size_t count = (n - base < kBlock ? n - base : kBlock) / N;
    float* q = p + base;
    for (std::size_t i = 0; i < count; ++i) {
      F x;
      std::memcpy(&x, q + i * N, sizeof x);
      const auto a = PowF32<N>::reduce(x);
      s[i] = a.s;
      e[i] = a.e;
    }
    for (std::size_t i = 0; i < count; ++i) {
      const auto b = pow.split(s[i], e[i]);
      g[i] = b.g;
      k[i] = b.k;
      t[i] = b.t_rough;
    }
    for (std::size_t i = 0; i < count; ++i) g[i] = PowF32<N>::power(g[i], k[i]);
    for (std::size_t i = 0; i < count; ++i) {
      F x;
      std::memcpy(&x, q + i * N, sizeof x);
      x = pow.finish(x, t[i], g[i]);
      std::memcpy(q + i * N, &x, sizeof x);
    }
  }
}

/// The f32 tone map of one value per lane: x = -h * exposure; 1 - exp(x) for |x| >= 0.5, and
/// below it the Taylor series of 1 - e^-a (a = -x) in Horner form,
/// a (1 - a/2 (1 - a/3 (1 - ... (1 - a/8)))): 1 - exp(x) cancels for small |x| (exp(-1e-10)
/// rounds to 1 and the result to 0, where the truth is 1e-10; the gamma curve then turns a 6e-8
/// error into 5e-4). Truncation a^8/9! < 1e-8 relative; the 1/k are the same float constants
/// as in tonemap.glsl, multiplications and subtractions only (correctly rounded in GLSL).
/// Reason and measured effect: docs/design.md, "The tone map has no cancellation".
///
/// tonemap_series is the series for any float vector F (or float), with the mask of the lanes
/// that take it; tonemap_f32 adds exp's lanes. The fast kernel runs the series on wider vectors
/// than exp's double lanes allow (finish_kernels.inc).
template <class F>
inline auto tonemap_series(F h, float exposure, F& series) {
  const F x = -h * exposure;
  const F a = -x;
  F r = 1.0f - a * 0.125f;
  r = 1.0f - a * 0.14285715f * r;
  r = 1.0f - a * 0.16666667f * r;
  r = 1.0f - a * 0.2f * r;
  r = 1.0f - a * 0.25f * r;
  r = 1.0f - a * 0.33333334f * r;
  r = 1.0f - a * 0.5f * r;
  series = a * r;
  const F abs_a = a < 0.0f ? -a : a;  // NaN: not below 0.5 -> 1 - exp(NaN) = NaN
  return abs_a < 0.5f;
}

template <int N>
inline typename Lanes<N>::F tonemap_f32(typename Lanes<N>::F h, float exposure) {
  using F = typename Lanes<N>::F;
  F series;
  const auto near = tonemap_series(h, exposure, series);
  // Where every lane takes the series (dark pixels, most of a typical frame), exp is not
  // evaluated at all: the lanes' results are the same, and the finishing stages skip most of
  // their exp work (docs/design.md, "The finishing stages are vectorised in double lanes, with
  // the oracle's bits").
  if (all_lanes(near)) return series;
  const F far = 1.0f - exp_f32<N>(-h * exposure);
  return near ? series : far;
}

}  // namespace BLOOMREF_ISA_NAMESPACE
}  // namespace bloomref::detail
