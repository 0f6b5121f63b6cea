// The one comparison of a stage (compare.cpp), shared by compare_captured and the cause
// hypotheses (internal to parity).
#pragma once

#include <string>

#include "bloomref/parity/compare.h"
#include "tolerance.h"

namespace bloomref::parity::detail {

/// Judges `gl` against `oracle` value by value with `bound` (RGB); `terms` names the terms of
/// the worst values' bounds. PASS / WARN / FAIL as compare.h says.
StageComparison judge(const std::string& stage, ConstImageView gl, ConstImageView oracle,
                      const Image& bound, const StageBounds& terms, Storage storage,
                      const DeviceProfile& p, const CompareOptions& opt, int threads);

}  // namespace bloomref::parity::detail
