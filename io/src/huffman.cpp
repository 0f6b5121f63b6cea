// OpenEXR's Huffman blocks, read as "OpenEXR File Layout" (PIZ) and ImfHuf.cpp (hufCompress,
// hufCanonicalCodeTable) write them. OpenEXR's own decoders look codes of up to 12 bits up in a
// table and search for longer ones length by length; in FLOAT stages two fifths of the codes
// are 16-19 bits long (the low 16 bits of floats are close to noise), and runs of one value
// (alpha, black), which they copy value by value, are many.
#include "huffman.h"

#include <algorithm>
#include <array>
#include <cstring>

namespace bloomref::detail {
namespace {

constexpr unsigned kSymbols = 65537;  // 16-bit values and the run code (HUF_ENCSIZE)
constexpr int kMaxLength = 58;
constexpr int kTableBits = 12;        // a 16 KiB table (in L1), rebuilt for every block
constexpr int kLonger = 8;            // longer lengths counted, not searched, up to this many

std::uint32_t le32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
         std::uint32_t(p[3]) << 24;
}

std::uint64_t be64(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, sizeof v);
  return __builtin_bswap64(v);
}

// The 64 bits from bit `pos` on (most significant first); 8 bytes of padding after the data.
std::uint64_t peek(const std::uint8_t* d, std::size_t pos) {
  const unsigned shift = pos & 7;
  const std::uint64_t w = be64(d + (pos >> 3)) << shift;
  return shift ? w | d[(pos >> 3) + 8] >> (8 - shift) : w;
}

}  // namespace

bool huf_decode(const std::uint8_t* in, std::size_t n, std::uint16_t* out, std::size_t count,
                HufScratch& s) {
  if (n < 20) return count == 0;
  const std::uint32_t im = le32(in), iM = le32(in + 4), nbits = le32(in + 12);
  if (im >= kSymbols || iM >= kSymbols || im > iM) return false;

  // The code lengths of [im, iM], 6 bits each, most significant bit first.
  const std::uint8_t *p = in + 20, *const end = in + n;
  std::uint64_t c = 0;
  int lc = 0;
  const auto bits = [&](int nb, unsigned& v) {
    while (lc < nb) {
      if (p == end) return false;
      c = c << 8 | *p++;
      lc += 8;
    }
    lc -= nb;
    v = static_cast<unsigned>(c >> lc) & ((1u << nb) - 1);
    return true;
  };
  s.lengths.assign(std::size_t(iM - im) + 1, 0);
  std::array<std::uint32_t, kMaxLength + 1> counts{};
  for (std::uint32_t i = im; i <= iM; ++i) {
    unsigned l;
    if (!bits(6, l)) return false;
    if (l >= 59) {  // a run of zero lengths: 59-62 for 2-5, 63 and 8 bits for 6-261
      unsigned run = l - 59 + 2;
      if (l == 63) {
        if (!bits(8, run)) return false;
        run += 6;
      }
      if (run > iM + 1 - i) return false;
      i += run - 1;
      continue;
    }
    s.lengths[i - im] = static_cast<std::uint8_t>(l);
    ++counts[l];
  }

  // Canonical codes: the lowest code of each length, from the longest down.
  std::array<std::uint64_t, kMaxLength + 1> base{};
  std::uint64_t next = 0;
  for (int l = kMaxLength; l > 0; --l) {
    base[l] = next;
    next = (next + counts[l]) >> 1;
    if (counts[l] && (base[l] + counts[l] - 1) >> l) return false;  // more codes than fit
  }
  // The symbols of each length in increasing order, from first[l] on, as 16 bits: the run code
  // iM may be 65536, and is told by where it is (run_at) instead.
  std::array<std::uint32_t, kMaxLength + 2> first{};
  for (int l = 1; l <= kMaxLength; ++l) first[l + 1] = first[l] + counts[l];
  s.symbols.resize(std::max<std::uint32_t>(first[kMaxLength + 1], 1));
  std::uint32_t run_at = UINT32_MAX;
  {
    std::array<std::uint32_t, kMaxLength + 1> at{};
    for (int l = 1; l <= kMaxLength; ++l) at[l] = first[l];
    for (std::uint32_t i = im; i <= iM; ++i)
      if (const int l = s.lengths[i - im]) {
        if (i == iM) run_at = at[l];
        s.symbols[at[l]++] = static_cast<std::uint16_t>(i);
      }
  }
  // Codes of up to kTableBits bits: every table entry they begin, (symbol << 16) | (0x100 for
  // the run code) | length. The entries left 0 begin longer codes (or none).
  s.table.assign(std::size_t(1) << kTableBits, 0);
  for (int l = 1; l <= kTableBits; ++l)
    for (std::uint32_t k = 0; k < counts[l]; ++k) {
      const std::uint32_t at = first[l] + k;
      const std::size_t from = std::size_t(base[l] + k) << (kTableBits - l);
      std::fill_n(s.table.begin() + from, std::size_t(1) << (kTableBits - l),
                  std::uint32_t(s.symbols[at]) << 16 | (at == run_at ? 0x100u : 0u) |
                      std::uint32_t(l));
    }
  // Longer codes, of the lengths longer[0] < longer[1] < ...: the code's length is longer[j]
  // for j the number of those lengths whose lowest code, left-justified (left[j], falling with
  // j), is above the bits. Past the lengths there are: a length of 63 and no codes.
  std::array<std::uint64_t, kMaxLength + 1> left{}, lbase{};
  std::array<std::uint32_t, kMaxLength + 1> llen{}, lcount{}, lfirst{};
  int nlonger = 0;
  for (int l = kTableBits + 1; l <= kMaxLength; ++l)
    if (counts[l]) {
      left[nlonger] = base[l] << (64 - l);
      llen[nlonger] = l;
      lbase[nlonger] = base[l];
      lcount[nlonger] = counts[l];
      lfirst[nlonger++] = first[l];
    }
  llen[nlonger] = 63;

  // The codes: nbits bits from the end of the table, copied with 9 bytes of padding.
  const std::size_t bytes = (std::size_t(nbits) + 7) / 8;
  if (bytes > std::size_t(end - p)) return false;
  s.bits.resize(bytes + 9);
  std::memcpy(s.bits.data(), p, bytes);
  std::memset(s.bits.data() + bytes, 0, 9);
  const std::uint8_t* d = s.bits.data();
  const std::uint32_t* table = s.table.data();
  const std::uint16_t* symbols = s.symbols.data();
  std::size_t pos = 0, o = 0;
  while (o < count) {
    const std::uint64_t w = peek(d, pos);
    const std::uint32_t e = table[w >> (64 - kTableBits)];
    unsigned l = e & 0xff, symbol = e >> 16;
    bool run = e & 0x100;
    if (l == 0) {
      // Counted, not searched, over kLonger lengths when there are no more.
      unsigned j = 0;
      if (nlonger <= kLonger)
        for (int i = 0; i < kLonger; ++i) j += i < nlonger && w < left[i];
      else
        while (j < unsigned(nlonger) && w < left[j]) ++j;
      l = llen[j];
      const std::uint64_t k = (w >> (64 - l)) - lbase[j];
      if (k >= lcount[j]) return false;  // no code begins so
      const std::uint32_t at = lfirst[j] + static_cast<std::uint32_t>(k);
      symbol = symbols[at];
      run = at == run_at;
    }
    pos += l;
    if (pos > nbits) return false;
    if (run) {  // the previous value, as many times again as the next 8 bits say
      if (pos + 8 > nbits || o == 0) return false;
      const std::size_t times = peek(d, pos) >> 56;
      pos += 8;
      if (times > count - o) return false;
      std::fill_n(out + o, times, out[o - 1]);
      o += times;
    } else {
      out[o++] = static_cast<std::uint16_t>(symbol);
    }
  }
  return true;
}

}  // namespace bloomref::detail
