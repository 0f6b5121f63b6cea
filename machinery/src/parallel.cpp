#include "bloomref/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

// ThreadSanitizer: GCC defines __SANITIZE_THREAD__, Clang answers __has_feature.
#if defined(__SANITIZE_THREAD__)
#define BLOOMREF_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define BLOOMREF_TSAN 1
#endif
#endif

namespace bloomref {

int resolve_threads(int threads) {
  return threads > 0 ? threads : tbb::info::default_concurrency();
}

namespace {

// One arena per thread count, made on first use and kept: an arena made per call costs its
// set-up and the workers' migration into it on every parallel loop, which the adaptive plan's
// small passes (three loops each) feel most (docs/design.md, "One row-parallel function is the
// only code that talks to oneTBB"). Never destroyed: an arena outliving the library's shutdown
// at exit is harmless, one destroyed after it is not. The map that holds them is never
// destroyed either, so that they stay reachable to the end (a static map was destroyed at
// exit, leaving the arenas unreachable: LeakSanitizer reported each).
tbb::task_arena& arena_for(int n) {
  static std::mutex mutex;
  static auto* const arenas = new std::map<int, std::unique_ptr<tbb::task_arena>>();
  std::lock_guard<std::mutex> lock(mutex);
  std::unique_ptr<tbb::task_arena>& a = (*arenas)[n];
  if (!a) {
    a = std::make_unique<tbb::task_arena>(n);
    a->initialize();
  }
  return *a;
}

#if defined(BLOOMREF_TSAN)
// Under ThreadSanitizer: plain threads, whose start, join and the counter's atomics it sees.
// oneTBB's library is not instrumented, so the hand-over of a range to one of its workers
// would look like a race on everything the range reads. The ranges are the same; an exception
// of any range is rethrown here, as oneTBB does.
void threads_over(int height, int n, int grain, const std::function<void(int, int)>& fn) {
  const int ranges = (height + grain - 1) / grain;
  std::atomic<int> next{0};
  std::mutex mutex;
  std::exception_ptr failed;
  const auto work = [&] {
    try {
      for (int r = next++; r < ranges; r = next++) fn(r * grain, std::min(height, (r + 1) * grain));
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!failed) failed = std::current_exception();
    }
  };
  std::vector<std::thread> helpers;
  for (int i = 1; i < std::min(n, ranges); ++i) helpers.emplace_back(work);
  work();
  for (std::thread& t : helpers) t.join();
  if (failed) std::rethrow_exception(failed);
}
#endif

}  // namespace

void parallel_rows(int height, int threads, const std::function<void(int, int)>& fn) {
  if (height <= 0) return;
  const int n = resolve_threads(threads);
  if (n == 1 || height == 1) {
    fn(0, height);
    return;
  }
  // Grain of a few rows: enough ranges to balance, few enough that a range's setup is noise.
  const int grain = std::max(1, height / (8 * n));
#if defined(BLOOMREF_TSAN)
  return threads_over(height, n, grain, fn);
#endif
  arena_for(n).execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, height, grain),
                      [&](const tbb::blocked_range<int>& r) { fn(r.begin(), r.end()); });
  });
}

ThreadsStarting::ThreadsStarting(int threads) {
  if (resolve_threads(threads) > 1)
    starter_ = std::thread([threads] { parallel_rows(64, threads, [](int, int) {}); });
}

ThreadsStarting::~ThreadsStarting() {
  if (starter_.joinable()) starter_.join();
}

}  // namespace bloomref
