// The machine's own thread-scaling ceilings (parallel_ceiling), which bench and opencv_peer
// report beside their two-thread figures.
#include <catch2/catch.hpp>

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
