// The adaptive plan's blur in boxes (engine/boxes.h): the bright support it starts from, the
// boxes it cuts, the rest of the image, and the bits of whole runs against the full plan.
#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "bloomref/engine/boxes.h"
#include "bloomref/executor.h"
#include "bloomref/plan.h"
#include "test_util.h"

using namespace bloomref;

namespace {

std::vector<std::pair<int, int>> as_pairs(const std::vector<Span>& row) {
  std::vector<std::pair<int, int>> out;
  for (const Span& s : row) out.emplace_back(s.x0, s.x1);
  return out;
}

using Pairs = std::vector<std::pair<int, int>>;

void set(Image& img, int x, int y, float r, float g, float b) {
  float* p = img.pixel(x, y);
  p[0] = r;
  p[1] = g;
  p[2] = b;
  p[3] = 1.0f;
}

// Whether the run took the boxed path: stage bright runs inside the blur ("bright+blur...")
// and the passes left texels out (the dense fused path records 0 for every pass).
bool ran_boxed(const StageTrace& t) {
  bool named = false, skipped = false;
  for (const auto& [name, ms] : t.timings) named |= name.rfind("bright+blur.1-", 0) == 0;
  for (const auto& [name, f] : t.skipped_fraction) skipped |= name == "blur.1" && f > 0.0;
  return named && skipped;
}

}  // namespace

TEST_CASE("bright_support_spans: extract_bright's test, then RGB not +0", "[boxes]") {
  // Row 0: x 1-2 bright (2, 2, 2); x 3 at the threshold (luminance 1, a tie: not bright);
  // x 4 (-0, 3, 0), luminance 2.1456: bright, in the support; x 5 bright again.
  // Row 1: threshold -1 below makes (0, 0, 0) bright, but its RGB is +0: not in the support;
  // (-0, 0, 0) is. Row 2 holds a bright pixel but its bright_rows entry is 0: not read.
  Image img(8, 3, 0.0f);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 8; ++x) img.pixel(x, y)[3] = 1.0f;
  set(img, 1, 0, 2, 2, 2);
  set(img, 2, 0, 2, 2, 2);
  set(img, 3, 0, 1, 1, 1);
  set(img, 4, 0, -0.0f, 3, 0);
  set(img, 5, 0, 2, 2, 2);
  set(img, 6, 2, 9, 9, 9);
  const std::uint8_t rows[3] = {1, 1, 0};
  RowSpans s;
  CHECK(bright_support_spans(img.cview(), 1.0f, rows, s, 1) == 4u);
  REQUIRE(s.size() == 3u);
  CHECK(as_pairs(s[0]) == Pairs{{1, 3}, {4, 6}});
  CHECK(s[1].empty());
  CHECK(s[2].empty());

  Image neg(4, 1, 0.0f);
  set(neg, 0, 0, 0, 0, 0);
  set(neg, 1, 0, -0.0f, 0, 0);
  set(neg, 2, 0, 0, 0, 0);
  set(neg, 3, 0, 0, 0, -0.0f);
  CHECK(bright_support_spans(neg.cview(), -1.0f, nullptr, s, 2) == 2u);
  CHECK(as_pairs(s[0]) == Pairs{{1, 2}, {3, 4}});
}

TEST_CASE("outside_boxes is the complement of the boxes, row by row", "[boxes]") {
  const RowSpans r = outside_boxes({{2, 1, 5, 3}, {7, 0, 9, 2}}, 10, 4);
  REQUIRE(r.size() == 4u);
  CHECK(as_pairs(r[0]) == Pairs{{0, 7}, {9, 10}});
  CHECK(as_pairs(r[1]) == Pairs{{0, 2}, {5, 7}, {9, 10}});
  CHECK(as_pairs(r[2]) == Pairs{{0, 2}, {5, 10}});
  CHECK(as_pairs(r[3]) == Pairs{{0, 10}});
}

TEST_CASE("boxes: far clusters apart, near ones together, every support inside", "[boxes]") {
  // 10 passes of discrete9: a pass's lookups reach at most 5 texels (offset 4, and the next
  // texel of a bilinear pair), so five horizontal passes spread a pixel at most 25 texels each
  // way; a tile (8 texels along), its footprint's reach (5) and the 16-texel cells add under 50
  // more. Pixels 180 texels apart keep their own box; 20 apart share one.
  const std::vector<Axis> axes = {
      Axis::horizontal, Axis::vertical,   Axis::horizontal, Axis::vertical,   Axis::horizontal,
      Axis::vertical,   Axis::horizontal, Axis::vertical,   Axis::horizontal, Axis::vertical};
  auto layout = [&](std::vector<int> xs) {
    RowSpans bright(60);
    for (int x : xs) bright[30].push_back({x, x + 1});
    return BoxedBlur(240, 60, bright, axes, kernel_discrete9(), 0, 1.0, 1);
  };
  const BoxedBlur far = layout({20, 200});
  REQUIRE(far.ok());
  REQUIRE(far.boxes().size() == 2u);
  auto holds = [](const Box& b, int x, int y) {
    return x >= b.x0 && x < b.x1 && y >= b.y0 && y < b.y1;
  };
  const Box& a = far.boxes()[0].x0 < far.boxes()[1].x0 ? far.boxes()[0] : far.boxes()[1];
  const Box& b = far.boxes()[0].x0 < far.boxes()[1].x0 ? far.boxes()[1] : far.boxes()[0];
  CHECK(holds(a, 20, 30));
  CHECK(holds(b, 200, 30));
  CHECK(a.x1 <= b.x0);
  // Every pass's support lies in a box.
  for (int k = 0; k <= 10; ++k)
    for (int y = 0; y < 60; ++y)
      for (const Span& s : far.support(k)[std::size_t(y)]) {
        INFO("pass " << k << " row " << y << " [" << s.x0 << ", " << s.x1 << ")");
        CHECK((holds(a, s.x0, y) && holds(a, s.x1 - 1, y) ||
               holds(b, s.x0, y) && holds(b, s.x1 - 1, y)));
      }
  CHECK(far.support_count(0) == 2u);
  CHECK(far.support_count(10) > far.support_count(1));

  const BoxedBlur near = layout({20, 40});
  REQUIRE(near.ok());
  CHECK(near.boxes().size() == 1u);
  // The boxes may cover at most max_fraction of the image.
  RowSpans bright(60);
  bright[30].push_back({20, 21});
  CHECK_FALSE(BoxedBlur(240, 60, bright, axes, kernel_discrete9(), 0, 0.01, 1).ok());
}

TEST_CASE("the adaptive plan's boxed blur gives the full plan's bits", "[boxes][determinism]") {
  // Clusters at the corners and edges (clamp-to-edge), near each other (merged boxes), one large
  // enough to run alone on the threads, negative and -0 values, odd sizes; both kernels, float
  // and 8-bit bilinear weights, odd and even pass counts (the last pass in either buffer).
  auto scene = [](int w, int h, bool big, float base) {
    Image img(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        set(img, x, y, base * float((x * 7 + y * 3) % 11), base * 0.5f,
            base * float(y % 5) * 0.25f);
    const int at[][2] = {{0, 0},
                         {w - 1, 0},
                         {0, h - 1},
                         {w - 1, h - 1},
                         {w / 2, 0},
                         {w / 3, h / 2},
                         {w / 3 + 9, h / 2 + 4},
                         {w - 1, h / 3}};
    for (const auto& p : at) set(img, p[0], p[1], 40.0f, 20.0f, -0.5f);
    set(img, w / 2, h - 1, 3.0f, -0.0f, 0.0f);
    if (big)
      for (int y = h / 4; y < h / 4 + 40; ++y)
        for (int x = w / 2; x < w / 2 + 40; ++x) set(img, x, y, 5.0f, 2.0f, 1.0f);
    return img;
  };
  // 400x400: 160,000 pixels, most outside the support, of binary16 values (base a power of two
  // over 64): the finishing stages take them from the table of finished binary16 values.
  const std::vector<std::pair<std::string, Image>> scenes = {
      {"617x411 stars", scene(617, 411, false, 0.01f)},
      {"400x400 halves", scene(400, 400, false, 1.0f / 64)},
      {"523x419 big cluster", scene(523, 419, true, 0.02f)},
  };
  int boxed = 0;
  for (const auto& [name, img] : scenes)
    for (KernelName kernel : {KernelName::discrete9, KernelName::linear5})
      for (int bits : {0, 8})
        for (int passes : {1, 2, 3, 10})
          for (int threads : {1, 2}) {
            BloomParams p;
            p.kernel = kernel;
            p.subtexel_bits = bits;
            p.passes = passes;
            p.threads = threads;
            p.plan = PlanMode::full;
            const Image full = test::run_output(img, p);
            p.plan = PlanMode::adaptive;
            const StageTrace t = execute(make_plan(p, img.cview()), img.cview());
            INFO(name << ", " << to_string(kernel) << ", subtexel bits " << bits << ", passes "
                      << passes << ", threads " << threads);
            CHECK(test::bit_identical(full.cview(), t.final_image().cview()));
            boxed += ran_boxed(t);
          }
  CHECK(boxed == 3 * 2 * 2 * 4 * 2);  // every run took the boxed path
}
