// The horizontal pass's inexact rows along their rows with AVX2 (blur_internal.h,
// blur_row_inexact_avx2): blur_row_inexact_avx512's lanes and terms, 8 floats a vector, from
// rows of R, G, B (the fused blur's rings). Built with -mavx2 only: nothing is fused
// (-ffp-contract=off, no FMA), so every lane does blur_inexact_lines's operations in its order.
//
// The AVX2 build transposes tiles for the other rows. Its inexact rows run here along their rows
// rather than through the group kernel (blur_tiles.inc), whose planes, picks and per-texel
// stores make these few rows (85 of 2160) a large share of the fused passes' time
// (docs/design.md, "Lines whose lookup straddles two lines across the blur go through the
// reference texel"). This kernel serves the passes between rings; the first pass, from RGBA,
// keeps the group kernel.
// The shifted vectors a lane's taps read (3 j floats away) are loaded unaligned: AVX2 has no
// lane rotation across its two halves.
#define BLOOMREF_ISA_NAMESPACE isa_avx2
#include <immintrin.h>

#include <algorithm>
#include <cstdint>

#include "blur_internal.h"

namespace bloomref::detail {
namespace {

constexpr int L = RowTaps::kLanes;  // the tables' vectors: 16 floats, two of ours

// The 8 bits of `bits` as lanes of all ones or all zeros (lane l: bit l).
inline __m256 lane_mask(unsigned bits) {
  const __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  return _mm256_castsi256_ps(
      _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(int(bits)), bit), bit));
}

// r = term (K = 0) or r + term: tap K at offset O of floats [f, f + 8) of an inexact row, rows
// a and b mixed at weights wa and wb; h: which half of the tables' vector (lane for lane
// blur_row_inexact_avx512's tap2).
template <int K, int O>
inline void tap(const float* a, const float* b, std::ptrdiff_t f, int h, const float* w,
                const std::uint32_t* m, __m256 wa, __m256 wb, __m256 wk, __m256& r) {
  const unsigned sel = (m[K] >> (8 * h)) & 0xffu, two = (m[K] >> (16 + 8 * h)) & 0xffu;
  __m256 s;
  if (sel == 0xffu && two == 0) {
    s = _mm256_add_ps(_mm256_mul_ps(_mm256_loadu_ps(a + f + 3 * O), wa),
                      _mm256_mul_ps(_mm256_loadu_ps(b + f + 3 * O), wb));
  } else {
    const __m256 sm = lane_mask(sel), tm = lane_mask(two);
    // The lane's texel a + o - 1 + sel and the next.
    const __m256 a0 = _mm256_blendv_ps(_mm256_loadu_ps(a + f + 3 * (O - 1)),
                                       _mm256_loadu_ps(a + f + 3 * O), sm);
    const __m256 a1 = _mm256_blendv_ps(_mm256_loadu_ps(a + f + 3 * O),
                                       _mm256_loadu_ps(a + f + 3 * (O + 1)), sm);
    const __m256 b0 = _mm256_blendv_ps(_mm256_loadu_ps(b + f + 3 * (O - 1)),
                                       _mm256_loadu_ps(b + f + 3 * O), sm);
    const __m256 b1 = _mm256_blendv_ps(_mm256_loadu_ps(b + f + 3 * O),
                                       _mm256_loadu_ps(b + f + 3 * (O + 1)), sm);
    const __m256 w0 = _mm256_load_ps(w + 2 * L * K + 8 * h);
    const __m256 w1 = _mm256_load_ps(w + 2 * L * K + L + 8 * h);
    const __m256 nz = _mm256_set1_ps(-0.0f);
    // A one-texel lane's second-texel products are -0 (x + -0 = x): what they would be (a
    // weight 0 times an Inf is NaN) is never added.
    s = _mm256_mul_ps(a0, _mm256_mul_ps(w0, wa));
    s = _mm256_add_ps(s, _mm256_blendv_ps(nz, _mm256_mul_ps(a1, _mm256_mul_ps(w1, wa)), tm));
    s = _mm256_add_ps(s, _mm256_mul_ps(b0, _mm256_mul_ps(w0, wb)));
    s = _mm256_add_ps(s, _mm256_blendv_ps(nz, _mm256_mul_ps(b1, _mm256_mul_ps(w1, wb)), tm));
  }
  const __m256 q = _mm256_mul_ps(s, wk);
  r = K == 0 ? q : _mm256_add_ps(r, q);
}

// Stores the lanes of r whose floats f + l lie in [f0, f1).
inline void store(float* d, std::ptrdiff_t f, int f0, int f1, __m256 r) {
  if (f >= f0 && f + 8 <= f1) {
    _mm256_storeu_ps(d + f, r);
    return;
  }
  const __m256i l =
      _mm256_add_epi32(_mm256_set1_epi32(int(f)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256i keep = _mm256_andnot_si256(_mm256_cmpgt_epi32(_mm256_set1_epi32(f0), l),
                                           _mm256_cmpgt_epi32(_mm256_set1_epi32(f1), l));
  _mm256_maskstore_ps(d + f, keep, r);
}

}  // namespace

void blur_row_inexact_avx2(const RowInexactJob& job) {
  __m256 wk[5];
  for (int i = 0; i < 5; ++i) wk[i] = _mm256_set1_ps(job.weights[i]);
  const __m256 wa = _mm256_set1_ps(job.wa), wb = _mm256_set1_ps(job.wb);
  for (int v = job.v0; v < job.v1; ++v) {
    const float* w = job.taps->w.data() + std::size_t(v) * RowTaps::kTaps * 2 * L;
    const std::uint32_t* m = job.taps->masks.data() + std::size_t(v) * RowTaps::kTaps;
    for (int h = 0; h < 2; ++h) {
      const std::ptrdiff_t f = std::ptrdiff_t(v) * L + 8 * h;
      if (f + 8 <= job.f0 || f >= job.f1) continue;
      const float *a = job.a, *b = job.b;
      __m256 r;
      each_row_tap(
          [&](auto K, auto O) { tap<K, O>(a, b, f, h, w, m, wa, wb, wk[(K + 1) / 2], r); });
      store(job.dst, f, job.f0, job.f1, r);
    }
  }
}

}  // namespace bloomref::detail
