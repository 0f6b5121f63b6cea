// The machine's own thread-scaling ceilings (parallel_ceiling), which bench and opencv_peer
// report beside their two-thread figures.
#include <catch2/catch.hpp>

#include <atomic>
#include <stdexcept>
#include <vector>

#include "bloomref/parallel.h"
#include "bloomref/machine_ceiling.h"

using namespace bloomref;

// The thread wedge's reference line: both register-only ceilings (latency- and throughput-
// bound: only the second tells two hardware threads of one core from two cores) and the copy.
TEST_CASE("the machine-ceiling line reports every ceiling it measured", "[parallel]") {
  ParallelCeiling c;
  c.threads = 2;
  c.compute = 1.96;
  c.throughput = 1.03;
  c.memory = 0.84;
  c.copy_gb_per_s_one = 37.8;
  c.copy_gb_per_s_all = 32.0;
  CHECK(describe(c) ==
        "machine ceiling, 2 threads: register-only work 1.96x (latency-bound), 1.03x "
        "(throughput-bound), memory copy 0.84x (37.8 -> 32.0 GB/s)");
  // One thread against one thread: every measured ratio near 1 (medians of alternated runs).
  const ParallelCeiling one = parallel_ceiling(1, 3);
  CHECK(one.threads == 1);
  for (double r : {one.compute, one.throughput, one.memory}) {
    CHECK(r > 0.5);
    CHECK(r < 2.0);
  }
}

// parallel_rows covers [0, height) with disjoint ranges, each row once, on any thread count
// (oneTBB; under ThreadSanitizer plain threads), and hands a range's exception to the caller.
TEST_CASE("parallel_rows visits every row once and passes an exception on", "[parallel]") {
  for (int threads : {1, 2, 3, 8}) {
    for (int height : {1, 2, 7, 100, 1000}) {
      std::vector<std::atomic<int>> seen(static_cast<std::size_t>(height));
      for (auto& s : seen) s = 0;
      parallel_rows(height, threads, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) ++seen[static_cast<std::size_t>(y)];
      });
      int once = 0;
      for (auto& s : seen) once += s == 1;
      CHECK(once == height);
    }
    CHECK_THROWS_WITH(parallel_rows(100, threads,
                                    [](int y0, int y1) {
                                      if (y0 <= 50 && 50 < y1) throw std::runtime_error("row 50");
                                    }),
                      "row 50");
  }
}
