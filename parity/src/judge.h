// The one comparison of a stage (compare.cpp), shared by compare_captured and the cause
// hypotheses (internal to parity).
#pragma once

#include <string>

#include "bloomref/parity/compare.h"
#include "tolerance.h"

namespace bloomref::parity::detail {

/// Judges `gl` against `oracle` value by value with `bound` (RGB); `terms` names the terms of
/// the worst values' bounds. PASS / WARN / FAIL as compare.h says. With `gates`, also the image
/// gates, on the error beyond the rounding allowed (`allowance`, RGB per value: the stage's
/// rounding terms and a capture's codes; without it, the storage term) against the bound beyond
/// the same; `slack` (optional) is taken off the error only (f16 roundings carried from stages
/// without capture).
StageComparison judge(const std::string& stage, ConstImageView gl, ConstImageView oracle,
                      const Image& bound, const StageBounds& terms, Storage storage,
                      const DeviceProfile& p, const CompareOptions& opt, int threads,
                      const ImageGates* gates = nullptr, const Image* allowance = nullptr,
                      const Image* slack = nullptr);

}  // namespace bloomref::parity::detail
