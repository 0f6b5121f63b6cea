// bloomref tools — the machine-ceiling probe: what `threads` threads can give on this machine
// at best, the ceiling the blur's thread scaling is judged against (bloomref bench).
#pragma once

#include <string>

namespace bloomref {

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
