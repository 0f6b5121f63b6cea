#include "bloomref/parity/compare.h"

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <tuple>

#include "bloomref/error.h"
#include "bloomref/mip.h"
#include "bloomref/parallel.h"
#include "judge.h"
#include "tolerance.h"

namespace bloomref::parity {

using namespace detail;

std::string to_string(Verdict v) {
  return v == Verdict::pass ? "PASS" : v == Verdict::warn ? "WARN" : "FAIL";
}

namespace detail {
namespace {

constexpr double kWarnTier = 4.0;  // over the derived bound but within 4x: WARN

double ulp16_of(double v) {
  const double a = std::fabs(v);
  return std::ldexp(1.0, (a > 0 ? std::max(std::ilogb(a), -14) : -14) - 10);
}

// Whether a non-finite or overflowing pair is acceptable, decided without a bound.
// Returns 1 acceptable, 0 mismatch, -1 not such a case (compare with the bound).
int special_case(double o, double g, Storage storage, const DeviceProfile& p, double bound) {
  if (std::isnan(o) || std::isnan(g)) return std::isnan(o) && std::isnan(g) ? 1 : 0;
  const double limit = storage == Storage::f16 ? 65504.0 : FLT_MAX;
  if (storage == Storage::f16 && std::fabs(o) > limit) {
    // Beyond half's range: Inf (nearest-even overflow) or 65504 (saturation), same sign.
    const bool same_sign = std::signbit(o) == std::signbit(g);
    const bool ok = (p.half_overflow_inf && std::isinf(g)) ||
                    (p.half_overflow_saturate && std::fabs(g) == limit);
    return same_sign && (ok || std::fabs(g) == std::fabs(o)) ? 1 : 0;
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

// Orders by error / bound, largest first; position breaks ties so the list is deterministic.
bool worse(const WorstValue& a, const WorstValue& b) {
  const double ra = a.error / std::max(a.bound, 1e-300), rb = b.error / std::max(b.bound, 1e-300);
  if (ra != rb) return ra > rb;
  return std::tie(a.y, a.x, a.channel) < std::tie(b.y, b.x, b.channel);
}

void keep_worst(std::vector<WorstValue>& w, std::size_t n) {
  const std::size_t keep = std::min(n, w.size());
  std::partial_sort(w.begin(), w.begin() + keep, w.end(), worse);
  w.resize(keep);
}

// Counts over a row range; merged by sums and maxima, so the result is thread-count independent.
struct Tally {
  std::uint64_t values = 0, over = 0, mismatch = 0, beyond_tier = 0;
  double excess = 0, base = 0;  // the image gates' sums (gate_sums): ratios, and their count
  double max_abs = 0, max_rel = 0, max_ulp16 = 0, max_ratio = 0;
  std::vector<std::uint64_t> hist = std::vector<std::uint64_t>(17, 0);
  std::vector<WorstValue> worst;
};

// What the image gates take off each value (judge.h): rounding from both error and bound,
// slack from the error only.
struct GateAllowance {
  const Image* rounding = nullptr;
  const Image* slack = nullptr;
};

// One value's part in the image gates: its error beyond the rounding it is allowed over its
// bound beyond the same (at most 4: beyond, the value fails anyway), added to `sum`; `count`
// counts the values with something to bound. A mean of these ratios, not a ratio of sums: the
// bounds span many orders of magnitude (a light's edge against flat sky), and a ratio of sums
// would only see the largest.
inline void gate_sums(double err, double b, double o, Storage storage, const DeviceProfile& p,
                      GateAllowance a, int x, int y, int c, double& sum, double& count) {
  const double r = a.rounding ? a.rounding->pixel(x, y)[c] : storage_term(o, storage, p);
  const double excess = std::max(0.0, err - r - (a.slack ? a.slack->pixel(x, y)[c] : 0.0f));
  const double base = b - r;
  if (!(base > 0)) return;
  sum += std::min(excess / base, 4.0);
  count += 1;
}

// The worst window's ratio of excess to bound, over non-overlapping n x n blocks (blocks with
// nothing to bound left out), and its top-left texel; ties go to the first block in row order.
double worst_window(ConstImageView gl, ConstImageView oracle, const Image& bound, Storage storage,
                    const DeviceProfile& p, GateAllowance allowance, int n, int threads, int& wx,
                    int& wy) {
  const int bw = (gl.width + n - 1) / n, bh = (gl.height + n - 1) / n;
  std::vector<double> ratio(std::size_t(bw) * bh, 0.0);
  parallel_rows(bh, threads, [&](int b0, int b1) {
    for (int by = b0; by < b1; ++by)
      for (int bx = 0; bx < bw; ++bx) {
        double excess = 0, base = 0;
        for (int y = by * n; y < std::min(gl.height, (by + 1) * n); ++y)
          for (int x = bx * n; x < std::min(gl.width, (bx + 1) * n); ++x)
            for (int c = 0; c < 3; ++c) {
              const double o = oracle.pixel(x, y)[c], g = gl.pixel(x, y)[c];
              const double b = bound.pixel(x, y)[c];
              // The values the main loop compares against their bound, no others.
              if (!(b < INFINITY) || special_case(o, g, storage, p, b) != -1) continue;
              gate_sums(std::fabs(g - o), b, o, storage, p, allowance, x, y, c, excess, base);
            }
        ratio[std::size_t(by) * bw + bx] = base > 0 ? excess / base : 0.0;  // sum / count
      }
  });
  const auto it = std::max_element(ratio.begin(), ratio.end());
  const std::size_t i = static_cast<std::size_t>(it - ratio.begin());
  wx = static_cast<int>(i % bw) * n;
  wy = static_cast<int>(i / bw) * n;
  return *it;
}

std::string fixed3(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

}  // namespace

// Whether every texel's RGB equals the first texel's (bit for bit, NaN never equal): on such an
// image every value has the same error, so a mean or a window mean is one sample of it, not an
// average over independent roundings, and the image gates would only tighten the per-value bound.
bool uniform_rgb(ConstImageView img) {
  if (img.width <= 0 || img.height <= 0) return true;
  const float* first = img.pixel(0, 0);
  for (int y = 0; y < img.height; ++y) {
    const float* p = img.row(y);
    for (int x = 0; x < img.width; ++x, p += kChannels)
      if (!(p[0] == first[0] && p[1] == first[1] && p[2] == first[2])) return false;
  }
  return true;
}

StageComparison judge(const std::string& stage, ConstImageView gl, ConstImageView oracle,
                      const Image& bound, const StageBounds& terms, Storage storage,
                      const DeviceProfile& p, const CompareOptions& opt, int threads,
                      const ImageGates* gates, const Image* allowance, const Image* slack) {
  const GateAllowance ga{allowance, slack};
  const std::size_t n_worst = static_cast<std::size_t>(opt.worst_count);
  if (gl.width != oracle.width || gl.height != oracle.height) {
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
  Tally total;
  std::mutex m;
  parallel_rows(gl.height, threads, [&](int y0, int y1) {
    Tally t;
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < gl.width; ++x)
        for (int c = 0; c < 3; ++c) {
          const double o = oracle.pixel(x, y)[c], g = gl.pixel(x, y)[c];
          const double b = bound.pixel(x, y)[c];
          ++t.values;
          // An infinite (or NaN, from non-finite data) bound: unpinned by GL (NaN/Inf in the
          // footprint, max(NaN, 0)); where NaN/Inf appear is still compared through the stages.
          if (!(b < INFINITY)) continue;
          const int special = special_case(o, g, storage, p, b);
          if (special == 0) {
            ++t.mismatch;
            t.worst.push_back({x, y, c, o, g, INFINITY, b, {}});
            continue;
          }
          if (special == 1) continue;
          const double err = std::fabs(g - o);
          if (gates) gate_sums(err, b, o, storage, p, ga, x, y, c, t.excess, t.base);
          if (err == 0) {
            t.hist[8]++;
            continue;
          }
          t.max_abs = std::max(t.max_abs, err);
          if (o != 0) t.max_rel = std::max(t.max_rel, err / std::fabs(o));
          const double ulps = (g - o) / ulp16_of(o);
          t.max_ulp16 = std::max(t.max_ulp16, std::fabs(ulps));
          t.hist[static_cast<int>(std::clamp(std::round(ulps), -8.0, 8.0)) + 8]++;
          const double ratio = b > 0 ? err / b : INFINITY;
          t.max_ratio = std::max(t.max_ratio, ratio);
          if (ratio > 1) {
            ++t.over;
            if (ratio > kWarnTier) ++t.beyond_tier;
          }
          t.worst.push_back({x, y, c, o, g, err, b, {}});
          if (t.worst.size() > 4096) keep_worst(t.worst, n_worst);
        }
    keep_worst(t.worst, n_worst);
    std::lock_guard<std::mutex> lock(m);
    total.values += t.values;
    total.over += t.over;
    total.mismatch += t.mismatch;
    total.beyond_tier += t.beyond_tier;
    total.excess += t.excess;
    total.base += t.base;
    total.max_abs = std::max(total.max_abs, t.max_abs);
    total.max_rel = std::max(total.max_rel, t.max_rel);
    total.max_ulp16 = std::max(total.max_ulp16, t.max_ulp16);
    total.max_ratio = std::max(total.max_ratio, t.max_ratio);
    for (int i = 0; i < 17; ++i) total.hist[i] += t.hist[i];
    total.worst.insert(total.worst.end(), t.worst.begin(), t.worst.end());
  });
  StageComparison s;
  s.stage = stage;
  s.values = total.values;
  s.over_bound = total.over;
  s.nonfinite_mismatch = total.mismatch;
  s.max_abs = total.max_abs;
  s.max_rel = total.max_rel;
  s.max_ulp16 = total.max_ulp16;
  s.max_ratio = total.max_ratio;
  s.ulp_histogram = total.hist;
  const std::uint64_t warn_tier = total.beyond_tier;
  s.beyond_tier = total.beyond_tier;
  std::vector<WorstValue> worst = std::move(total.worst);
  keep_worst(worst, n_worst);
  for (WorstValue& w : worst) w.terms = terms.terms(w.x, w.y, w.channel);
  s.worst = std::move(worst);

  if (gates && !uniform_rgb(oracle)) {
    s.mean_excess = total.base > 0 ? total.excess / total.base : 0.0;  // sum / count
    if (gates->window > 0 && gates->window_size > 0)
      s.worst_window = worst_window(gl, oracle, bound, storage, p, ga, gates->window_size,
                                    threads, s.worst_window_x, s.worst_window_y);
    const double over = s.values ? double(s.over_bound) / double(s.values) : 0.0;
    if (gates->mean > 0 && s.mean_excess > gates->mean)
      s.gate = "the mean error is " + fixed3(s.mean_excess) + " of the bound beyond rounding (gate " +
               fixed3(gates->mean) + ")";
    else if (gates->window > 0 && s.worst_window > gates->window)
      s.gate = "the " + std::to_string(gates->window_size) + "x" +
               std::to_string(gates->window_size) + " window at (" +
               std::to_string(s.worst_window_x) + ", " + std::to_string(s.worst_window_y) +
               ") has a mean error of " + fixed3(s.worst_window) +
               " of its bound beyond rounding (gate " + fixed3(gates->window) + ")";
    else if (gates->over_fraction > 0 && over > gates->over_fraction)
      s.gate = fixed3(100 * over) + "% of the values exceed their bound (gate " +
               fixed3(100 * gates->over_fraction) + "%)";
  }
  if (s.nonfinite_mismatch > 0 || warn_tier > 0) {
    s.verdict = Verdict::fail;
    s.reason = s.nonfinite_mismatch > 0
                   ? std::to_string(s.nonfinite_mismatch) + " values are NaN/Inf on one side only"
                   : std::to_string(warn_tier) + " values exceed " +
                         std::to_string(static_cast<int>(kWarnTier)) +
                         "x their derived bound (worst " + fixed3(s.max_ratio) + "x)";
  } else if (!s.gate.empty()) {
    s.verdict = Verdict::fail;
    s.reason = "image gate: " + s.gate;
  } else if (s.over_bound > 0) {
    s.verdict = Verdict::warn;
    s.reason = std::to_string(s.over_bound) + " values exceed their derived bound, by at most " +
               fixed3(s.max_ratio) + "x (within the 4x quality tier)";
  } else {
    s.reason = "every value within its bound (largest error / bound " +
               fixed3(s.max_ratio) + ")";
  }
  if (opt.keep_images && !(opt.keep_failing_only && s.verdict == Verdict::pass)) {
    s.oracle = Image(gl.width, gl.height);
    for (int y = 0; y < gl.height; ++y)
      std::copy(oracle.row(y), oracle.row(y) + std::size_t(gl.width) * kChannels,
                s.oracle.view().row(y));
    s.bound = bound;
  }
  return s;
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
