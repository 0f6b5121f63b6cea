// io/src/huffman.h and wavelet.h: bloomref's decoders of PIZ's Huffman blocks and wavelet,
// against OpenEXR's own (ImfHuf.h, ImfWav.h) on data of every shape a PIZ chunk gives them,
// and on Huffman blocks broken on purpose.
#include <ImfHuf.h>
#include <ImfWav.h>

#include <catch2/catch.hpp>
#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "huffman.h"
#include "wavelet.h"

namespace {

using Words = std::vector<std::uint16_t>;

std::vector<std::uint8_t> compress(const Words& raw) {
  // hufCompress needs room for its table and the codes: at worst 58 bits a value.
  std::vector<std::uint8_t> out(raw.size() * 8 + 65537 + 64);
  const int n = Imf::hufCompress(raw.data(), static_cast<int>(raw.size()),
                                 reinterpret_cast<char*>(out.data()));
  out.resize(static_cast<std::size_t>(n));
  return out;
}

Words openexr_decode(const std::vector<std::uint8_t>& block, std::size_t count) {
  Words out(count);
  Imf::hufUncompress(reinterpret_cast<const char*>(block.data()), static_cast<int>(block.size()),
                     out.data(), static_cast<int>(count));
  return out;
}

// Raw data of several shapes: noise (codes of 16-18 bits, as the low words of float stages),
// skewed (short codes), long runs (alpha, black), one value, the largest value (so that the
// run code is 65536), and Fibonacci frequencies (codes of more than 20 bits, more lengths than
// the decoder counts without a loop).
std::vector<std::pair<const char*, Words>> shapes() {
  std::mt19937 rng(7);
  std::vector<std::pair<const char*, Words>> out;
  Words noise(200000);
  for (auto& v : noise) v = static_cast<std::uint16_t>(rng());
  out.emplace_back("noise", noise);
  Words skewed(100000);
  std::geometric_distribution<int> geo(0.3);
  for (auto& v : skewed) v = static_cast<std::uint16_t>(std::min(geo(rng), 65535));
  out.emplace_back("skewed", skewed);
  Words runs;
  for (int r = 0; r < 300; ++r) runs.insert(runs.end(), 1 + rng() % 2000, static_cast<std::uint16_t>(rng() % 7));
  out.emplace_back("runs", runs);
  out.emplace_back("one value", Words(5000, 0x3c00));
  Words top(30000);
  for (auto& v : top) v = static_cast<std::uint16_t>(65535 - rng() % 3);
  out.emplace_back("largest values", top);
  Words fib;
  std::uint64_t a = 1, b = 1;
  for (std::uint16_t s = 0; s < 27; ++s) {
    fib.insert(fib.end(), a, static_cast<std::uint16_t>(1000 + 17 * s));
    const std::uint64_t c = a + b;
    a = b;
    b = c;
  }
  std::shuffle(fib.begin(), fib.end(), rng);
  out.emplace_back("fibonacci", fib);
  out.emplace_back("three values", Words{1, 2, 3});
  out.emplace_back("single", Words{42});
  return out;
}

}  // namespace

TEST_CASE("huf_decode gives the values OpenEXR's encoder coded, as OpenEXR's decoder does",
          "[io][huffman]") {
  bloomref::detail::HufScratch s;
  for (const auto& [name, raw] : shapes()) {
    INFO(name << ", " << raw.size() << " values");
    const std::vector<std::uint8_t> block = compress(raw);
    Words out(raw.size(), 0xdead);
    REQUIRE(bloomref::detail::huf_decode(block.data(), block.size(), out.data(), out.size(), s));
    CHECK(out == raw);
    CHECK(openexr_decode(block, raw.size()) == raw);
  }
}

TEST_CASE("huf_decode refuses broken blocks without reading or writing past them",
          "[io][huffman]") {
  bloomref::detail::HufScratch s;
  std::mt19937 rng(11);
  for (const auto& [name, raw] : shapes()) {
    INFO(name);
    const std::vector<std::uint8_t> block = compress(raw);
    // Cut short anywhere: the codes, the table or the header run out (one value needs none
    // of its codes' bits when the whole block is a run, so only the header must be whole).
    for (std::size_t n : {std::size_t(0), std::size_t(19), block.size() / 2, block.size() - 1}) {
      std::vector<std::uint8_t> cut(block.begin(), block.begin() + std::min(n, block.size()));
      Words out(raw.size());
      CHECK_FALSE(bloomref::detail::huf_decode(cut.data(), cut.size(), out.data(), out.size(), s));
    }
    // More values asked for than coded: the bits run out.
    Words more(raw.size() + 300);
    CHECK_FALSE(bloomref::detail::huf_decode(block.data(), block.size(), more.data(),
                                             more.size(), s));
    // Bytes changed at random: refused or decoded, never past the buffers (the sanitizer
    // builds run this too).
    for (int t = 0; t < 200; ++t) {
      std::vector<std::uint8_t> bad = block;
      for (int k = 0; k < 3; ++k) bad[rng() % bad.size()] ^= static_cast<std::uint8_t>(1 + rng() % 255);
      Words out(raw.size());
      (void)bloomref::detail::huf_decode(bad.data(), bad.size(), out.data(), out.size(), s);
    }
  }
}

TEST_CASE("huf_decode: tables that are no code, and a run with nothing before it",
          "[io][huffman]") {
  bloomref::detail::HufScratch s;
  Words out(4);
  const auto le32 = [](std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
  };
  // Three symbols 0..2 (2 codes runs), each given length 1: three codes of one bit do not fit.
  std::vector<std::uint8_t> b(20 + 3 + 8, 0);
  le32(b, 0, 0);
  le32(b, 4, 2);
  le32(b, 12, 16);
  // Lengths 1, 1, 1 in 6 bits each, most significant first: 000001 000001 000001.
  b[20] = 0x04;
  b[21] = 0x10;
  b[22] = 0x40;
  CHECK_FALSE(bloomref::detail::huf_decode(b.data(), b.size(), out.data(), out.size(), s));
  // Lengths 1 (value 0) and 1 (the run code 1): codes 0 and 1. The bits begin with the run.
  std::vector<std::uint8_t> r(20 + 2 + 4, 0);
  le32(r, 0, 0);
  le32(r, 4, 1);
  le32(r, 12, 9);
  r[20] = 0x04;  // 000001 00|0001 ....
  r[21] = 0x10;
  r[22] = 0x80;  // the run code (1), then 8 bits of count
  CHECK_FALSE(bloomref::detail::huf_decode(r.data(), r.size(), out.data(), out.size(), s));
  // Value 0 (code 0) first, then a run of 3: 0, 1, 00000011.
  r[22] = 0x40;  // 0 1 000000
  r[23] = 0xc0;  // 11 ......
  le32(r, 12, 10);
  Words four(4, 9);
  REQUIRE(bloomref::detail::huf_decode(r.data(), r.size(), four.data(), four.size(), s));
  CHECK(four == Words{0, 0, 0, 0});
  CHECK(openexr_decode(r, 4) == Words{0, 0, 0, 0});
  // Three values asked for: the run of 3 after the first does not fit, and nothing is written
  // past the three.
  Words three(4, 9);
  CHECK_FALSE(bloomref::detail::huf_decode(r.data(), r.size(), three.data(), 3, s));
  CHECK(three[3] == 9);
}

TEST_CASE("wavelet_decode_block gives OpenEXR's wav2Decode values, word for word",
          "[io][huffman]") {
  std::mt19937 rng(5);
  int cases = 0;
  for (const int words : {1, 2})
    for (const int nx : {1, 2, 3, 4, 5, 7, 8, 9, 16, 33, 100, 1920})
      for (const int ny : {1, 2, 3, 5, 8, 24, 32})
        for (const std::uint16_t max : {std::uint16_t(200), std::uint16_t(16383),
                                        std::uint16_t(16384), std::uint16_t(65535)}) {
          INFO(words << " words, " << nx << "x" << ny << ", max " << max);
          Words block(std::size_t(words) * nx * ny);
          for (auto& v : block) v = static_cast<std::uint16_t>(rng() % (std::uint32_t(max) + 1));
          Words want = block;
          for (int j = 0; j < words; ++j)
            Imf::wav2Decode(want.data() + j, nx, words, ny, nx * words, max);
          bloomref::detail::wavelet_decode_block(block.data(), nx, words, ny, max);
          CHECK(block == want);
          ++cases;
        }
  CHECK(cases == 2 * 12 * 7 * 4);
}
