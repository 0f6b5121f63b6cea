// The files of data/ (data/README.md): the corpus checksums, and small scenes whose stages were
// derived by hand.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "test_util.h"

using namespace bloomref;

namespace {

// SHA-256 as FIPS 180-4 specifies it (section 6.2), kept here so that the check does not rest on
// a library the project does not otherwise use; checked below against the standard's examples.
class Sha256 {
 public:
  void add(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    length_ += n;
    for (std::size_t i = 0; i < n; ++i) {
      block_[fill_++] = p[i];
      if (fill_ == 64) compress();
    }
  }
  std::string hex() {
    const std::uint64_t bits = length_ * 8;
    const unsigned char one = 0x80, zero = 0;
    add(&one, 1);
    while (fill_ != 56) add(&zero, 1);
    for (int i = 7; i >= 0; --i) {
      const unsigned char b = static_cast<unsigned char>(bits >> (8 * i));
      add(&b, 1);
    }
    std::ostringstream s;
    for (std::uint32_t v : h_) s << std::hex << std::setw(8) << std::setfill('0') << v;
    return s.str();
  }

 private:
  static std::uint32_t rotr(std::uint32_t x, int n) { return (x >> n) | (x << (32 - n)); }
  void compress() {
    static const std::uint32_t k[64] = {
        0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4,
        0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe,
        0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f,
        0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7,
        0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc,
        0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b,
        0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116,
        0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
        0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
        0xc67178f2};
    std::uint32_t w[64];
    for (int t = 0; t < 16; ++t)
      w[t] = std::uint32_t(block_[4 * t]) << 24 | std::uint32_t(block_[4 * t + 1]) << 16 |
             std::uint32_t(block_[4 * t + 2]) << 8 | block_[4 * t + 3];
    for (int t = 16; t < 64; ++t) {
      const std::uint32_t s0 = rotr(w[t - 15], 7) ^ rotr(w[t - 15], 18) ^ (w[t - 15] >> 3);
      const std::uint32_t s1 = rotr(w[t - 2], 17) ^ rotr(w[t - 2], 19) ^ (w[t - 2] >> 10);
      w[t] = w[t - 16] + s0 + w[t - 7] + s1;
    }
    std::uint32_t a = h_[0], b = h_[1], c = h_[2], d = h_[3], e = h_[4], f = h_[5], g = h_[6],
                  h = h_[7];
    for (int t = 0; t < 64; ++t) {
      const std::uint32_t t1 =
          h + (rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25)) + ((e & f) ^ (~e & g)) + k[t] + w[t];
      const std::uint32_t t2 =
          (rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
      h = g;
      g = f;
      f = e;
      e = d + t1;
      d = c;
      c = b;
      b = a;
      a = t1 + t2;
    }
    const std::uint32_t v[8] = {a, b, c, d, e, f, g, h};
    for (int i = 0; i < 8; ++i) h_[i] += v[i];
    fill_ = 0;
  }

  std::array<std::uint32_t, 8> h_ = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                     0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
  unsigned char block_[64] = {};
  std::size_t fill_ = 0;
  std::uint64_t length_ = 0;
};

std::string sha256_of_text(const std::string& s) {
  Sha256 h;
  h.add(s.data(), s.size());
  return h.hex();
}

std::string sha256_of_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open " + path);
  Sha256 h;
  std::vector<char> buf(1 << 16);
  while (f.read(buf.data(), buf.size()) || f.gcount() > 0) h.add(buf.data(), f.gcount());
  return h.hex();
}

// data/corpus.sha256: "<64 hex digits>  <file name>" per line.
std::map<std::string, std::string> listed_checksums() {
  std::ifstream f(test::data_path("corpus.sha256"));
  REQUIRE(f);
  std::map<std::string, std::string> sums;
  std::string line;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    REQUIRE(line.size() > 66);
    REQUIRE(line.substr(64, 2) == "  ");
    sums[line.substr(66)] = line.substr(0, 64);
  }
  return sums;
}

// A scene file of data/scenes (format: data/README.md): parameters and stage images in double.
struct HandScene {
  int width = 0, height = 0;
  float threshold = 1;
  int passes = 0;
  std::vector<std::pair<std::string, std::vector<double>>> stages;  // RGBA, row-major
};

double parse_value(const std::string& s) {
  const auto slash = s.find('/');
  if (slash == std::string::npos) return std::stod(s);
  return std::stod(s.substr(0, slash)) / std::stod(s.substr(slash + 1));
}

HandScene read_scene(const std::string& name) {
  std::ifstream f(test::data_path("scenes/" + name));
  REQUIRE(f);
  HandScene sc;
  std::string line;
  while (std::getline(f, line)) {
    std::istringstream in(line);
    std::string key;
    if (!(in >> key) || key[0] == '#') continue;
    if (key == "size") in >> sc.width >> sc.height;
    else if (key == "threshold") in >> sc.threshold;
    else if (key == "passes") in >> sc.passes;
    else if (key == "stage") {
      std::string stage;
      in >> stage;
      std::vector<double> v;
      for (int y = 0; y < sc.height; ++y) {
        REQUIRE(std::getline(f, line));
        std::istringstream row(line);
        std::string px;
        for (int x = 0; x < sc.width; ++x) {
          REQUIRE(row >> px);
          std::istringstream cs(px);
          std::string c;
          for (int k = 0; k < 4; ++k) {
            REQUIRE(std::getline(cs, c, ','));
            v.push_back(parse_value(c));
          }
        }
      }
      sc.stages.emplace_back(stage, std::move(v));
    } else {
      FAIL("unknown line in " << name << ": " << line);
    }
  }
  return sc;
}

// Runs the scene at f64 precision (full plan, f32 storage) and checks every stage the file
// lists. A stored stage is its f64 value rounded once to float (2^-24 relative); a pass reads
// the rounded stage before it (its weights sum to 1, so it carries that error on) and adds f64
// rounding far below 2^-40: two passes stay within 2^-23 relative. Zeros are exact.
void check_hand_scene(const std::string& name) {
  const HandScene sc = read_scene(name);
  REQUIRE(sc.stages.size() >= 2);
  REQUIRE(sc.stages[0].first == "input");
  Image scene(sc.width, sc.height);
  for (std::size_t i = 0; i < sc.stages[0].second.size(); ++i)
    scene.values()[i] = static_cast<float>(sc.stages[0].second[i]);
  BloomParams p;
  p.precision = Precision::f64;
  p.plan = PlanMode::full;
  p.threshold = sc.threshold;
  p.passes = sc.passes;
  const StageTrace t = execute(make_plan(p, scene.cview()), scene.cview(), {true});
  for (const auto& [stage, expected] : sc.stages) {
    const StageResult* r = t.find(stage);
    INFO(name << ", stage " << stage);
    REQUIRE(r);
    REQUIRE(r->image.values().size() == expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i) {
      INFO("pixel " << i / 4 << " channel " << i % 4 << ": got " << r->image.values()[i]
                    << ", expected " << expected[i]);
      CHECK(std::fabs(r->image.values()[i] - expected[i]) <= 0x1p-23 * std::fabs(expected[i]));
    }
  }
}

}  // namespace

TEST_CASE("the SHA-256 used for the corpus gives FIPS 180-4's example digests", "[data]") {
  CHECK(sha256_of_text("abc") ==
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  CHECK(sha256_of_text("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  // Two blocks: the message fills the first past the length field.
  CHECK(sha256_of_text("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq") ==
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  CHECK(sha256_of_text(std::string(1000000, 'a')) ==
        "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST_CASE("the corpus holds exactly the images data/corpus.sha256 lists", "[data][corpus]") {
  const std::map<std::string, std::string> sums = listed_checksums();
  CHECK(sums.size() == 15);
  const std::vector<std::string> files = test::corpus_files();
  if (files.empty()) {
    WARN("BLOOMREF_CORPUS is not set: corpus checksums not checked");
    return;
  }
  std::set<std::string> present;
  for (const std::string& f : files) {
    const std::string name = std::filesystem::path(f).filename().string();
    present.insert(name);
    INFO(f);
    REQUIRE(sums.count(name) == 1);  // an image the list does not know
    CHECK(sha256_of_file(f) == sums.at(name));
  }
  for (const auto& [name, sum] : sums) {
    INFO(name << " is listed but not in " << test::corpus_dir());
    CHECK(present.count(name) == 1);
  }
}

// data/scenes/edge_texel_5x1.txt. bright: luminance 0.5 at x = 0 and 2.353 at x = 4 against the
// threshold 1 (strictly greater): only x = 4 keeps its colour (4, 2, 1); the rest (0, 0, 0), all
// alpha 1. blur.1, horizontal: r(x) = sum over i = -4..4 of w|i| B(clamp(x + i, 0, 4)) with
// w = (924, 792, 495, 220, 66) / 4070; taps at texel centres read the texel itself. Only x + i >= 4
// reads B(4) (positions past 4 clamp to it), so r(x) = (4, 2, 1) * sum_{i = 4-x}^{4} w|i|:
//   x = 0: 66                          =   66 / 4070 -> (264, 132, 66) / 4070
//   x = 1: 220 + 66                    =  286 / 4070 -> (1144, 572, 286) / 4070
//   x = 2: 495 + 220 + 66              =  781 / 4070 -> (3124, 1562, 781) / 4070
//   x = 3: 792 + 495 + 220 + 66        = 1573 / 4070 -> (6292, 3146, 1573) / 4070
//   x = 4: 924 + 792 + 495 + 220 + 66  = 2497 / 4070 -> (9988, 4994, 2497) / 4070
TEST_CASE("a bright texel at the edge: bright and one pass as derived by hand", "[data]") {
  check_hand_scene("edge_texel_5x1.txt");
}

// data/scenes/centre_texel_3x3.txt. bright: luminance 0.9 at (0, 0) is not above 1; the centre
// (2, 1, 4) with luminance 1.4292 is. blur.1, horizontal: only x + i = 1 reads the centre (a
// clamped position is 0 or 2), so row 1 is (2, 1, 4) * (792, 924, 792) / 4070 and rows 0 and 2
// stay 0. blur.2, vertical, the same along y: (2, 1, 4) * w|x-1| * w|y-1|, over 4070^2 =
// 16564900: corners 792^2 = 627264, edges 792 * 924 = 731808, centre 924^2 = 853776 (times 2, 1
// and 4 for r, g, b).
TEST_CASE("a bright centre: bright and two passes as derived by hand", "[data]") {
  check_hand_scene("centre_texel_3x3.txt");
}
