// bloomref — the scan of a scene row the plan makes (runtime plan.cpp), per instruction set.
#pragma once

#include <cstdint>

#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"

namespace bloomref::detail {

/// One row of `width` RGBA floats: whether every value (alpha too) is finite and within
/// kRangeGuard (|v| <= 2^120; NaN is not), and if so, in `bright`, how many of its pixels have
/// luminance > threshold, each luminance and comparison the scalar ones (luminance(): the
/// products and sums in the same order, nothing fused). A row that is not clean leaves `bright`
/// alone: the caller counts it value by value.
using ScanKernel = bool (*)(const float* row, int width, float threshold, std::uint64_t& bright);

bool scan_row_generic(const float*, int, float, std::uint64_t&);
bool scan_row_avx2(const float*, int, float, std::uint64_t&);
bool scan_row_avx512(const float*, int, float, std::uint64_t&);

/// The kernel for `isa` (BlurIsa::best: the widest the CPU has; ParamError for one it lacks).
ScanKernel scan_kernel_for(BlurIsa isa);

}  // namespace bloomref::detail
