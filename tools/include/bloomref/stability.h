// bloomref — hostile scenes and what the pipeline guarantees on them (`bloomref stability`).
//
// Each case is an image, parameter changes and a written expectation (a closed form, a bound, or
// "no NaN from finite input") that `check` asserts on the runs it is given: the CPU f64 truth
// always, and any of CPU f32, CPU f16, GL f32, GL f16 that could run.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/params.h"

namespace bloomref {

/// One backend's run of a case.
struct StabilityRun {
  std::string backend;  ///< "cpu-f64", "cpu-f32", "cpu-f16", "gl-f32", "gl-f16"
  Plan plan;
  StageTrace trace;     ///< every stage kept
};

struct Finding {
  std::string backend;
  bool ok = true;
  std::string detail;   ///< measured values behind the verdict
};

struct StabilityCase {
  std::string name;
  std::string description;
  std::string expectation;
  std::function<Image()> make;
  std::function<void(BloomParams&)> adjust;  ///< on top of the method's defaults
  /// Checks the expectation on every run (the f64 run first). Returns one finding per run.
  std::function<std::vector<Finding>(const Image& input, const std::vector<StabilityRun>&)> check;
  bool expects_refusal = false;  ///< the plan must refuse the input (--nonfinite error)
};

/// The parameters a case runs with: the defaults, the method, the case's adjustments.
BloomParams stability_params(const StabilityCase& c, Method method);

/// Runs a case on the CPU (every stage kept), named like "cpu-f64" / "cpu-f16".
StabilityRun run_stability_cpu(const StabilityCase& c, Method method, const Image& input,
                               Precision precision, Storage storage);

/// The built-in hostile cases for a method (gaussian or mip).
std::vector<StabilityCase> stability_cases(Method method);

/// A corpus image as a case (WideColorGamut's negatives, WideFloatRange's and scale.hdr's 1.7e38,
/// AllHalfValues' every half pattern): no NaN from finite input (after the default policy),
/// output in [0, 1], f32 within 1e-4 of f64.
StabilityCase corpus_case(const std::string& path);

/// Per run and stage: NaN and Inf counts over RGB, and the first stage holding any.
struct NonFiniteSummary {
  std::uint64_t nan = 0, inf = 0;
  std::string first_stage;  ///< "" when none
};
NonFiniteSummary nonfinite_summary(const StageTrace& t);

/// Error of a run's output against the f64 truth: max abs over finite RGB values, and the
/// largest error of its bloom (blur.N or `bloom`) relative to the truth's largest bloom.
struct ErrorSummary {
  double output_max_abs = 0;
  double bloom_max_rel = 0;
};
ErrorSummary error_against(const StabilityRun& run, const StabilityRun& truth);

}  // namespace bloomref
