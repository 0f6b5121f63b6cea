// bloomref parity — two traces in, a verdict out.
//
// Stage isolation: each GL stage is judged against the CPU stage recomputed (f32, the shaders'
// order) from GL's own readback of the stage before it, so an error is charged to the stage that
// made it. End to end: each GL stage against the CPU's full run, with bounds propagated through
// the pipeline (the blur of the previous bound, the tone map's and gamma's slopes).
//
// Per value the bound is the sum of named terms (tolerance.cpp says how each is derived).
// PASS: every value within its bound. WARN: some values over it but none beyond 4x (the looser
// quality tier; the reason says how many and by how much). FAIL: beyond 4x, or a NaN/Inf where
// the other side has none.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/parity/profile.h"

namespace bloomref::parity {

enum class Verdict { pass, warn, fail };
std::string to_string(Verdict v);

struct Term {
  std::string name;
  double value = 0;
};

struct WorstValue {
  int x = 0, y = 0, channel = 0;
  double oracle = 0, gl = 0, error = 0, bound = 0;
  std::vector<Term> terms;
};

struct StageComparison {
  std::string stage;
  Verdict verdict = Verdict::pass;
  std::string reason;
  std::uint64_t values = 0;              ///< RGB values compared
  std::uint64_t over_bound = 0;          ///< values with error > bound
  std::uint64_t nonfinite_mismatch = 0;  ///< NaN/Inf on one side only
  double max_abs = 0, max_rel = 0;       ///< largest |gl - oracle|, and relative to |oracle|
  double max_ulp16 = 0;                  ///< largest error in f16 ULPs of the oracle
  double max_ratio = 0;                  ///< largest error / bound (the bound's tightness)
  std::vector<WorstValue> worst;         ///< the largest error / bound, with bound terms
  /// Signed f16-ULP differences (gl - oracle): bins -8..+8, [0] and [16] also hold the tails.
  std::vector<std::uint64_t> ulp_histogram;
  Image oracle, bound;                   ///< kept when CompareOptions::keep_images
};

struct ParityResult {
  DeviceProfile profile;
  std::vector<StageComparison> isolated;
  std::vector<StageComparison> end_to_end;
  std::optional<std::string> first_divergent_stage;  ///< first isolated stage not PASS
  Verdict verdict = Verdict::pass;                    ///< worst over both lists
};

struct CompareOptions {
  bool keep_images = false;
  int worst_count = 8;
};

/// `gl` and `cpu` are traces of `plan` on `scene` with every stage kept (keep_all); `cpu` is
/// the f32 CPU oracle run with the profile's sub-texel bits.
ParityResult compare(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                     const StageTrace& cpu, const DeviceProfile& profile,
                     const CompareOptions& opt = {});

/// The plan both backends run: `params` with the profile's sub-texel bits (the oracle samples as
/// the device does) and f32 precision.
Plan plan_for_device(BloomParams params, ConstImageView scene, const DeviceProfile& profile,
                     const std::string& source = "");

/// Runs the CPU oracle for `plan` (every stage kept, f16 rounding as the profile measured) and
/// compares `gl` with it. `cpu_ms` (optional) receives the oracle's wall time.
ParityResult compare_with_oracle(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                                 const DeviceProfile& profile, const CompareOptions& opt = {},
                                 double* cpu_ms = nullptr);

}  // namespace bloomref::parity
