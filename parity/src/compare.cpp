#include "bloomref/parity/compare.h"

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <tuple>

#include "bloomref/error.h"
#include "bloomref/mip.h"
#include "bloomref/parallel.h"
#include "tolerance.h"

namespace bloomref::parity {

using namespace detail;

std::string to_string(Verdict v) {
  return v == Verdict::pass ? "PASS" : v == Verdict::warn ? "WARN" : "FAIL";
}

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
  double max_abs = 0, max_rel = 0, max_ulp16 = 0, max_ratio = 0;
  std::vector<std::uint64_t> hist = std::vector<std::uint64_t>(17, 0);
  std::vector<WorstValue> worst;
};

StageComparison judge(const std::string& stage, ConstImageView gl, ConstImageView oracle,
                      const Image& bound, const StageBounds& terms, Storage storage,
                      const DeviceProfile& p, const CompareOptions& opt, int threads) {
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
  std::vector<WorstValue> worst = std::move(total.worst);
  keep_worst(worst, n_worst);
  for (WorstValue& w : worst) w.terms = terms.terms(w.x, w.y, w.channel);
  s.worst = std::move(worst);

  if (s.nonfinite_mismatch > 0 || warn_tier > 0) {
    s.verdict = Verdict::fail;
    s.reason = s.nonfinite_mismatch > 0
                   ? std::to_string(s.nonfinite_mismatch) + " values are NaN/Inf on one side only"
                   : std::to_string(warn_tier) + " values exceed " +
                         std::to_string(static_cast<int>(kWarnTier)) +
                         "x their derived bound (worst " + std::to_string(s.max_ratio) + "x)";
  } else if (s.over_bound > 0) {
    s.verdict = Verdict::warn;
    s.reason = std::to_string(s.over_bound) + " values exceed their derived bound, by at most " +
               std::to_string(s.max_ratio) + "x (within the 4x quality tier)";
  } else {
    s.reason = "every value within its bound (largest error / bound " +
               std::to_string(s.max_ratio) + ")";
  }
  if (opt.keep_images) {
    s.oracle = Image(gl.width, gl.height);
    for (int y = 0; y < gl.height; ++y)
      std::copy(oracle.row(y), oracle.row(y) + std::size_t(gl.width) * kChannels,
                s.oracle.view().row(y));
    s.bound = bound;
  }
  return s;
}

const Image& stage_image(const StageTrace& t, const std::string& name, const char* which) {
  const StageResult* r = t.find(name);
  if (!r) throw ParamError(std::string("the ") + which + " trace has no stage '" + name + "'");
  return r->image;
}

}  // namespace

ParityResult compare(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                     const StageTrace& cpu, const DeviceProfile& profile,
                     const CompareOptions& opt) {
  const BloomParams& p = plan.params;
  const int threads = p.threads, w = scene.width, h = scene.height;
  const BoundContext ctx{&profile, p.storage, threads};
  const Kernel& kernel = kernel_for(p.kernel);
  const bool mip = p.method == Method::mip;
  const bool after = mip && p.composite == CompositeOrder::after_tonemap;
  const int top = static_cast<int>(plan.levels.size());
  ParityResult result;
  result.profile = profile;

  // The sanitised scene (unrounded): what the input pass computes before storing.
  Image sanitized(w, h);
  sanitize(scene, sanitized.view(), p.nonfinite, p.storage, threads);

  auto G = [&](const std::string& n) -> const Image& { return stage_image(gl, n, "GL"); };
  auto C = [&](const std::string& n) -> const Image& { return stage_image(cpu, n, "CPU"); };
  auto level = [](const char* kind, int k) { return std::string(kind) + "." + std::to_string(k); };
  // The stage each one reads (its isolation input), by method and composite order.
  const std::string bloom_stage = bloom_stage_name(plan);
  const std::string composite_base = after ? "tonemap" : "input";
  const std::string tonemap_src = after ? "input" : "composite";
  const std::string output_src = after ? "composite" : "tonemap";
  std::map<std::string, Image> e2e;  // end-to-end bound of each stage, on the CPU's images

  for (const StageSpec& spec : plan.stages) {
    const std::string& name = spec.name;
    const Image& g = G(name);
    const Image& c = C(name);
    Image oracle(c.width(), c.height()), bound(c.width(), c.height(), 0.0f);
    Image e(c.width(), c.height(), 0.0f);  // end-to-end bound
    std::unique_ptr<StageBounds> b;
    auto add = [&](const Image& a, double scale) {
      for (std::size_t i = 0; i < e.values().size(); ++i)
        e.values()[i] += static_cast<float>(scale * a.values()[i]);
    };
    switch (spec.kind) {
      case StageKind::input:
        oracle = sanitized;
        b = input_bounds(oracle.cview(), ctx);
        b->fill(bound);
        e = bound;
        break;
      case StageKind::bright:
        extract_bright(sanitized.cview(), oracle.view(), p.threshold, threads);
        b = bright_bounds(sanitized.cview(), p.threshold, ctx);
        b->fill(bound);
        e = bound;
        break;
      case StageKind::blur: {
        const std::string prev = spec.pass == 1 ? "bright" : level("blur", spec.pass - 1);
        const Image& src = G(prev);
        blur_pass(src.cview(), oracle.view(), {spec.axis, &kernel, profile.subtexel_bits}, threads);
        b = blur_bounds(src.cview(), oracle.cview(), spec.axis, kernel, ctx);
        b->fill(bound);
        e = propagate_blur(e2e.at(prev).cview(), spec.axis, kernel, threads);
        add(bound, 1.0);
        break;
      }
      case StageKind::down: {
        const int k = spec.pass;
        const std::string prev = k == 1 ? "input" : level("down", k - 1);
        const Image& src = G(prev);
        oracle = Image(plan.levels[k - 1].width, plan.levels[k - 1].height);
        bound = Image(oracle.width(), oracle.height(), 0.0f);
        const DownsampleOptions o{k == 1, p.threshold, p.karis && k == 1, profile.subtexel_bits};
        downsample(src.cview(), oracle.view(), o, threads);
        b = down_bounds(src.cview(), oracle.cview(), nullptr, k == 1, p.threshold, p.karis, ctx);
        b->fill(bound);
        down_bounds(C(prev).cview(), c.cview(), &e2e.at(prev), k == 1, p.threshold, p.karis, ctx)
            ->fill(e);
        break;
      }
      case StageKind::up:
      case StageKind::bloom: {
        const int k = spec.kind == StageKind::bloom ? 0 : spec.pass;
        const std::string small = k + 1 == top ? level("down", top) : level("up", k + 1);
        const std::string cur = k == 0 ? "" : level("down", k);
        const BasicView<const float> none{};
        const Image& gs = G(small);
        if (k == 0) {
          oracle = Image(w, h);
        } else {
          oracle = Image(G(cur).width(), G(cur).height());
        }
        bound = Image(oracle.width(), oracle.height(), 0.0f);
        upsample_tent(gs.cview(), k ? G(cur).cview() : none, oracle.view(), profile.subtexel_bits,
                      threads);
        b = up_bounds(gs.cview(), k ? G(cur).cview() : none, oracle.cview(), nullptr, nullptr, ctx);
        b->fill(bound);
        up_bounds(C(small).cview(), k ? C(cur).cview() : none, c.cview(), &e2e.at(small),
                  k ? &e2e.at(cur) : nullptr, ctx)
            ->fill(e);
        break;
      }
      case StageKind::composite: {
        const Image& sc = G(composite_base);
        const Image& bl = G(bloom_stage);
        composite(sc.cview(), bl.cview(), oracle.view(), p.strength, threads);
        b = composite_bounds(sc.cview(), bl.cview(), oracle.cview(), p.strength, ctx);
        b->fill(bound);
        e = e2e.at(composite_base);
        add(e2e.at(bloom_stage), p.strength);
        add(bound, 1.0);
        break;
      }
      case StageKind::tonemap: {
        const Image& hd = G(tonemap_src);
        tonemap(hd.cview(), oracle.view(), p.exposure, threads);
        b = tonemap_bounds(hd.cview(), oracle.cview(), p.exposure, ctx);
        b->fill(bound);
        const Image& ch = C(tonemap_src);
        const Image& eh = e2e.at(tonemap_src);
        for (std::size_t i = 0; i < e.values().size(); ++i) {
          const double hv = ch.values()[i], ev = eh.values()[i];
          // The slope of 1 - exp(-h k) is k exp(-h k): largest at the low end of h +- e.
          e.values()[i] = std::isfinite(hv) && std::isfinite(ev)
                              ? static_cast<float>(p.exposure * std::exp(-(hv - ev) * p.exposure) * ev)
                              : INFINITY;
        }
        add(bound, 1.0);
        break;
      }
      case StageKind::output: {
        const Image& m = G(output_src);
        encode_output(m.cview(), oracle.view(), p.gamma, threads);
        b = output_bounds(m.cview(), oracle.cview(), p.gamma, ctx);
        b->fill(bound);
        const Image& cm = C(output_src);
        const Image& em = e2e.at(output_src);
        const double gexp = 1.0 / p.gamma;
        for (std::size_t i = 0; i < e.values().size(); ++i) {
          const double mv = cm.values()[i], ev = em.values()[i];
          // Gamma's slope is unbounded near black: bound by the interval's image instead.
          e.values()[i] = std::isfinite(mv) && std::isfinite(ev)
                              ? static_cast<float>(std::pow(std::max(mv + ev, 0.0), gexp) -
                                                   std::pow(std::max(mv - ev, 0.0), gexp))
                              : INFINITY;
        }
        add(bound, 1.0);
        break;
      }
    }
    result.isolated.push_back(
        judge(name, g.cview(), oracle.cview(), bound, *b, p.storage, profile, opt, threads));
    result.end_to_end.push_back(
        judge(name, g.cview(), c.cview(), e, *b, p.storage, profile, opt, threads));
    e2e[name] = std::move(e);
  }

  for (const StageComparison& s : result.isolated) {
    if (s.verdict != Verdict::pass && !result.first_divergent_stage)
      result.first_divergent_stage = s.stage;
    result.verdict = std::max(result.verdict, s.verdict);
  }
  for (const StageComparison& s : result.end_to_end)
    result.verdict = std::max(result.verdict, s.verdict);
  return result;
}

Plan plan_for_device(BloomParams params, ConstImageView scene, const DeviceProfile& profile,
                     const std::string& source) {
  if (params.precision != Precision::f32)
    throw ParamError("parity judges the GL path against the f32 oracle; --precision f64 is the "
                     "CPU truth only");
  params.subtexel_bits = profile.subtexel_bits;
  return make_plan(params, scene, source);
}

ParityResult compare_with_oracle(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                                 const DeviceProfile& profile, const CompareOptions& opt,
                                 double* cpu_ms) {
  ExecuteOptions eo;
  eo.keep_all = true;
  eo.half_rounding = !profile.half_nearest_even       ? HalfRounding::toward_zero
                     : profile.half_overflow_saturate ? HalfRounding::nearest_even_saturate
                                                      : HalfRounding::nearest_even;
  const auto t0 = std::chrono::steady_clock::now();
  const StageTrace cpu = execute(plan, scene, eo);
  if (cpu_ms)
    *cpu_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return compare(plan, scene, gl, cpu, profile, opt);
}

}  // namespace bloomref::parity
