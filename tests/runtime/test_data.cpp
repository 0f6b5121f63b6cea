// The files of data/ (data/README.md): small scenes whose stages were derived by hand (the
// corpus checksums: test_corpus_checksums.py).
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "bloomref/executor.h"
#include "test_util.h"

using namespace bloomref;

namespace {

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
