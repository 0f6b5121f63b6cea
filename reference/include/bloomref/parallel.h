// bloomref — the one place work is handed to threads (oneTBB). Stages are serial loops over a
// row range; this helper splits [0, height) into ranges. Each output row is computed by exactly
// one call and depends only on the inputs, so results are bit-identical for any thread count.
#pragma once

#include <functional>

namespace bloomref {

/// 0 -> all hardware threads; otherwise the value itself (>= 1).
int resolve_threads(int threads);

/// Calls fn(y0, y1) over disjoint half-open row ranges covering [0, height).
void parallel_rows(int height, int threads, const std::function<void(int y0, int y1)>& fn);

}  // namespace bloomref
