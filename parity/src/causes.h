// The cause hypotheses of a failing stage (internal to parity; compare.h, CauseFit).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "bloomref/half.h"
#include "bloomref/parity/compare.h"
#include "bloomref/plan.h"

namespace bloomref::parity::detail {

struct CauseContext {
  const Plan& plan;
  ConstImageView sanitized;  ///< the scene after the non-finite policy, unrounded
  const DeviceProfile& profile;
  HalfRounding rounding;     ///< how the oracle stores f16
  int threads;
  /// A stage as the isolated oracle reads it: the capture, or the oracle's recomputation.
  std::function<ConstImageView(const std::string&)> view;
  std::function<bool(const std::string&)> captured;
  /// The target stage's bound, value by value (a storage hypothesis rounds the oracle's value
  /// give or take it: any value of that range may be the one the device rounded).
  const Image* target_bound = nullptr;
  /// The likely cause named at the last failing stage of the target's kind before it, and
  /// that stage: tried alone first (the same bug at every pass costs one hypothesis a pass).
  std::string prior, prior_stage;
  /// Find the fitted parameter's interval of the likely cause (CauseFit::low, high).
  bool interval = false;
};

/// A failing stage's residual (capture - isolated oracle) in words, for a failure no cause
/// explains: its total against the oracle's, where the values out of bound lie (near the
/// edges, on the lit texels, in the dark), and the first-order change it resembles most.
std::string describe_residual(const CauseContext& ctx, const StageSpec& target);

/// Recomputes `target` once per hypothesis (the oracle with one change, from the same captures)
/// and scores each with `within` (which may adjust the image, e.g. clamp it as an 8-bit capture
/// was, and returns the fraction of values within the stage's bound widened by the absolute
/// amount it is given: a hypothesis that samples at other positions than the oracle's carries
/// its own coordinates' float error, which the stage's bound does not hold where the oracle's
/// neighbourhood is dark). Returns the hypotheses
/// that score above `oracle_within`, best first (ties: the simpler, listed first).
std::vector<CauseFit> test_causes(const CauseContext& ctx, const StageSpec& target,
                                  double oracle_within,
                                  const std::function<double(Image&, double)>& within);

}  // namespace bloomref::parity::detail
