// bloomref — how much memory a run needs, said before it starts, and how much it may take.
//
// A run holds a few whole images at once (the scene, the blur's ping-pong pair, the groups of
// the fused blur, every stage when they are kept), so its memory follows the image's size and,
// with every stage kept, the stage count; never the pass count otherwise. `working_set` bounds
// it from above; a command refuses (exit 2) an image whose bound exceeds its budget instead of
// running out of memory part way (exit 4, or the kernel's OOM killer).
#pragma once

#include <cstdint>
#include <string>

#include "bloomref/params.h"

namespace bloomref {

struct WorkingSet {
  std::uint64_t bytes = 0;        ///< the bound: fixed + images * image_bytes + extra
  double images = 0;              ///< whole images held at once, at most
  std::uint64_t image_bytes = 0;  ///< one image in the run's precision
};

/// The most a run of `params` over a width x height image holds at once: the loaded input
/// (float RGBA), the executor's images (4 in the run's precision: scene, bright, blur ping and
/// pong, or the mip chain with its bloom; 2 more float ones for a fused blur of more than 15
/// passes), or with `kept_traces` > 0 that many images per stage instead (1: --dump-stages; 3:
/// compare, which holds GL's trace, the oracle's and the GL driver's textures), the 8-bit PNG
/// output buffer, and 64 MiB for the program, its tables and threads (128 MiB with `gl`: the
/// driver). Measured peaks lie below it (tests/cli/test_memory.cpp).
WorkingSet working_set(const BloomParams& params, int width, int height, int kept_traces = 0,
                       bool gl = false);

/// The memory this process may use: physical memory or, where lower, the control group's limit
/// (cgroup v2 memory.max, v1 memory.limit_in_bytes).
std::uint64_t available_memory_bytes();

/// The default budget: 80% of available_memory_bytes() (the rest for the system, the page
/// cache and the output's writing).
std::uint64_t default_memory_budget();

/// This process's peak resident memory since it started its program: VmHWM of
/// /proc/self/status (getrusage's ru_maxrss where there is none). ru_maxrss also counts the
/// process it was forked from as it was before the exec: a bloomref started by a test binary
/// holding 135 MB reported 135 MB for any run.
std::uint64_t peak_rss_bytes();

/// "123", "512K", "64M", "8G", "1.5T" (powers of 1024, case-insensitive, an optional "B" or
/// "iB") -> bytes; ParamError naming `option` otherwise.
std::uint64_t parse_byte_size(const std::string& text, const std::string& option);
/// Bytes as "1.5 GiB", "64 MiB".
std::string byte_size_text(std::uint64_t bytes);

}  // namespace bloomref
