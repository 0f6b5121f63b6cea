// bloomref parity — two traces in, a verdict out.
//
// Stage isolation: each captured stage is judged against the CPU stage recomputed (f32, the
// shaders' order) from the capture of the stage before it, so an error is charged to the stage
// that made it. The captures may be any subset of the plan's stages (a GL trace holds them all;
// a user's dump may hold only `output`): a stage with no capture is recomputed by the oracle from
// the last captures before it (or the scene), and its own bound is carried into the bounds of
// the stages that read it. End to end: each captured stage against the CPU's full run, with
// bounds propagated through the pipeline (the blur of the previous bound, the tone map's and
// gamma's slopes).
//
// Per value the bound is the sum of named terms (tolerance.cpp says how each is derived).
// PASS: every value within its bound. WARN: some values over it but none beyond 4x (the looser
// quality tier; the reason says how many and by how much). FAIL: beyond 4x, or a NaN/Inf where
// the other side has none, or (isolated stages) an image gate of the profile exceeded: the
// mean excess error, the worst window's, or the fraction of values over bound.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
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

/// A one-change variant of the oracle that explains a failing stage (causes.cpp): the stage
/// recomputed with that change, judged against the same bound.
struct CauseFit {
  std::string id;           ///< stable name: "flipped-vertically", "rb-swapped", ...
  std::string description;  ///< in words, e.g. "image flipped vertically (bottom row first)"
  std::string detail;       ///< what was fitted or changed, e.g. the fitted kernel weights
  /// Fraction of values within bound under this hypothesis (the stage's bound plus the
  /// hypothesis's own rounding: captured.cpp says how much).
  double within = 0;
  double oracle_within = 0;  ///< the same measure of the oracle as specified
  /// Parameters fitted to the capture (0 for a fixed change such as a flip, 1 for a fitted
  /// spacing or gain, 5 for discrete9's weights): causes are ranked by the fraction within
  /// bound less 0.2% per parameter, so that a flexible fit loses to a simpler cause that
  /// explains about as much.
  int params = 0;
  /// Whether it explains the failure (a "likely cause"): at most 0.1% of all values left out of
  /// bound, and at most a tenth of those the oracle as specified leaves out. Otherwise it is a
  /// partial explanation (test_causes keeps none that brings in less than a tenth of them).
  bool likely() const { return within >= 0.999 && 1 - within <= 0.1 * (1 - oracle_within); }
  /// Not the first cause, but one the captures cannot tell from it: likely too, a different
  /// id, within 0.05% of the values of what the first explains, and no more than one fitted
  /// parameter more flexible (five fitted weights describe any kernel: they never are).
  bool as_likely = false;
  /// A likely cause with one fitted parameter, at the first stage where causes are searched:
  /// the fitted value and the range of it that still explains the failure (likely), each end
  /// found to a sixteenth of the first step out that did not; NaN otherwise.
  double value = NAN, low = NAN, high = NAN;
};

struct StageComparison {
  std::string stage;
  Verdict verdict = Verdict::pass;
  std::string reason;
  std::uint64_t values = 0;              ///< RGB values compared
  std::uint64_t over_bound = 0;          ///< values with error > bound
  std::uint64_t beyond_tier = 0;         ///< values with error > 4x bound (FAIL)
  std::uint64_t nonfinite_mismatch = 0;  ///< NaN/Inf on one side only
  double max_abs = 0, max_rel = 0;       ///< largest |gl - oracle|, and relative to |oracle|
  double max_ulp16 = 0;                  ///< largest error in f16 ULPs of the oracle
  double max_ratio = 0;                  ///< largest error / bound (the bound's tightness)
  std::vector<WorstValue> worst;         ///< the largest error / bound, with bound terms
  /// Signed f16-ULP differences (gl - oracle): bins -8..+8, [0] and [16] also hold the tails.
  std::vector<std::uint64_t> ulp_histogram;
  /// Image gates (profile.h, ImageGates), isolated stages only: the excess error over the
  /// whole image and over its worst window (ratios to the bound beyond rounding), where that
  /// window starts, and the gate that failed ("" when none did).
  double mean_excess = 0, worst_window = 0;
  int worst_window_x = 0, worst_window_y = 0;
  std::string gate;
  std::string gate_id;  ///< the gate that failed: "mean", "window", "over-fraction", "gain",
                        ///< "tile-gain", "envelope"
  /// The gain gates (docs/check.md, "Gain gates"), per channel R, G, B: the stage's total over
  /// the oracle's (`gain`) and the most the profile lets that total differ from the oracle's, as
  /// a fraction of it (`gain_allowed`: the smaller of the two signs' budgets); `gain_ratio` is
  /// the largest total error over its budget across the channels, `tile_gain_ratio` the same
  /// over every tile of 32 columns by a band of rows (isolated comparisons), at (tile_x, tile_y).
  /// Above 1 fails.
  std::array<double, 3> gain{1, 1, 1}, gain_allowed{0, 0, 0};
  double gain_ratio = 0, tile_gain_ratio = 0;
  int tile_x = -1, tile_y = -1;
  /// The envelope gate (docs/check.md, "Envelopes"), isolated blur passes and finishing stages
  /// that have an envelope: the fraction of values beyond what any device the profile allows
  /// could write from what the stage read (`envelope_outside`), and the largest total error over
  /// the envelope's total, over the whole image and over every tile (`envelope_ratio`). -1: no
  /// envelope was made. A fraction above the profile's over_fraction, or a ratio above 1, fails.
  double envelope_outside = -1, envelope_ratio = -1;
  /// Isolated comparisons of a stage that reads stages without capture: those stages (back to
  /// the captures or the scene, in plan order), and the share of this stage's bound, summed over
  /// its finite RGB values, that is the error they may carry. An error entering at one of them
  /// is seen here only where it exceeds that carried part (docs/check.md, "Partial captures").
  std::vector<std::string> carried_from;
  double carried_share = 0;
  Image oracle, bound;                   ///< isolated comparisons, with CompareOptions::keep_images
  /// Fraction of the values within their bound (1 for PASS).
  double within() const {
    return values ? double(values - over_bound - nonfinite_mismatch) / double(values) : 1.0;
  }
  /// Fraction of the values within the WARN tier (4x their bound): those that do not fail.
  double within_tier() const {
    return values ? double(values - beyond_tier - nonfinite_mismatch) / double(values) : 1.0;
  }
  /// Isolated stages not PASS, when CompareOptions::causes: the hypotheses that bring more
  /// values within bound than the oracle as specified, best first.
  std::vector<CauseFit> causes;
  /// A failing stage no cause explains, described (CompareOptions::causes): its total against
  /// the oracle's, where its values out of bound lie, and what its residual resembles, e.g.
  /// "total 1.02x the oracle's; 92% of the values out of bound within 4 texels of an edge".
  std::string residual;
};

struct ParityResult {
  DeviceProfile profile;
  std::vector<StageComparison> isolated;
  std::vector<StageComparison> end_to_end;
  std::optional<std::string> first_divergent_stage;  ///< first isolated stage not PASS
  Verdict verdict = Verdict::pass;                    ///< worst over both lists
};

struct CompareOptions {
  bool keep_images = false;        ///< the isolated oracle and bound of each stage (the report's)
  bool keep_failing_only = false;  ///< with keep_images: only of stages that are not PASS
  int worst_count = 8;
  bool causes = false;  ///< test the usual causes on every isolated stage that is not PASS
  /// What an implementation may do that the specification allows and bloomref's own shaders
  /// avoid; each widens a bound (docs/design.md, "What a user's implementation may do").
  /// direct_exp_tonemap: the tone map computed as 1 - exp(x) directly, as the LearnOpenGL
  /// tutorial's 7.bloom_final.fs does: near 0 its error is exp's near 1, absolute, where the
  /// specification's series (stages.cpp) has a relative one. interpolated_reads: the composite's
  /// inputs read with texture() at interpolated coordinates (the tutorial's TexCoords), whose
  /// rounding blends in the neighbours, instead of texelFetch. `compare` (bloomref's own
  /// shaders) turns both off; captures and user shaders keep them on.
  bool direct_exp_tonemap = true;
  bool interpolated_reads = true;
  /// Stop after the first stage that fails (isolated or end to end): what a question "does
  /// this fail?" needs (sensitivity).
  bool stop_at_first_fail = false;
};

/// A stage image from outside the CPU oracle: a GL readback, or a user's file.
struct CapturedStage {
  ConstImageView image;
  /// 0: float values. 8: stored as 8-bit codes (PNG): each value may be half a code off, and
  /// values beyond [0, 1] were clamped, so the oracle is clamped to [0, 1] before judging.
  int code_bits = 0;
  bool srgb = false;  ///< the 8-bit codes are sRGB-encoded (a code's step measured decoded)
};
using CapturedStages = std::map<std::string, CapturedStage>;

/// `gl` and `cpu` are traces of `plan` on `scene` with every stage kept (keep_all); `cpu` is
/// the f32 CPU oracle run with the profile's sub-texel bits.
ParityResult compare(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                     const StageTrace& cpu, const DeviceProfile& profile,
                     const CompareOptions& opt = {});

/// compare's general form: `captured` holds any subset of the plan's stages (at least one;
/// ParamError for a name the plan lacks); only those are judged. `cpu` as for compare.
ParityResult compare_captured(const Plan& plan, ConstImageView scene,
                              const CapturedStages& captured, const StageTrace& cpu,
                              const DeviceProfile& profile, const CompareOptions& opt = {});

/// A captured stage the comparison owns: streamed, loaded when the comparison reaches it and
/// released once no later stage reads it.
struct OwnedCapture {
  Image image;
  int code_bits = 0;
  bool srgb = false;
};
using CaptureLoader = std::function<OwnedCapture(const std::string& stage)>;

/// compare_captured for captures loaded one by one (`load` is called once per name of
/// `captured`, in plan order), with the oracle's full run computed stage by stage beside them:
/// only the images later stages read are held (peak memory a few images, not the trace).
/// `oracle_ms` (optional) receives the oracle's time.
ParityResult compare_streamed(const Plan& plan, ConstImageView scene,
                              const std::vector<std::string>& captured, const CaptureLoader& load,
                              const DeviceProfile& profile, const CompareOptions& opt = {},
                              double* oracle_ms = nullptr);

/// A wrong bloom, planted in the oracle's run at its first stage (blur.1, or down.1): every
/// value times `amount` (gain), moved `amount` texels to the right (shift), or, for the
/// gaussian method, every pass blurred with a 9-tap Gaussian `amount` times as wide as the
/// kernel's (spread). The stages after it carry it as a real bloom's bug would.
struct PlantedChange {
  enum Kind { gain, shift, spread } kind = gain;
  double amount = 1;
  /// Where the change enters: empty for the bloom's first stage (and, for spread, every blur
  /// pass); a stage's name for that stage alone (spread: that blur pass).
  std::string stage;
};

/// What a check could have seen of an error entering at one captured stage: the smallest amount
/// of each ladder planted there (PlantedChange::stage) whose run fails, and the first stage that
/// fails it (0 and "": none of the ladder). Spread only for a blur pass of the gaussian method.
struct StageSensitivity {
  std::string stage;
  double gain = 0, shift = 0, spread = 0;
  bool spread_measured = false;
  std::string gain_stage, shift_stage, spread_stage;
};

/// What a check could have seen (sensitivity): for each kind of PlantedChange, the smallest
/// amount of its ladder whose planted run the same captures, profile and scene fail, and the
/// first stage that fails it (0 and "": none of the ladder; spread 0 for the mip method, which
/// has no blur to widen).
struct Sensitivity {
  double gain = 0, shift = 0, spread = 0;
  bool gain_at_most = false;  ///< the gain is the floor asked for, smaller ones not tried
  bool shape = false;   ///< shift measured (and spread, for the gaussian method)
  bool spread_measured = false;
  std::string gain_stage, shift_stage, spread_stage;
  /// With `per_stage`: each captured stage's, in plan order.
  std::vector<StageSensitivity> stages;
  static const std::vector<double>& gain_ladder();    ///< 1.01 ... 4
  static const std::vector<double>& shift_ladder();   ///< 1, 2, 4, 8 texels
  static const std::vector<double>& spread_ladder();  ///< 1.02 ... 1.5
};

/// Plants changes of the ladders in the oracle's run of `plan` and judges its images of the
/// `captured` stages (in plan order) as compare_streamed judges captures, stopping at the
/// first failing stage: the gain ladder from `required_gain` (the weak-verdict question) up
/// (without `shape`, a failure there ends it: gain_at_most), and with `shape`, the gains below
/// it and the shift and spread ladders too. `codes`: per stage, the capture's
/// 8-bit codes (8: linear, -8: sRGB; absent or 0: float), which the planted image is rounded
/// to. With `per_stage` (and `shape`), each ladder is also planted at each captured stage
/// alone (Sensitivity::stages). Each planted run costs up to one comparison.
Sensitivity sensitivity(const Plan& plan, ConstImageView scene,
                        const std::vector<std::string>& captured,
                        const std::map<std::string, int>& codes, const DeviceProfile& profile,
                        const CompareOptions& opt, double required_gain, bool shape,
                        bool per_stage = false);

/// The oracle's f16 rounding for a device: the mode it measured (toward zero where it allows
/// it, else nearest-even, saturating where it saturates).
HalfRounding half_rounding_for(const DeviceProfile& profile);

/// compare_with_oracle for captures; the oracle's full run is computed stage by stage beside
/// the comparison (compare_streamed), not kept whole. `cpu_ms` receives its time.
ParityResult check_with_oracle(const Plan& plan, ConstImageView scene,
                               const CapturedStages& captured, const DeviceProfile& profile,
                               const CompareOptions& opt = {}, double* cpu_ms = nullptr);

/// The plan both backends run: `params` with the profile's sub-texel bits (the oracle samples as
/// the device does) and f32 precision.
Plan plan_for_device(BloomParams params, ConstImageView scene, const DeviceProfile& profile,
                     const std::string& source = "");

/// Runs the CPU oracle for `plan` (f16 rounding as the profile measured) and compares `gl` with
/// it (check_with_oracle with every stage of `gl` captured). `cpu_ms` (optional) receives the
/// oracle's time.
ParityResult compare_with_oracle(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                                 const DeviceProfile& profile, const CompareOptions& opt = {},
                                 double* cpu_ms = nullptr);

}  // namespace bloomref::parity
