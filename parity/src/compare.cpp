#include "bloomref/parity/compare.h"

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <tuple>

#include "bloomref/error.h"
#include "bloomref/mip.h"
#include "bloomref/parallel.h"
#include "judge.h"
#include "tolerance.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace bloomref::parity {

using namespace detail;

std::string to_string(Verdict v) {
  return v == Verdict::pass ? "PASS" : v == Verdict::warn ? "WARN" : "FAIL";
}

namespace detail {
namespace {

constexpr double kWarnTier = 4.0;  // over the derived bound but within 4x: WARN

// 1 / (one f16 ULP at v), exactly: the ULP is 2^(max(e, -14) - 10) for |v| = m 2^e
// (1 <= m < 2), 2^-24 for 0, read from the exponent bits (as ilogb gives it for every finite
// double: a subnormal double's exponent is below -14 either way). A power of two between 2^-117
// and 2^24, so multiplying by it is dividing by the ULP, exactly.
double inverse_ulp16(double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  const int e = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  const int k = (v != 0 ? std::max(e, -14) : -14) - 10;
  const std::uint64_t out = std::uint64_t(1023 - k) << 52;
  double r;
  std::memcpy(&r, &out, sizeof r);
  return r;
}

}  // namespace

int special_case(double o, double g, Storage storage, const DeviceProfile& p, double bound,
                 int channel) {
  if (std::isnan(o) || std::isnan(g)) return std::isnan(o) && std::isnan(g) ? 1 : 0;
  // Unknown channel of R11G11B10: beyond the larger limit only (R and G's).
  const double limit = storage == Storage::r11g11b10 && channel < 0
                           ? storage_limit(storage, 0)
                           : storage_limit(storage, channel);
  if (storage == Storage::f16 && std::fabs(o) > limit) {
    // Beyond half's range: Inf (nearest-even overflow) or 65504 (saturation), same sign, as
    // the profile says.
    const bool same_sign = std::signbit(o) == std::signbit(g);
    const bool ok = (p.half_overflow_inf && std::isinf(g)) ||
                    (p.half_overflow_saturate && std::fabs(g) == limit);
    return same_sign && (ok || std::fabs(g) == std::fabs(o)) ? 1 : 0;
  }
  if (storage == Storage::r11g11b10 && std::fabs(o) > limit) {
    // Beyond R11G11B10's range: its channel's largest value (llvmpipe and lavapipe saturate
    // there: AllHalfValues.exr under --preset bevy-old-school) or Inf. Within the bound of the
    // limit the device's own errors may leave it below: a number, judged by the bound
    // (scale.hdr under --preset unity-urp: 64512.004 where the device stored 63488).
    if (std::isinf(g) || std::fabs(g) == limit) return 1;
    return std::fabs(o) - bound <= limit && std::isfinite(g) ? -1 : 0;
  }
  if (std::isinf(o) || std::isinf(g)) {
    if (o == g) return 1;
    // f32 overflow on one side only, where the finite side is within its bound of FLT_MAX.
    const double finite = std::isinf(o) ? g : o;
    const bool near_max = std::fabs(finite) + bound >= FLT_MAX;
    return near_max && std::signbit(o) == std::signbit(g) ? 1 : 0;
  }
  return -1;
}

bool judged_as_number_slow(double o, double g, Storage storage, const DeviceProfile& p, double bound) {
  return bound < INFINITY && special_case(o, g, storage, p, bound) == -1;
}

namespace {

// The key the worst values are ordered by: error / bound.
double worst_key(const WorstValue& w) { return w.error / std::max(w.bound, 1e-300); }

// Orders by error / bound, largest first; position breaks ties so the list is deterministic.
bool worse(const WorstValue& a, const WorstValue& b) {
  const double ra = worst_key(a), rb = worst_key(b);
  if (ra != rb) return ra > rb;
  return std::tie(a.y, a.x, a.channel) < std::tie(b.y, b.x, b.channel);
}

void keep_worst(std::vector<WorstValue>& w, std::size_t n) {
  const std::size_t keep = std::min(n, w.size());
  std::partial_sort(w.begin(), w.begin() + keep, w.end(), worse);
  w.resize(keep);
}

// Adds a value to the band's worst values when it may be among the n worst. Past 4096 the list
// is cut to the n worst, whose smallest key then bounds what may enter (ties enter: position
// decides them).
void offer_worst(Tally& t, std::size_t n, WorstValue w) {
  if (n == 0 || worst_key(w) < t.worst_floor) return;
  t.worst.push_back(std::move(w));
  if (t.worst.size() > 4096) {
    keep_worst(t.worst, n);
    if (t.worst.size() == n) t.worst_floor = worst_key(t.worst.back());
  }
}

// One value's part in the image gates: its error beyond the rounding it is allowed (r, and the
// slack taken off the error only) over its bound beyond the same, at most 4 (beyond, the value
// fails anyway); false when nothing is left to bound. A mean of these ratios, not a ratio of
// sums: the bounds span many orders of magnitude (a light's edge against flat sky), and a ratio
// of sums would only see the largest.
inline bool gate_ratio(double err, double b, double r, double slack, double& ratio) {
  const double excess = std::max(0.0, err - r - slack);
  const double base = b - r;
  if (!(base > 0)) return false;
  ratio = std::min(excess / base, 4.0);
  return true;
}

std::string fixed3(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// The image gates of a stage (profile.h, ImageGates): the mean excess ratio, the worst window's,
// and the first gate exceeded ("" when none).
void apply_gates(StageComparison& s, const Tally& t, const ImageGates& gates, int window,
                 int width) {
  s.mean_excess = t.base > 0 ? t.excess / t.base : 0.0;  // sum / count
  if (gates.window > 0 && window > 0 && !t.window_excess.empty()) {
    // Windows with nothing to bound count as 0; ties go to the first in row order.
    const int per_row = (width + window - 1) / window;
    std::size_t best = 0;
    double worst = -1;
    for (std::size_t i = 0; i < t.window_excess.size(); ++i) {
      const double r = t.window_count[i] > 0 ? t.window_excess[i] / t.window_count[i] : 0.0;
      if (r > worst) {
        worst = r;
        best = i;
      }
    }
    s.worst_window = worst;
    s.worst_window_x = static_cast<int>(best % per_row) * window;
    s.worst_window_y = static_cast<int>(best / per_row) * window;
  }
  const double over = s.values ? double(s.over_bound) / double(s.values) : 0.0;
  if (gates.mean > 0 && s.mean_excess > gates.mean)
    s.gate_id = "mean", s.gate = "the mean error is " + fixed3(s.mean_excess) + " of the bound beyond rounding (gate " +
             fixed3(gates.mean) + ")";
  else if (gates.window > 0 && s.worst_window > gates.window)
    s.gate_id = "window", s.gate = "the " + std::to_string(gates.window_size) + "x" + std::to_string(gates.window_size) +
             " window at (" + std::to_string(s.worst_window_x) + ", " +
             std::to_string(s.worst_window_y) + ") has a mean error of " + fixed3(s.worst_window) +
             " of its bound beyond rounding (gate " + fixed3(gates.window) + ")";
  else if (gates.over_fraction > 0 && over > gates.over_fraction)
    s.gate_id = "over-fraction", s.gate = fixed3(100 * over) + "% of the values exceed their bound (gate " +
             fixed3(100 * gates.over_fraction) + "%)";
}

// The verdict and its reason from the counts and the gate.
void decide(StageComparison& s) {
  if (s.nonfinite_mismatch > 0 || s.beyond_tier > 0) {
    s.verdict = Verdict::fail;
    // Where the worst value's bound is all but 0 (a denormal floor: the oracle's value is
    // exact there), a ratio such as 1e+35x says nothing: the values are said instead.
    std::string worst = "worst " + fixed3(s.max_ratio) + "x";
    if (!s.worst.empty() && !(s.worst.front().bound >= 1e-20)) {
      const WorstValue& w = s.worst.front();
      char b[200];
      std::snprintf(b, sizeof b, "worst at (%d, %d) %c: oracle %.6g, capture %.6g, where it allows no error",
                    w.x, w.y, "RGBA"[w.channel & 3], w.oracle, w.gl);
      worst = b;
    }
    s.reason = s.nonfinite_mismatch > 0
                   ? std::to_string(s.nonfinite_mismatch) + " values are NaN/Inf on one side only"
                   : std::to_string(s.beyond_tier) + " values exceed " +
                         std::to_string(static_cast<int>(kWarnTier)) + "x their derived bound (" +
                         worst + ")";
  } else if (!s.gate.empty()) {
    s.verdict = Verdict::fail;
    s.reason = "image gate: " + s.gate;
  } else if (s.over_bound > 0) {
    s.verdict = Verdict::warn;
    s.reason = std::to_string(s.over_bound) + " values exceed their derived bound, by at most " +
               fixed3(s.max_ratio) + "x (within the 4x quality tier)";
  } else {
    s.reason = "every value within its bound (largest error / bound " + fixed3(s.max_ratio) + ")";
  }
}

// Whether texels [x0, x1) of a row have the oracle's RGB values (== : -0 and +0 too), finite and
// at most `limit` in magnitude (f16: within half's range), with finite bounds: values judge_row
// would only count (an error of 0, neither special nor unbounded).
bool same_values(const float* gl, const float* oracle, const float* bound, int x0, int x1,
                 float limit) {
  std::size_t i = std::size_t(x0) * kChannels;
  const std::size_t end = std::size_t(x1) * kChannels;
#if defined(__SSE2__)
  // A texel at a time: its four lanes compared at once, alpha's result dropped.
  const __m128 lim = _mm_set1_ps(limit), inf = _mm_set1_ps(INFINITY);
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  __m128 ok = _mm_castsi128_ps(_mm_set1_epi32(-1));
  for (; i < end; i += kChannels) {
    const __m128 o = _mm_loadu_ps(oracle + i);
    const __m128 same = _mm_cmpeq_ps(_mm_loadu_ps(gl + i), o);
    const __m128 small = _mm_cmple_ps(_mm_and_ps(o, abs_mask), lim);
    const __m128 bounded = _mm_cmplt_ps(_mm_loadu_ps(bound + i), inf);
    ok = _mm_and_ps(ok, _mm_and_ps(same, _mm_and_ps(small, bounded)));
  }
  return (_mm_movemask_ps(ok) & 0x7) == 0x7;
#else
  bool ok = true;
  for (; i < end; i += kChannels)
    for (int c = 0; c < 3; ++c)  // alpha is not judged
      ok &= (gl[i + c] == oracle[i + c]) & (std::fabs(oracle[i + c]) <= limit) &
            (bound[i + c] < INFINITY);
  return ok;
#endif
}

// How many RGB values of texels [x0, x1) have a bound beyond their rounding allowance (the
// storage term where `allowance` is null): double(b) - double(r) > 0, which for floats is b > r.
std::uint64_t beyond_rounding(const float* oracle, const float* bound, const float* allowance,
                              int x0, int x1, Storage storage, const DeviceProfile& p) {
  std::uint32_t n = 0;
  const std::size_t i0 = std::size_t(x0) * kChannels, i1 = std::size_t(x1) * kChannels;
  if (allowance) {
    for (std::size_t i = i0; i < i1; i += kChannels)
      n += (bound[i] > allowance[i]) + (bound[i + 1] > allowance[i + 1]) +
           (bound[i + 2] > allowance[i + 2]);
    return n;
  }
  if (storage == Storage::f32) {  // a storage term of 0
    for (std::size_t i = i0; i < i1; i += kChannels)
      n += (bound[i] > 0.0f) + (bound[i + 1] > 0.0f) + (bound[i + 2] > 0.0f);
    return n;
  }
  for (std::size_t i = i0; i < i1; ++i)
    if (i % kChannels != 3) n += double(bound[i]) - storage_term(oracle[i], storage, p, int(i % kChannels)) > 0;
  return n;
}

}  // namespace

StageComparison size_fault(const std::string& stage, ConstImageView gl, ConstImageView oracle) {
  StageComparison s;
  s.stage = stage;
  s.verdict = Verdict::fail;
  s.ulp_histogram.assign(17, 0);
  s.max_ratio = INFINITY;
  s.reason = "the GL image is " + std::to_string(gl.width) + "x" + std::to_string(gl.height) +
             ", the oracle's is " + std::to_string(oracle.width) + "x" +
             std::to_string(oracle.height);
  return s;
}

void Tally::merge(Tally&& band, std::size_t keep) {
  values += band.values;
  over += band.over;
  mismatch += band.mismatch;
  beyond_tier += band.beyond_tier;
  excess += band.excess;
  base += band.base;
  max_abs = std::max(max_abs, band.max_abs);
  max_rel = std::max(max_rel, band.max_rel);
  max_ulp16 = std::max(max_ulp16, band.max_ulp16);
  max_ratio = std::max(max_ratio, band.max_ratio);
  for (std::size_t i = 0; i < hist.size(); ++i) hist[i] += band.hist[i];
  worst.insert(worst.end(), std::make_move_iterator(band.worst.begin()),
               std::make_move_iterator(band.worst.end()));
  keep_worst(worst, keep);
  window_excess.insert(window_excess.end(), band.window_excess.begin(), band.window_excess.end());
  window_count.insert(window_count.end(), band.window_count.begin(), band.window_count.end());
}

void judge_row(const JudgeRules& rules, int y, const float* gl, const float* oracle,
               const float* bound, const float* allowance, const float* slack, Tally& t) {
  const DeviceProfile& p = *rules.profile;
  const int n = rules.gates && rules.window > 0 ? rules.window : rules.width;
  const bool windows = rules.gates && rules.window > 0;
  const std::size_t per_row = std::size_t(rules.width + n - 1) / n;
  if (windows && y % n == 0) {  // a new row of windows
    t.window_excess.resize(t.window_excess.size() + per_row, 0.0);
    t.window_count.resize(t.window_count.size() + per_row, 0.0);
  }
  double* w_excess = windows ? t.window_excess.data() + t.window_excess.size() - per_row : nullptr;
  double* w_count = windows ? t.window_count.data() + t.window_count.size() - per_row : nullptr;
  // Window by window along the row (chunks of 16 texels when there are none), texel by texel;
  // a chunk whose values all equal the oracle's, finite, within a finite bound, only counts.
  const int chunk = windows ? n : 16;
  const float limit = static_cast<float>(storage_limit(rules.storage));
  for (int x0 = 0, wi = 0; x0 < rules.width; x0 += chunk, ++wi) {
    const int x1 = std::min(rules.width, x0 + chunk);
    if (same_values(gl, oracle, bound, x0, x1, limit)) {
      const std::uint64_t m = 3 * std::uint64_t(x1 - x0);
      t.values += m;
      t.hist[8] += m;
      if (!rules.gates) continue;
      // No error: no excess, a ratio of +0 wherever there is a bound beyond rounding.
      const double count =
          double(beyond_rounding(oracle, bound, allowance, x0, x1, rules.storage, p));
      t.base += count;
      if (windows) w_count[wi] += count;
      continue;
    }
    for (int x = x0; x < x1; ++x)
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = std::size_t(x) * kChannels + c;
        const double o = oracle[i], g = gl[i], b = bound[i];
        ++t.values;
        // An infinite (or NaN, from non-finite data) bound: unpinned by GL (NaN/Inf in the
        // footprint, max(NaN, 0)); where NaN/Inf appear is still compared through the stages.
        if (!(b < INFINITY)) continue;
        const int special = special_case(o, g, rules.storage, p, b, c);
        if (special == 0) {
          ++t.mismatch;
          offer_worst(t, rules.worst_count, {x, y, c, o, g, INFINITY, b, {}});
          continue;
        }
        if (special == 1) continue;
        const double err = std::fabs(g - o);
        double gate = 0;
        if (rules.gates) {
          const double r = allowance ? allowance[i] : storage_term(o, rules.storage, p, c);
          if (err == 0 ? b - r > 0 : gate_ratio(err, b, r, slack ? slack[i] : 0.0f, gate)) {
            t.excess += gate;
            t.base += 1;
            if (windows) {
              w_excess[wi] += gate;
              w_count[wi] += 1;
            }
          }
        }
        if (err == 0) {
          t.hist[8]++;
          continue;
        }
        t.max_abs = std::max(t.max_abs, err);
        if (o != 0) t.max_rel = std::max(t.max_rel, err / std::fabs(o));
        const double ulps = (g - o) * inverse_ulp16(o);  // a power of two: exact
        t.max_ulp16 = std::max(t.max_ulp16, std::fabs(ulps));
        t.hist[static_cast<int>(std::clamp(std::round(ulps), -8.0, 8.0)) + 8]++;
        const double ratio = b > 0 ? err / b : INFINITY;
        t.max_ratio = std::max(t.max_ratio, ratio);
        if (ratio > 1) {
          ++t.over;
          if (ratio > kWarnTier) ++t.beyond_tier;
        }
        offer_worst(t, rules.worst_count, {x, y, c, o, g, err, b, {}});
      }
  }
}

StageComparison conclude(const std::string& stage, Tally total, const JudgeRules& rules,
                         const StageBounds& terms, const ImageGates* gates, bool uniform) {
  StageComparison s;
  s.stage = stage;
  s.values = total.values;
  s.over_bound = total.over;
  s.nonfinite_mismatch = total.mismatch;
  s.beyond_tier = total.beyond_tier;
  s.max_abs = total.max_abs;
  s.max_rel = total.max_rel;
  s.max_ulp16 = total.max_ulp16;
  s.max_ratio = total.max_ratio;
  s.ulp_histogram.assign(total.hist.begin(), total.hist.end());
  keep_worst(total.worst, rules.worst_count);
  for (WorstValue& w : total.worst) w.terms = terms.terms(w.x, w.y, w.channel);
  s.worst = std::move(total.worst);
  if (gates && !uniform) apply_gates(s, total, *gates, rules.window, rules.width);
  decide(s);
  return s;
}

int judge_band(int window) {
  constexpr int kRows = 32;  // a band's rows: a few MB of scratch at 3840 texels a row
  return window > 0 ? std::max(1, kRows / window) * window : kRows;
}

// Whether every texel's RGB equals the first texel's (bit for bit, NaN never equal): on such an
// image every value has the same error, so a mean or a window mean is one sample of it, not an
// average over independent roundings, and the image gates would only tighten the per-value bound.
bool uniform_rgb(ConstImageView img, bool clamped) {
  if (img.width <= 0 || img.height <= 0) return true;
  auto value = [clamped](float v) { return clamped && !std::isnan(v) ? std::clamp(v, 0.0f, 1.0f) : v; };
  const float* first = img.pixel(0, 0);
  const float f[3] = {value(first[0]), value(first[1]), value(first[2])};
  for (int y = 0; y < img.height; ++y) {
    const float* p = img.row(y);
    for (int x = 0; x < img.width; ++x, p += kChannels)
      if (!(value(p[0]) == f[0] && value(p[1]) == f[1] && value(p[2]) == f[2])) return false;
  }
  return true;
}

double within_bound(ConstImageView gl, ConstImageView oracle, const Image& bound, double relative,
                    Storage storage, const DeviceProfile& p, int threads, double absolute,
                    bool packed_slack) {
  if (gl.width != oracle.width || gl.height != oracle.height) return 0.0;
  std::vector<std::uint64_t> outside(std::size_t(gl.height), 0);
  parallel_rows(gl.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float *g = gl.row(y), *o = oracle.row(y), *b = bound.cview().row(y);
      std::uint64_t n = 0;
      for (int i = 0; i < gl.width * kChannels; ++i) {
        if (i % kChannels == 3) continue;
        // A packed-float level's quantum is coarse (2^-6 of the value): one of the variant's
        // own, which may lie a binade above the oracle's the bound holds.
        const double packed = packed_slack && storage == Storage::r11g11b10
                                  ? storage_term(o[i], storage, p, i % kChannels)
                                  : 0.0;
        // A NaN or Inf value relaxes nothing (NaN would make the bound NaN: not judged).
        const double mag = std::isfinite(o[i]) ? std::fabs(o[i]) : 0.0;
        const float relaxed = b[i] + static_cast<float>(relative * mag + absolute + packed);
        if (!(relaxed < INFINITY)) continue;
        // Finite values in the storage's range are numbers (special_case's -1), told apart here
        // without the call.
        const bool plain = std::isfinite(o[i]) && std::isfinite(g[i]) &&
                           std::fabs(o[i]) <= storage_limit(storage, int(i % kChannels));
        if (!plain) {
          const int special = special_case(o[i], g[i], storage, p, relaxed, int(i % kChannels));
          if (special != -1) {
            n += special == 0;
            continue;
          }
        }
        // Outside when err / relaxed > 1 (relaxed >= 0; 0 admits no error).
        n += std::fabs(double(g[i]) - double(o[i])) > relaxed;
      }
      outside[std::size_t(y)] = n;
    }
  });
  std::uint64_t out = 0;
  for (std::uint64_t n : outside) out += n;
  const std::uint64_t values = std::uint64_t(gl.width) * gl.height * 3;
  return values ? double(values - out) / double(values) : 1.0;
}

}  // namespace detail

ParityResult compare(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                     const StageTrace& cpu, const DeviceProfile& profile,
                     const CompareOptions& opt) {
  CapturedStages captured;
  for (const StageSpec& spec : plan.stages) {
    const StageResult* r = gl.find(spec.name);
    if (!r) throw ParamError("the GL trace has no stage '" + spec.name + "'");
    captured[spec.name] = CapturedStage{r->image.cview()};
  }
  return compare_captured(plan, scene, captured, cpu, profile, opt);
}

Plan plan_for_device(BloomParams params, ConstImageView scene, const DeviceProfile& profile,
                     const std::string& source) {
  if (params.precision != Precision::f32)
    throw ParamError("parity judges the GL path against the f32 oracle; --precision f64 is the "
                     "CPU truth only");
  params.subtexel_bits = profile.subtexel_bits;
  return make_plan(params, scene, source);
}

HalfRounding half_rounding_for(const DeviceProfile& profile) {
  return !profile.half_nearest_even       ? HalfRounding::toward_zero
         : profile.half_overflow_saturate ? HalfRounding::nearest_even_saturate
                                          : HalfRounding::nearest_even;
}


ParityResult compare_with_oracle(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                                 const DeviceProfile& profile, const CompareOptions& opt,
                                 double* cpu_ms) {
  CapturedStages captured;
  for (const StageSpec& spec : plan.stages) {
    const StageResult* r = gl.find(spec.name);
    if (!r) throw ParamError("the GL trace has no stage '" + spec.name + "'");
    captured[spec.name] = CapturedStage{r->image.cview()};
  }
  return check_with_oracle(plan, scene, captured, profile, opt, cpu_ms);
}

}  // namespace bloomref::parity
