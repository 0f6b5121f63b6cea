#include "bloomref/parallel.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace bloomref {

int resolve_threads(int threads) {
  return threads > 0 ? threads : tbb::info::default_concurrency();
}

void parallel_rows(int height, int threads, const std::function<void(int, int)>& fn) {
  if (height <= 0) return;
  const int n = resolve_threads(threads);
  if (n == 1 || height == 1) {
    fn(0, height);
    return;
  }
  // Grain of a few rows: enough ranges to balance, few enough that a range's setup is noise.
  const int grain = std::max(1, height / (8 * n));
  tbb::task_arena arena(n);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, height, grain),
                      [&](const tbb::blocked_range<int>& r) { fn(r.begin(), r.end()); });
  });
}

}  // namespace bloomref
