// The one comparison of a stage (compare.cpp), shared by compare_captured and the cause
// hypotheses' scores (internal to parity).
//
// Judging runs band by band: `judge_row` adds a row's values to the band's Tally, the bands'
// tallies are merged in row order (so every sum is the same for any thread count), and
// `conclude` turns the total into the stage's verdict. PASS / WARN / FAIL as compare.h says; the
// image gates measure the error beyond the rounding each value is allowed (the stage's rounding
// terms and a capture's codes; without them, the storage term) against the bound beyond the
// same.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "bloomref/parity/compare.h"
#include "tolerance.h"

namespace bloomref::parity::detail {

/// How a stage's values are judged.
struct JudgeRules {
  Storage storage = Storage::f32;
  const DeviceProfile* profile = nullptr;
  std::size_t worst_count = 8;  ///< the worst values kept (0: none)
  bool gates = false;           ///< add up the image gates' sums
  int window = 0;               ///< with gates: the gates' window size (0: no window gate)
  int width = 0;                ///< the stage's width
};

/// What judging adds up over a band of rows: counts, sums, maxima, the worst values, and with a
/// window gate the sums of each window of the band (its rows must start on a window boundary).
struct Tally {
  std::uint64_t values = 0, over = 0, mismatch = 0, beyond_tier = 0;
  double excess = 0, base = 0;  // the image gates' sums: ratios, and their count
  double max_abs = 0, max_rel = 0, max_ulp16 = 0, max_ratio = 0;
  std::array<std::uint64_t, 17> hist{};
  std::vector<WorstValue> worst;
  double worst_floor = 0;  // a value whose error / bound is below this cannot be among the worst
  std::vector<double> window_excess, window_count;  // per window, row-major over the band
  /// Adds a later band's tally (rows below this one's), keeping the worst `keep`.
  void merge(Tally&& band, std::size_t keep);
};

/// Judges the RGB of row y: `gl`, `oracle`, `bound` (RGBA rows of rules.width texels); with the
/// gates, `allowance` is the rounding each value is allowed (null: the storage term) and `slack`
/// (null: none) is taken off the error only.
void judge_row(const JudgeRules& rules, int y, const float* gl, const float* oracle,
               const float* bound, const float* allowance, const float* slack, Tally& t);

/// The stage's comparison from the tally of all its rows: counts, the worst values with their
/// bound's terms (from `terms`), the image gates (when given, unless `uniform`: an oracle of one
/// colour has one error, not an average), the verdict and its reason.
StageComparison conclude(const std::string& stage, Tally total, const JudgeRules& rules,
                         const StageBounds& terms, const ImageGates* gates, bool uniform);

/// Whether judge_row compares this value's error with its bound (`bound` finite, neither side
/// NaN/Inf, no f16 overflow): the values the gain gates add up.
bool judged_as_number_slow(double o, double g, Storage storage, const DeviceProfile& p, double bound);
/// What judges a value that is NaN, Inf or beyond `storage`'s range in `channel` (-1: not known)
/// on one side or both: 1 acceptable, 0 a mismatch, -1 not such a case (compare with the bound).
int special_case(double o, double g, Storage storage, const DeviceProfile& p, double bound,
                 int channel = -1);
/// The largest finite value `storage` holds in `channel`: 65504 (f16); R11G11B10's 65024 for R
/// and G (6-bit mantissas at exponent 15) and 64512 for B (5 bits), the smaller where the
/// channel is not given (-1); FLT_MAX.
inline double storage_limit(Storage storage, int channel = -1) {
  return storage == Storage::f16         ? 65504.0
         : storage == Storage::r11g11b10 ? (channel == 0 || channel == 1 ? 65024.0 : 64512.0)
                                         : 3.4028234663852886e38;
}

inline bool judged_as_number(double o, double g, Storage storage, const DeviceProfile& p,
                             double bound) {
  const double limit = storage_limit(storage);
  if (std::fabs(o) <= limit && std::fabs(g) <= limit) return bound < INFINITY;  // the usual case
  return judged_as_number_slow(o, g, storage, p, bound);
}

/// A stage whose capture is not the oracle's size: FAIL, nothing compared.
StageComparison size_fault(const std::string& stage, ConstImageView gl, ConstImageView oracle);

/// Whether every texel's RGB equals the first texel's (==: NaN never equal), with every value
/// first clamped to [0, 1] when `clamped` (an 8-bit capture's oracle, as judged).
bool uniform_rgb(ConstImageView img, bool clamped = false);

/// The band height for judging a stage: a multiple of the gates' window (when there is one).
int judge_band(int window);

/// The fraction of values of `gl` within their bound against `oracle` (what
/// StageComparison::within gives of the whole comparison, without the rest), the bound of each value being `bound`'s plus
/// `relative` x |oracle value| and `absolute` (rounded to float, then added in float).
/// `packed_slack`: with R11F_G11F_B10F storage, one quantum of the `oracle` value's own too (a
/// variant that lies a binade above the oracle the bound was made for).
double within_bound(ConstImageView gl, ConstImageView oracle, const Image& bound, double relative,
                    Storage storage, const DeviceProfile& p, int threads, double absolute = 0.0,
                    bool packed_slack = false);

}  // namespace bloomref::parity::detail
