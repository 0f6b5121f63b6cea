// bloomref — the one place work is handed to threads (oneTBB). Stages are serial loops over a
// row range; this helper splits [0, height) into ranges. Each output row is computed by exactly
// one call and depends only on the inputs, so results are bit-identical for any thread count.
#pragma once

#include <functional>
#include <string>

namespace bloomref {

/// 0 -> all hardware threads; otherwise the value itself (>= 1).
int resolve_threads(int threads);

/// Calls fn(y0, y1) over disjoint half-open row ranges covering [0, height).
void parallel_rows(int height, int threads, const std::function<void(int y0, int y1)>& fn);

/// What `threads` threads can give on this machine at best, each a speedup over one thread with
/// the same work per thread through parallel_rows, median of `repeats` alternating measurements:
/// `compute` on work that touches no memory (8 float multiply-add chains in registers, two
/// 4-float vectors once vectorised: latency-bound, a core's vector units mostly idle),
/// `throughput` on the same kind
/// of work with enough chains to keep a core's vector units busy (as the blur's kernels do),
/// `memory` on copying 32 MiB per thread between buffers far larger than the caches. The
/// ceilings the blur's thread scaling is judged against: two vCPUs that are one physical core's
/// two hardware threads stay well below `threads` in `throughput` (not in `compute`), two that
/// share one memory channel in `memory`.
struct ParallelCeiling {
  int threads = 1;
  double compute = 0, throughput = 0, memory = 0;  ///< 0: not measured
  double copy_gb_per_s_one = 0, copy_gb_per_s_all = 0;  ///< bytes read + written per second
};
ParallelCeiling parallel_ceiling(int threads, int repeats = 5);
/// One line for the reports: "machine ceiling, N threads: register-only work ..., memory copy ...".
std::string describe(const ParallelCeiling& c);

}  // namespace bloomref
