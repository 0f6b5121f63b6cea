// The exact horizontal pass along its rows, 16 floats of a row a vector (blur_internal.h,
// RowTaps): the rows whose lookup across sits on them (blur_rows_exact_avx512: blur_texel's
// operations in its order) and those whose lookup mixes two (blur_row_inexact_avx512:
// blur_inexact_lines's, bilinear_v4's terms), from rows of R, G, B or, packed in registers, of
// RGBA (the first pass). Built with -mavx512f; nothing is fused (-ffp-contract=off, no FMA
// intrinsics), so every lane does the reference's operations in its order; only called where
// the CPU has AVX-512F.
//
// A lane reads its taps' texels 3 floats apart, so the vectors it needs start 3 j floats from
// its own (j = -5 ... 5): they are cut from three aligned vectors by lane rotations (valignd),
// as loading them unaligned, each straddling two cache lines, is far slower (docs/design.md,
// "Horizontal passes: transposed tiles, or rows on AVX-512").
#define BLOOMREF_ISA_NAMESPACE isa_avx512
#include <immintrin.h>

#include <algorithm>
#include <cstdint>
#include <type_traits>

#include "blur_internal.h"

namespace bloomref::detail {
namespace {

constexpr int L = RowTaps::kLanes;
// How far ahead (in vectors) the first pass fetches its RGBA rows (4, 8 and 16 alike). Without
// the prefetch the fused passes run slower on the row kernel than on the tile kernel; with it,
// faster.
constexpr int kPrefetch = 8;

// s[j + 5]: the row's floats [f + 3 j, f + 3 j + 16), j = -5 ... 5, from a, b, c: its vectors
// at f - 16, f and f + 16. The zero-masked form with every lane kept is valignd itself (GCC 12's
// plain one warns of an undefined operand).
inline void shifted(__m512i a, __m512i b, __m512i c, __m512i* s) {
  s[0] = _mm512_maskz_alignr_epi32(0xffff, b, a, 1);
  s[1] = _mm512_maskz_alignr_epi32(0xffff, b, a, 4);
  s[2] = _mm512_maskz_alignr_epi32(0xffff, b, a, 7);
  s[3] = _mm512_maskz_alignr_epi32(0xffff, b, a, 10);
  s[4] = _mm512_maskz_alignr_epi32(0xffff, b, a, 13);
  s[5] = b;
  s[6] = _mm512_maskz_alignr_epi32(0xffff, c, b, 3);
  s[7] = _mm512_maskz_alignr_epi32(0xffff, c, b, 6);
  s[8] = _mm512_maskz_alignr_epi32(0xffff, c, b, 9);
  s[9] = _mm512_maskz_alignr_epi32(0xffff, c, b, 12);
  s[10] = _mm512_maskz_alignr_epi32(0xffff, c, b, 15);
}

// The packing of R, G, B vector j of a row from RGBA: with m = j / 3 and p = j % 3, its floats
// 16 j + l are texel T = 16 m + (16 p + l) / 3, channel (16 p + l) % 3, i.e. float
// 4 T + channel of the RGBA row, which lies in its vectors j + m and j + m + 1 (index below 32
// from float 16 (j + m)): one two-table permutation of two loads.
struct RgbaPacking {
  __m512i idx[3];
  RgbaPacking() {
    alignas(64) std::int32_t v[3][L];
    for (int p = 0; p < 3; ++p)
      for (int l = 0; l < L; ++l) {
        const int f = 16 * p + l;
        v[p][l] = 4 * (f / 3) + f % 3 - 16 * p;
      }
    for (int p = 0; p < 3; ++p) idx[p] = _mm512_load_si512(v[p]);
  }
  __m512i rgb(const float* row, int j) const {
    const float* q = row + std::ptrdiff_t(L) * (j + j / 3);
    return _mm512_castps_si512(
        _mm512_permutex2var_ps(_mm512_loadu_ps(q), idx[j % 3], _mm512_loadu_ps(q + L)));
  }
};

struct NoPacking {};  // rows of 3 floats a texel need none

// The shifted vectors of vector v of a row of C floats a texel (3: as they are; 4: packed).
template <int C, class Packing>
inline void shifted_at(const float* row, int v, const Packing& pk, __m512i* s) {
  if constexpr (C == 3) {
    const float* p = row + std::ptrdiff_t(v) * L;
    shifted(_mm512_castps_si512(_mm512_loadu_ps(p - L)), _mm512_castps_si512(_mm512_loadu_ps(p)),
            _mm512_castps_si512(_mm512_loadu_ps(p + L)), s);
  } else {
    shifted(pk.rgb(row, v - 1), pk.rgb(row, v), pk.rgb(row, v + 1), s);
  }
}

// Bit k: tap k of a vector (its masks m[k]) is not every lane one texel at its offset (sel all
// lanes, two none), so it takes tap's second form. Found once per vector, not tested from its
// masks anew in every row: a load, a shift and a compare-and-branch a tap less per row.
inline std::uint32_t second_form_taps(const std::uint32_t* m) {
  std::uint32_t bits = 0;
  for (int k = 0; k < RowTaps::kTaps; ++k)
    if (m[k] != 0xffffu) bits |= 1u << k;
  return bits;
}

// r = term (K = 0) or r + term: tap K at offset O (shader order) of the vector whose shifted
// copies are s. Every lane one texel at its offset: p wk. Otherwise (p0 w0 + p1 w1) wk, where a
// one-texel lane has w0 = 1 and its second product is -0 (masked), so the same bits as p0 wk.
// The branches are taken alike for every row of a vector, so they are predicted.
template <int K, int O>
inline void tap(const __m512i* s, const float* w, const std::uint32_t* m, std::uint32_t second,
                __m512 wk, __m512& r) {
  __m512 q;
  if (!(second & (1u << K))) {
    q = _mm512_mul_ps(_mm512_castsi512_ps(s[O + 5]), wk);
  } else {
    const __mmask16 sel = __mmask16(m[K]), two = __mmask16(m[K] >> 16);
    __m512 p0 = _mm512_castsi512_ps(s[O + 5]), p1 = _mm512_castsi512_ps(s[O + 6]);
    if (sel != 0xffff) {
      p0 = _mm512_mask_blend_ps(sel, _mm512_castsi512_ps(s[O + 4]), p0);
      p1 = _mm512_mask_blend_ps(sel, _mm512_castsi512_ps(s[O + 5]), p1);
    }
    const __m512 t = _mm512_mul_ps(p0, _mm512_load_ps(w + 2 * L * K));
    const __m512 u =
        _mm512_mask_mul_ps(_mm512_set1_ps(-0.0f), two, p1, _mm512_load_ps(w + 2 * L * K + L));
    q = _mm512_mul_ps(_mm512_add_ps(t, u), wk);
  }
  r = K == 0 ? q : _mm512_add_ps(r, q);
}

// r = term (K = 0) or r + term: tap K at offset O of an inexact row, rows a and b mixed at
// weights wa and wb (blur_row_inexact_avx512).
template <int K, int O>
inline void tap2(const __m512i* sa, const __m512i* sb, const float* w, const std::uint32_t* m,
                 __m512 wa, __m512 wb, __m512 wk, __m512& r) {
  const __mmask16 sel = __mmask16(m[K]), two = __mmask16(m[K] >> 16);
  __m512 a0 = _mm512_castsi512_ps(sa[O + 5]), b0 = _mm512_castsi512_ps(sb[O + 5]);
  __m512 s;
  if (sel == 0xffff && two == 0) {
    // Every lane one texel at its offset: p_a (1 wa) + p_b (1 wb).
    s = _mm512_add_ps(_mm512_mul_ps(a0, wa), _mm512_mul_ps(b0, wb));
  } else {
    __m512 a1 = _mm512_castsi512_ps(sa[O + 6]), b1 = _mm512_castsi512_ps(sb[O + 6]);
    if (sel != 0xffff) {
      a0 = _mm512_mask_blend_ps(sel, _mm512_castsi512_ps(sa[O + 4]), a0);
      b0 = _mm512_mask_blend_ps(sel, _mm512_castsi512_ps(sb[O + 4]), b0);
      a1 = _mm512_mask_blend_ps(sel, _mm512_castsi512_ps(sa[O + 5]), a1);
      b1 = _mm512_mask_blend_ps(sel, _mm512_castsi512_ps(sb[O + 5]), b1);
    }
    const __m512 w0 = _mm512_load_ps(w + 2 * L * K), w1 = _mm512_load_ps(w + 2 * L * K + L);
    const __m512 nz = _mm512_set1_ps(-0.0f);
    s = _mm512_mul_ps(a0, _mm512_mul_ps(w0, wa));
    s = _mm512_add_ps(s, _mm512_mask_mul_ps(nz, two, a1, _mm512_mul_ps(w1, wa)));
    s = _mm512_add_ps(s, _mm512_mul_ps(b0, _mm512_mul_ps(w0, wb)));
    s = _mm512_add_ps(s, _mm512_mask_mul_ps(nz, two, b1, _mm512_mul_ps(w1, wb)));
  }
  const __m512 q = _mm512_mul_ps(s, wk);
  r = K == 0 ? q : _mm512_add_ps(r, q);
}

// The lanes of vector v whose floats 16 v + l lie in [f0, f1).
inline __mmask16 kept_lanes(int v, int f0, int f1) {
  const int lo = std::clamp(f0 - L * v, 0, L), hi = std::clamp(f1 - L * v, 0, L);
  return __mmask16(((1u << hi) - 1) & ~((1u << lo) - 1));
}
inline void store(float* p, __mmask16 keep, __m512 r) {
  if (keep == 0xffff) _mm512_storeu_ps(p, r);
  else _mm512_mask_storeu_ps(p, keep, r);
}

template <int C>
void row_inexact(const RowInexactJob& job) {
  const std::conditional_t<C == 4, RgbaPacking, NoPacking> pk;
  __m512 wk[5];
  for (int i = 0; i < 5; ++i) wk[i] = _mm512_set1_ps(job.weights[i]);
  const __m512 wa = _mm512_set1_ps(job.wa), wb = _mm512_set1_ps(job.wb);
  for (int v = job.v0; v < job.v1; ++v) {
    const float* w = job.taps->w.data() + std::size_t(v) * RowTaps::kTaps * 2 * L;
    const std::uint32_t* m = job.taps->masks.data() + std::size_t(v) * RowTaps::kTaps;
    const std::ptrdiff_t f = std::ptrdiff_t(v) * L;
    __m512i sa[11], sb[11];
    shifted_at<C>(job.a, v, pk, sa);
    shifted_at<C>(job.b, v, pk, sb);
    __m512 r;
    each_row_tap([&](auto K, auto O) { tap2<K, O>(sa, sb, w, m, wa, wb, wk[(K + 1) / 2], r); });
    store(job.dst + f, kept_lanes(v, job.f0, job.f1), r);
  }
}

// Rows [y, r1) of vector v of rows of R, G, B (the rings), two at a time, their taps
// interleaved: two independent chains of eight additions in flight where one row has one, which
// is faster than the one-row kernel. Returns the row left over when their count is odd (r1
// otherwise).
// Rows packed from RGBA (rows_exact<4>, the first pass of blur_passes_fused) stay one at a time:
// their packing's index registers beside two rows' shifted vectors make pairs there slower than
// pairs for the rings alone.
__attribute__((always_inline)) inline int row_pairs(const RowsExactJob& job, int v, int y, int r1,
                                                    const float* w, const std::uint32_t* m,
                                                    std::uint32_t second, const __m512* wk,
                                                    __mmask16 keep) {
  const NoPacking pk;
  const std::ptrdiff_t f = std::ptrdiff_t(v) * L;
  for (; y + 1 < r1; y += 2) {
    __m512i s[11], t[11];
    shifted_at<3>(job.src_rows[y], v, pk, s);
    shifted_at<3>(job.src_rows[y + 1], v, pk, t);
    __m512 r, q;
    each_row_tap([&](auto K, auto O) {
      tap<K, O>(s, w, m, second, wk[(K + 1) / 2], r);
      tap<K, O>(t, w, m, second, wk[(K + 1) / 2], q);
    });
    store(job.dst_rows[y] + f, keep, r);
    store(job.dst_rows[y + 1] + f, keep, q);
  }
  return y;
}

template <int C>
void rows_exact(const RowsExactJob& job, int r0, int r1) {
  const std::conditional_t<C == 4, RgbaPacking, NoPacking> pk;
  __m512 wk[5];
  for (int i = 0; i < 5; ++i) wk[i] = _mm512_set1_ps(job.weights[i]);
  for (int v = job.v0; v < job.v1; ++v) {
    const float* w = job.taps->w.data() + std::size_t(v) * RowTaps::kTaps * 2 * L;
    const std::uint32_t* m = job.taps->masks.data() + std::size_t(v) * RowTaps::kTaps;
    const std::ptrdiff_t f = std::ptrdiff_t(v) * L;
    const __mmask16 keep = kept_lanes(v, job.f0, job.f1);
    const std::uint32_t second = second_form_taps(m);
    int y = r0;
    if constexpr (C == 3) y = row_pairs(job, v, y, r1, w, m, second, wk, keep);
    for (; y < r1; ++y) {
      __m512i s[11];
      shifted_at<C>(job.src_rows[y], v, pk, s);
      if constexpr (C == 4) {
        // The source comes from memory, a few floats of each of the chunk's rows in turn:
        // fetched kPrefetch vectors ahead (the two lines the packing of vector v + kPrefetch
        // starts in; a prefetch past the row does not fault, and its address is an integer,
        // not a pointer past the row's array).
        const int u = v + kPrefetch;
        const std::uintptr_t q = reinterpret_cast<std::uintptr_t>(job.src_rows[y]) +
                                 sizeof(float) * std::uintptr_t(L) * std::uintptr_t(u + u / 3);
        _mm_prefetch(reinterpret_cast<const char*>(q), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(q + 64), _MM_HINT_T0);
      }
      __m512 r;
      each_row_tap([&](auto K, auto O) { tap<K, O>(s, w, m, second, wk[(K + 1) / 2], r); });
      store(job.dst_rows[y] + f, keep, r);
    }
  }
}

}  // namespace

void blur_row_inexact_avx512(const RowInexactJob& job) {
  if (job.src_channels == 4) row_inexact<4>(job);
  else row_inexact<3>(job);
}

void blur_rows_exact_avx512(const RowsExactJob& job, int r0, int r1) {
  if (job.src_channels == 4) rows_exact<4>(job, r0, r1);
  else rows_exact<3>(job, r0, r1);
}

}  // namespace bloomref::detail
