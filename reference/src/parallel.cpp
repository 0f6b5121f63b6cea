#include "bloomref/parallel.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace bloomref {

int resolve_threads(int threads) {
  return threads > 0 ? threads : tbb::info::default_concurrency();
}

namespace {

// One arena per thread count, made on first use and kept: creating an arena per call (as this
// file did) cost its set-up and the workers' migration into it on every parallel loop, which
// the adaptive plan's small passes (three loops each) felt most: at 256x256 its blur took 5.0 ms
// on two threads against 2.9 ms on one (bench, medians of 21). Never destroyed: an arena
// outliving the library's shutdown at exit is harmless, one destroyed after it is not. The map
// that holds them is never destroyed either, so that they stay reachable to the end (a static
// map was destroyed at exit, leaving the arenas unreachable: LeakSanitizer reported each).
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
