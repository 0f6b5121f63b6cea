// bloomref — the one place work is handed to threads (oneTBB). Stages are serial loops over a
// row range; this helper splits [0, height) into ranges. Each output row is computed by exactly
// one call and depends only on the inputs, so results are bit-identical for any thread count.
#pragma once

#include <functional>
#include <thread>

namespace bloomref {

/// 0 -> all hardware threads; otherwise the value itself (>= 1).
int resolve_threads(int threads);

/// Calls fn(y0, y1) over disjoint half-open row ranges covering [0, height).
void parallel_rows(int height, int threads, const std::function<void(int y0, int y1)>& fn);

/// Starts parallel_rows's threads for `threads` on a thread of its own, for a caller with other
/// work to do first (a command reading its input): a fresh process's first parallel loop
/// otherwise waits for them to start (docs/design.md, "A command starts its threads while it
/// reads its input"). Waits for that thread when destroyed.
class ThreadsStarting {
 public:
  explicit ThreadsStarting(int threads);
  ~ThreadsStarting();
  ThreadsStarting(const ThreadsStarting&) = delete;
  ThreadsStarting& operator=(const ThreadsStarting&) = delete;

 private:
  std::thread starter_;
};

}  // namespace bloomref
