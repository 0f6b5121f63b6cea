// OpenEXR's Huffman-coded blocks (the entropy stage of PIZ), decoded with one table lookup for
// every code of up to 12 bits (internal to io).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace bloomref::detail {

/// What huf_decode keeps between blocks (one per thread): its tables and the padded bits.
struct HufScratch {
  std::vector<std::uint8_t> lengths, bits;
  std::vector<std::uint32_t> table;
  std::vector<std::uint16_t> symbols;
};

/// Decodes the block in[0, n) that OpenEXR's hufCompress wrote (ImfHuf.cpp) into the `count`
/// 16-bit values out[0, count). The block: the smallest and largest symbol im and iM (iM codes
/// a run: the next 8 bits repeat the previous value that many times), the code lengths of
/// [im, iM] packed in 6 bits each (59-62: a run of 2-5 zero lengths, 63 and 8 bits: a run of
/// 6-261), then the codes, most significant bit first. Codes are canonical: of each length, the
/// symbols in increasing order, and longer codes below shorter ones. False where the block is
/// inconsistent (a bad table, a code that is none, bits or values running out).
bool huf_decode(const std::uint8_t* in, std::size_t n, std::uint16_t* out, std::size_t count,
                HufScratch& s);

}  // namespace bloomref::detail
