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

  // One value: the oracle's o, GL's g, the bound b.
  void add(int x, int y, int c, double o, double g, double b, Storage storage,
           const DeviceProfile& p, std::size_t n_worst) {
    ++values;
    // An infinite (or NaN, from non-finite data) bound: unpinned by GL (NaN/Inf in the
    // footprint, max(NaN, 0)); where NaN/Inf appear is still compared through the stages.
    if (!(b < INFINITY)) return;
    const int special = special_case(o, g, storage, p, b);
    if (special == 0) {
      ++mismatch;
      worst.push_back({x, y, c, o, g, INFINITY, b, {}});
      return;
    }
    if (special == 1) return;
    const double err = std::fabs(g - o);
    if (err == 0) {
      hist[8]++;
      return;
    }
    max_abs = std::max(max_abs, err);
    if (o != 0) max_rel = std::max(max_rel, err / std::fabs(o));
    const double ulps = (g - o) / ulp16_of(o);
    max_ulp16 = std::max(max_ulp16, std::fabs(ulps));
    hist[static_cast<int>(std::clamp(std::round(ulps), -8.0, 8.0)) + 8]++;
    const double ratio = b > 0 ? err / b : INFINITY;
    max_ratio = std::max(max_ratio, ratio);
    if (ratio > 1) {
      ++over;
      if (ratio > kWarnTier) ++beyond_tier;
    }
    worst.push_back({x, y, c, o, g, err, b, {}});
    if (worst.size() > 4096) keep_worst(worst, n_worst);
  }

  void merge(const Tally& t) {
    values += t.values;
    over += t.over;
    mismatch += t.mismatch;
    beyond_tier += t.beyond_tier;
    max_abs = std::max(max_abs, t.max_abs);
    max_rel = std::max(max_rel, t.max_rel);
    max_ulp16 = std::max(max_ulp16, t.max_ulp16);
    max_ratio = std::max(max_ratio, t.max_ratio);
    for (int i = 0; i < 17; ++i) hist[i] += t.hist[i];
    worst.insert(worst.end(), t.worst.begin(), t.worst.end());
  }
};

// Every RGB value of `gl` against `oracle` and `bound` (images of the same size).
Tally tally(ConstImageView gl, ConstImageView oracle, const Image& bound, Storage storage,
            const DeviceProfile& p, std::size_t n_worst, int threads) {
  Tally total;
  std::mutex m;
  parallel_rows(gl.height, threads, [&](int y0, int y1) {
    Tally t;
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < gl.width; ++x)
        for (int c = 0; c < 3; ++c)
          t.add(x, y, c, oracle.pixel(x, y)[c], gl.pixel(x, y)[c], bound.pixel(x, y)[c], storage, p,
                n_worst);
    keep_worst(t.worst, n_worst);
    std::lock_guard<std::mutex> lock(m);
    total.merge(t);
  });
  return total;
}

StageComparison size_mismatch(const std::string& stage, ConstImageView gl, ConstImageView oracle) {
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

// FAIL for a non-finite mismatch or a value beyond the quality tier; WARN for one over its
// bound within the tier; else PASS.
void set_verdict(StageComparison& s, std::uint64_t beyond_tier) {
  if (s.nonfinite_mismatch > 0 || beyond_tier > 0) {
    s.verdict = Verdict::fail;
    s.reason = s.nonfinite_mismatch > 0
                   ? std::to_string(s.nonfinite_mismatch) + " values are NaN/Inf on one side only"
                   : std::to_string(beyond_tier) + " values exceed " +
                         std::to_string(static_cast<int>(kWarnTier)) +
                         "x their derived bound (worst " + std::to_string(s.max_ratio) + "x)";
  } else if (s.over_bound > 0) {
    s.verdict = Verdict::warn;
    s.reason = std::to_string(s.over_bound) + " values exceed their derived bound, by at most " +
               std::to_string(s.max_ratio) + "x (within the 4x quality tier)";
  } else {
    s.reason =
        "every value within its bound (largest error / bound " + std::to_string(s.max_ratio) + ")";
  }
}

StageComparison judge(const std::string& stage, ConstImageView gl, ConstImageView oracle,
                      const Image& bound, const StageBounds& terms, Storage storage,
                      const DeviceProfile& p, const CompareOptions& opt, int threads) {
  if (gl.width != oracle.width || gl.height != oracle.height)
    return size_mismatch(stage, gl, oracle);
  const std::size_t n_worst = static_cast<std::size_t>(opt.worst_count);
  Tally total = tally(gl, oracle, bound, storage, p, n_worst, threads);
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
  std::vector<WorstValue> worst = std::move(total.worst);
  keep_worst(worst, n_worst);
  for (WorstValue& w : worst) w.terms = terms.terms(w.x, w.y, w.channel);
  s.worst = std::move(worst);
  set_verdict(s, total.beyond_tier);
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

std::string level(const char* kind, int k) {
  return std::string(kind) + "." + std::to_string(k);
}

// e += scale * a, value by value.
void add_scaled(Image& e, const Image& a, double scale) {
  for (std::size_t i = 0; i < e.values().size(); ++i)
    e.values()[i] += static_cast<float>(scale * a.values()[i]);
}

// One stage's expectations: the oracle recomputed from GL's own input (isolation) with its
// per-value bound and their terms, and the end-to-end bound around the CPU's image.
struct Expected {
  Image oracle, bound, e2e;
  std::unique_ptr<StageBounds> terms;
};

// Judges each stage of a GL trace: isolated (the oracle from GL's input to the stage) and end to
// end (the CPU's image, within the bounds propagated from the scene).
class ParityRun {
 public:
  ParityRun(const Plan& plan, ConstImageView scene, const StageTrace& gl, const StageTrace& cpu,
            const DeviceProfile& profile, const CompareOptions& opt)
      : plan_(plan),
        p_(plan.params),
        gl_(gl),
        cpu_(cpu),
        profile_(profile),
        opt_(opt),
        threads_(plan.params.threads),
        w_(scene.width),
        h_(scene.height),
        ctx_{&profile, plan.params.storage, plan.params.threads},
        kernel_(kernel_for(plan.params.kernel)),
        after_(plan.params.method == Method::mip &&
               plan.params.composite == CompositeOrder::after_tonemap),
        bloom_stage_(bloom_stage_name(plan)),
        sanitized_(scene.width, scene.height) {
    // The sanitised scene (unrounded): what the input pass computes before storing.
    sanitize(scene, sanitized_.view(), p_.nonfinite, p_.storage, threads_);
  }

  ParityResult run() {
    ParityResult result;
    result.profile = profile_;
    for (const StageSpec& spec : plan_.stages) {
      const std::string& name = spec.name;
      const Image& g = G(name);
      const Image& c = C(name);
      Expected x{Image(c.width(), c.height()), Image(c.width(), c.height(), 0.0f),
                 Image(c.width(), c.height(), 0.0f), nullptr};
      expect(spec, c, x);
      result.isolated.push_back(judge(name, g.cview(), x.oracle.cview(), x.bound, *x.terms,
                                      p_.storage, profile_, opt_, threads_));
      result.end_to_end.push_back(
          judge(name, g.cview(), c.cview(), x.e2e, *x.terms, p_.storage, profile_, opt_, threads_));
      e2e_[name] = std::move(x.e2e);
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

 private:
  const Image& G(const std::string& n) const { return stage_image(gl_, n, "GL"); }
  const Image& C(const std::string& n) const { return stage_image(cpu_, n, "CPU"); }

  // Fills `x` for one stage, each reading GL's image of the stage before it (its isolation
  // input, by method and composite order); `c` is the CPU's image of the stage.
  void expect(const StageSpec& spec, const Image& c, Expected& x) {
    switch (spec.kind) {
      case StageKind::input:
        return input(x);
      case StageKind::bright:
        return bright(x);
      case StageKind::blur:
        return blur(spec, x);
      case StageKind::down:
        return down(spec, c, x);
      case StageKind::up:
        return up(spec.pass, c, x);
      case StageKind::bloom:
        return up(0, c, x);
      case StageKind::composite:
        return composite_stage(x);
      case StageKind::tonemap:
        return tonemap_stage(x);
      case StageKind::output:
        return output(x);
    }
  }

  void input(Expected& x) {
    x.oracle = sanitized_;
    x.terms = input_bounds(x.oracle.cview(), ctx_);
    x.terms->fill(x.bound);
    x.e2e = x.bound;
  }

  void bright(Expected& x) {
    extract_bright(sanitized_.cview(), x.oracle.view(), p_.threshold, threads_);
    x.terms = bright_bounds(sanitized_.cview(), p_.threshold, ctx_);
    x.terms->fill(x.bound);
    x.e2e = x.bound;
  }

  void blur(const StageSpec& spec, Expected& x) {
    const std::string prev = spec.pass == 1 ? "bright" : level("blur", spec.pass - 1);
    const Image& src = G(prev);
    blur_pass(src.cview(), x.oracle.view(), {spec.axis, &kernel_, profile_.subtexel_bits},
              threads_);
    x.terms = blur_bounds(src.cview(), x.oracle.cview(), spec.axis, kernel_, ctx_);
    x.terms->fill(x.bound);
    x.e2e = propagate_blur(e2e_.at(prev).cview(), spec.axis, kernel_, threads_);
    add_scaled(x.e2e, x.bound, 1.0);
  }

  void down(const StageSpec& spec, const Image& c, Expected& x) {
    const int k = spec.pass;
    const std::string prev = k == 1 ? "input" : level("down", k - 1);
    const Image& src = G(prev);
    x.oracle = Image(plan_.levels[k - 1].width, plan_.levels[k - 1].height);
    x.bound = Image(x.oracle.width(), x.oracle.height(), 0.0f);
    const DownsampleOptions o{k == 1, p_.threshold, p_.karis && k == 1, profile_.subtexel_bits};
    downsample(src.cview(), x.oracle.view(), o, threads_);
    x.terms =
        down_bounds(src.cview(), x.oracle.cview(), nullptr, k == 1, p_.threshold, p_.karis, ctx_);
    x.terms->fill(x.bound);
    down_bounds(C(prev).cview(), c.cview(), &e2e_.at(prev), k == 1, p_.threshold, p_.karis, ctx_)
        ->fill(x.e2e);
  }

  // up.k (k >= 1), or the bloom (k = 0): the tent of the level below, plus down.k for up.k.
  void up(int k, const Image& c, Expected& x) {
    const int top = static_cast<int>(plan_.levels.size());
    const std::string small = k + 1 == top ? level("down", top) : level("up", k + 1);
    const std::string cur = k == 0 ? "" : level("down", k);
    const BasicView<const float> none{};
    const Image& gs = G(small);
    if (k == 0) {
      x.oracle = Image(w_, h_);
    } else {
      x.oracle = Image(G(cur).width(), G(cur).height());
    }
    x.bound = Image(x.oracle.width(), x.oracle.height(), 0.0f);
    upsample_tent(gs.cview(), k ? G(cur).cview() : none, x.oracle.view(), profile_.subtexel_bits,
                  threads_);
    x.terms =
        up_bounds(gs.cview(), k ? G(cur).cview() : none, x.oracle.cview(), nullptr, nullptr, ctx_);
    x.terms->fill(x.bound);
    up_bounds(C(small).cview(), k ? C(cur).cview() : none, c.cview(), &e2e_.at(small),
              k ? &e2e_.at(cur) : nullptr, ctx_)
        ->fill(x.e2e);
  }

  void composite_stage(Expected& x) {
    const std::string base = after_ ? "tonemap" : "input";
    const Image& sc = G(base);
    const Image& bl = G(bloom_stage_);
    composite(sc.cview(), bl.cview(), x.oracle.view(), p_.strength, threads_);
    x.terms = composite_bounds(sc.cview(), bl.cview(), x.oracle.cview(), p_.strength, ctx_);
    x.terms->fill(x.bound);
    x.e2e = e2e_.at(base);
    add_scaled(x.e2e, e2e_.at(bloom_stage_), p_.strength);
    add_scaled(x.e2e, x.bound, 1.0);
  }

  void tonemap_stage(Expected& x) {
    const std::string src = after_ ? "input" : "composite";
    const Image& hd = G(src);
    tonemap(hd.cview(), x.oracle.view(), p_.exposure, threads_);
    x.terms = tonemap_bounds(hd.cview(), x.oracle.cview(), p_.exposure, ctx_);
    x.terms->fill(x.bound);
    const Image& ch = C(src);
    const Image& eh = e2e_.at(src);
    for (std::size_t i = 0; i < x.e2e.values().size(); ++i) {
      const double hv = ch.values()[i], ev = eh.values()[i];
      // The slope of 1 - exp(-h k) is k exp(-h k): largest at the low end of h +- e.
      x.e2e.values()[i] =
          std::isfinite(hv) && std::isfinite(ev)
              ? static_cast<float>(p_.exposure * std::exp(-(hv - ev) * p_.exposure) * ev)
              : INFINITY;
    }
    add_scaled(x.e2e, x.bound, 1.0);
  }

  void output(Expected& x) {
    const std::string src = after_ ? "composite" : "tonemap";
    const Image& m = G(src);
    encode_output(m.cview(), x.oracle.view(), p_.gamma, threads_);
    x.terms = output_bounds(m.cview(), x.oracle.cview(), p_.gamma, ctx_);
    x.terms->fill(x.bound);
    const Image& cm = C(src);
    const Image& em = e2e_.at(src);
    const double gexp = 1.0 / p_.gamma;
    for (std::size_t i = 0; i < x.e2e.values().size(); ++i) {
      const double mv = cm.values()[i], ev = em.values()[i];
      // Gamma's slope is unbounded near black: bound by the interval's image instead.
      x.e2e.values()[i] = std::isfinite(mv) && std::isfinite(ev)
                              ? static_cast<float>(std::pow(std::max(mv + ev, 0.0), gexp) -
                                                   std::pow(std::max(mv - ev, 0.0), gexp))
                              : INFINITY;
    }
    add_scaled(x.e2e, x.bound, 1.0);
  }

  const Plan& plan_;
  const BloomParams& p_;
  const StageTrace& gl_;
  const StageTrace& cpu_;
  const DeviceProfile& profile_;
  const CompareOptions& opt_;
  const int threads_, w_, h_;
  const BoundContext ctx_;
  const Kernel& kernel_;
  const bool after_;  // method mip, composite after the tone map
  const std::string bloom_stage_;
  Image sanitized_;
  std::map<std::string, Image> e2e_;  // end-to-end bound of each stage, on the CPU's images
};

}  // namespace

ParityResult compare(const Plan& plan, ConstImageView scene, const StageTrace& gl,
                     const StageTrace& cpu, const DeviceProfile& profile,
                     const CompareOptions& opt) {
  return ParityRun(plan, scene, gl, cpu, profile, opt).run();
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
