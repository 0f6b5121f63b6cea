// OpenEXR's inverse wavelet (ImfWav.cpp, wav2Decode; "OpenEXR File Layout", PIZ): from the
// coarsest level down, each 2x2 block (x, y), (x + p, y), (x, y + p), (x + p, y + p) at steps
// of 2p is decoded by four 1-D steps, then a column or row left over when the size is odd by
// one. The finest level, p = 1, is three quarters of the work: there the blocks are adjacent
// values, and the steps run 8 words at a time (SSE2: every x86-64 has it). Word positions are
// independent, so both of a FLOAT's words go through together, level by level.
#include "wavelet.h"

#include <algorithm>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace bloomref::detail {
namespace {

// One 1-D step: (l, h) to (a, b). 14-bit: a = l + (h & 1) + (h >> 1), b = a - h, in signed
// 16-bit values. 16-bit: modulo 2^16, b = l - (h >> 1), a = h + b - 2^15.
template <bool W14>
inline void step(std::uint16_t l, std::uint16_t h, std::uint16_t& a, std::uint16_t& b) {
  if constexpr (W14) {
    const int hs = static_cast<std::int16_t>(h);
    const int ai = static_cast<std::int16_t>(l) + (hs & 1) + (hs >> 1);
    a = static_cast<std::uint16_t>(ai);
    b = static_cast<std::uint16_t>(ai - hs);
  } else {
    const int bb = (int(l) - (int(h) >> 1)) & 0xffff;
    a = static_cast<std::uint16_t>((int(h) + bb - 0x8000) & 0xffff);
    b = static_cast<std::uint16_t>(bb);
  }
}

// A 2x2 block: (p00, p10) and (p01, p11) down the columns, then along both rows.
template <bool W14>
inline void block(std::uint16_t* p00, std::uint16_t* p01, std::uint16_t* p10, std::uint16_t* p11) {
  std::uint16_t i00, i01, i10, i11;
  step<W14>(*p00, *p10, i00, i10);
  step<W14>(*p01, *p11, i01, i11);
  step<W14>(i00, i01, *p00, *p01);
  step<W14>(i10, i11, *p10, *p11);
}

// One level (p: the block's spacing, p2 = 2p) of one word position, x step ox, y step oy; the
// blocks of whole row pairs from x_from on (those before it done already).
template <bool W14>
void level(std::uint16_t* in, int nx, int ox, int ny, int oy, int p, int p2, int x_from = 0) {
  int y = 0;
  for (; y <= ny - p2; y += p2) {
    std::uint16_t* row = in + std::size_t(y) * oy;
    int x = x_from;
    for (; x <= nx - p2; x += p2) {
      std::uint16_t* px = row + std::size_t(x) * ox;
      block<W14>(px, px + std::size_t(p) * ox, px + std::size_t(p) * oy,
                 px + std::size_t(p) * oy + std::size_t(p) * ox);
    }
    if (nx & p) {  // the odd column
      std::uint16_t *px = row + std::size_t(x) * ox, *p10 = px + std::size_t(p) * oy, i00;
      step<W14>(*px, *p10, i00, *p10);
      *px = i00;
    }
  }
  if (ny & p) {  // the odd row
    std::uint16_t* row = in + std::size_t(y) * oy;
    for (int x = 0; x <= nx - p2; x += p2) {
      std::uint16_t *px = row + std::size_t(x) * ox, *p01 = px + std::size_t(p) * ox, i00;
      step<W14>(*px, *p01, i00, *p01);
      *px = i00;
    }
  }
}

#if defined(__SSE2__)
template <bool W14>
inline void step8(__m128i l, __m128i h, __m128i& a, __m128i& b) {
  if constexpr (W14) {
    a = _mm_add_epi16(_mm_add_epi16(l, _mm_and_si128(h, _mm_set1_epi16(1))), _mm_srai_epi16(h, 1));
    b = _mm_sub_epi16(a, h);
  } else {
    b = _mm_sub_epi16(l, _mm_srli_epi16(h, 1));
    a = _mm_add_epi16(_mm_add_epi16(h, b), _mm_set1_epi16(-0x8000));
  }
}

// Two rows of the finest level of a FLOAT block (2 words a value): 32 bits a value, so an
// 8-word vector holds 2 blocks; a block's left values are its even 32-bit lanes. Returns the
// values done.
template <bool W14>
int finest_pairs_float(std::uint16_t* r0, std::uint16_t* r1, int nx) {
  const __m128i odd = _mm_set_epi32(-1, 0, -1, 0);
  int x = 0;
  for (; x + 4 <= nx; x += 4) {
    __m128i* a = reinterpret_cast<__m128i*>(r0 + 2 * x);
    __m128i* b = reinterpret_cast<__m128i*>(r1 + 2 * x);
    __m128i top, bottom;
    step8<W14>(_mm_loadu_si128(a), _mm_loadu_si128(b), top, bottom);
    __m128i l0, h0, l1, h1;
    step8<W14>(_mm_shuffle_epi32(top, _MM_SHUFFLE(2, 2, 0, 0)),
               _mm_shuffle_epi32(top, _MM_SHUFFLE(3, 3, 1, 1)), l0, h0);
    step8<W14>(_mm_shuffle_epi32(bottom, _MM_SHUFFLE(2, 2, 0, 0)),
               _mm_shuffle_epi32(bottom, _MM_SHUFFLE(3, 3, 1, 1)), l1, h1);
    _mm_storeu_si128(a, _mm_or_si128(_mm_and_si128(odd, h0), _mm_andnot_si128(odd, l0)));
    _mm_storeu_si128(b, _mm_or_si128(_mm_and_si128(odd, h1), _mm_andnot_si128(odd, l1)));
  }
  return x;
}
#endif

// The finest level (p = 1) of every word position of a block: a FLOAT block's row pairs 4
// values at a time where SSE2 is, the rest (and the odd column and row) as every level.
template <bool W14>
void finest(std::uint16_t* in, int nx, int words, int ny) {
  const int oy = nx * words;
  int done = 0;
#if defined(__SSE2__)
  if (words == 2)
    for (int y = 0; y <= ny - 2; y += 2) {
      std::uint16_t* r0 = in + std::size_t(y) * oy;
      done = finest_pairs_float<W14>(r0, r0 + oy, nx & ~1);
    }
#endif
  for (int j = 0; j < words; ++j) level<W14>(in + j, nx, words, ny, oy, 1, 2, done);
}

template <bool W14>
void decode(std::uint16_t* in, int nx, int words, int ny) {
  // The levels: p2 the largest power of two not above min(nx, ny), p half of it, down to 1.
  const int n = std::min(nx, ny);
  int p = 1;
  while (p <= n) p <<= 1;
  p >>= 1;
  int p2 = p;
  p >>= 1;
  for (; p >= 2; p2 = p, p >>= 1)
    for (int j = 0; j < words; ++j) level<W14>(in + j, nx, words, ny, nx * words, p, p2);
  if (p == 1) finest<W14>(in, nx, words, ny);
}

}  // namespace

void wavelet_decode_block(std::uint16_t* block, int width, int words, int lines,
                          std::uint16_t max) {
  if (width <= 0 || lines <= 0 || words <= 0) return;
  if (max < (1 << 14))
    decode<true>(block, width, words, lines);
  else
    decode<false>(block, width, words, lines);
}

}  // namespace bloomref::detail
