// compare_captured: the stage-by-stage comparison of any subset of captured stages.
//
// Three images per stage: the isolated oracle (the stage recomputed from what the device had:
// the captures of the stages it reads, or, where a stage has no capture, the oracle's own
// recomputation of it), its bound, and the end-to-end bound (against the CPU's full run). A
// stage without capture is stored as the device would store it and carries an error: its own
// bound plus what it inherited, plus the storage rounding of the recomputed value; the stages
// that read it add that error, propagated through them, to their isolated bounds. A capture
// carries none: it is what the device had.
//
// How it runs: stage by stage, in plan order, each stage in bands of rows on every thread. A
// band's bounds (isolated, inherited, end to end, a capture's codes) are made in scratch rows
// and judged at once; only the images later stages read are kept whole (the oracle's run, the
// captures, the end-to-end bounds, what stages without capture carry), and each is released
// once no later stage reads it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <cstring>
#include <map>
#include <memory>

#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "causes.h"
#include "chain.h"
#include "holding.h"
#include "judge.h"
#include "stage_terms.h"
#include "tolerance.h"

namespace bloomref::parity {

using namespace detail;

namespace {

// A stage's bound terms plus extra per-value terms (the error carried from stages without
// capture, an 8-bit capture's half code), for the report's worst values.
struct ExtraTerms : StageBounds {
  using Value = std::function<double(int x, int y, int c)>;
  const StageBounds& inner;
  std::vector<std::pair<std::string, Value>> extra;
  ExtraTerms(const StageBounds& b, std::vector<std::pair<std::string, Value>> e)
      : inner(b), extra(std::move(e)) {}
  void rows(int y0, int y1, float* bound, float* rounding) const override {
    inner.rows(y0, y1, bound, rounding);
  }
  std::vector<Term> terms(int x, int y, int c) const override {
    std::vector<Term> t = inner.terms(x, y, c);
    for (const auto& [name, value] : extra)
      if (value) t.push_back({name, value(x, y, c)});
    return t;
  }
};

// What a band of a captured stage keeps whole (each null when not wanted): the end-to-end bound
// as later stages read it, the isolated bound as judged, the error carried in.
struct Kept {
  Image *e2e = nullptr, *bound = nullptr, *inherited = nullptr;
};

class Comparison {
 public:
  Comparison(const Plan& plan, ConstImageView scene, const std::vector<std::string>& names,
             const std::function<Held(const std::string&)>& load, const StageTrace* cpu,
             const DeviceProfile& profile, const CompareOptions& opt)
      : plan_(plan), p_(plan.params), scene_(scene), load_(load), cpu_(cpu), profile_(profile),
        opt_(opt), threads_(p_.threads), ctx_{&profile, p_.storage, threads_, opt.direct_exp_tonemap, opt.interpolated_reads},
        kernel_(kernel_for(p_.kernel)), rounding_(half_rounding_for(profile)),
        streams_(plan, names, opt.causes) {
    result_.profile = profile;
    for (const std::string& name : names)
      if (!find_stage(plan, name))
        throw ParamError("no stage '" + name + "' in this plan (" + to_string(p_.method) + ", " +
                         std::to_string(p_.passes) + " passes)");
  }

  ParityResult run(double* oracle_ms);

 private:
  void sanitize_scene();
  void oracle_full(const StageSpec& spec, const std::vector<std::string>& in);
  TermInputs inputs();
  void judge_captured(std::size_t index, StageTerms& t);
  void band_captured(int y0, int y1, StageTerms& t, Tally& iso, Tally& e2e, Kept kept, bool judge);
  ExtraTerms iso_terms(const StageTerms& t, const CapturedStage& cap, const Image& inherited) const;
  ExtraTerms::Value codes_of(const CapturedStage& cap, ConstImageView oracle) const;
  Image final_bound(const StageTerms& t);
  void test_causes_of(const StageSpec& spec, StageComparison& iso, Image& oracle,
                      const Image& bound);
  void keep_uncaptured(std::size_t index, StageTerms& t);
  ParityResult finish();

  ConstImageView V(const std::string& n) const {  // a stage as the isolated oracle reads it
    const auto c = captures_.find(n);
    if (c != captures_.end()) return c->second.view;
    const auto it = computed_.find(n);
    return it != computed_.end() ? it->second.cview() : ConstImageView{};
  }
  const Image* E(const std::string& n) const {  // the error a stage without capture carries
    const auto it = carried_.find(n);
    return it == carried_.end() ? nullptr : &it->second;
  }
  ConstImageView C(const std::string& n) const {  // the oracle's full run
    if (!cpu_) return n == "input" && input_is_scene_ ? sanitized_ : full_.at(n).cview();
    const StageResult* r = cpu_->find(n);
    if (!r) throw ParamError("the CPU trace has no stage '" + n + "'");
    return r->image.cview();
  }
  BoundRows e2e_rows(const std::string& n) const {
    const auto it = e2e_.find(n);
    if (it != e2e_.end()) return {&it->second, nullptr};
    return {nullptr, input_e2e_};
  }
  bool e2e_made_again(const std::string& n) const;
  // The capture of the stage being judged, as judged (the profile may say every capture holds
  // 8-bit codes).
  CapturedStage capture(const std::string& n) const {
    const Held& h = captures_.at(n);
    return {h.view, std::max(h.code_bits, profile_.capture_code_bits), h.srgb};
  }

  const Plan& plan_;
  const BloomParams& p_;
  ConstImageView scene_, sanitized_;
  const std::function<Held(const std::string&)>& load_;
  const StageTrace* cpu_;
  const DeviceProfile& profile_;
  const CompareOptions& opt_;
  const int threads_;
  const BoundContext ctx_;
  const Kernel& kernel_;
  const HalfRounding rounding_;
  Streams streams_;
  ParityResult result_;
  double oracle_time_ = 0;

  ImagePool pool_;
  Image sanitized_owned_;                  // when the policy changed the scene
  bool input_is_scene_ = false;            // the full run's input is sanitized_ (f32 storage)
  std::shared_ptr<const StageBounds> input_e2e_;  // input's end-to-end bound, made again
  std::map<std::string, Held> captures_;   // loaded when reached
  std::map<std::string, Image> computed_;  // stages without capture: the oracle's, stored
  std::map<std::string, Image> carried_;   // and the error each carries
  std::map<std::string, Image> full_;      // the oracle's full run (when no trace is given)
  std::map<std::string, Image> e2e_;       // end-to-end bound of each stage, on the full run
  const StageSpec* spec_ = nullptr;        // the stage being judged
  std::string name_;
  JudgeRules iso_rules_, e2e_rules_;       // how its values are judged
};

// The sanitised scene (unrounded): what the input pass computes before storing. A scene the
// policy leaves as it is (every value finite and within range, the usual case) is read in
// place.
void Comparison::sanitize_scene() {
  Image s = Image::uninitialised(scene_.width, scene_.height);
  sanitize(scene_, s.view(), p_.nonfinite, p_.storage, threads_);
  bool same = true;
  for (int y = 0; y < scene_.height && same; ++y)
    same = std::equal(scene_.row(y), scene_.row(y) + std::size_t(scene_.width) * kChannels,
                      s.cview().row(y), [](float a, float b) {
                        return std::memcmp(&a, &b, sizeof a) == 0;
                      });
  if (same) {
    sanitized_ = scene_;
    return;
  }
  sanitized_owned_ = std::move(s);
  sanitized_ = sanitized_owned_.cview();
}

// The oracle's full run of one stage, stored as the device stores it.
void Comparison::oracle_full(const StageSpec& spec, const std::vector<std::string>& in) {
  if (cpu_) return;
  // f32 storage leaves the input stage the sanitised scene itself: read in place.
  if (spec.kind == StageKind::input && p_.storage == Storage::f32) {
    input_is_scene_ = true;
    return;
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<ConstImageView> cin;
  for (const std::string& n : in) cin.push_back(C(n));
  Image out = oracle_stage(plan_, spec, sanitized_, cin, profile_.subtexel_bits, pool_);
  store(out.view(), p_.storage, rounding_, threads_);
  full_[spec.name] = std::move(out);
  oracle_time_ +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The comparison's images, by stage name, as the stages' terms read them.
TermInputs Comparison::inputs() {
  return {plan_, profile_, ctx_, sanitized_, pool_,
          [this](const std::string& n) { return V(n); },
          [this](const std::string& n) { return E(n); },
          [this](const std::string& n) { return C(n); },
          [this](const std::string& n) { return e2e_rows(n); }};
}

// Whether a stage's end-to-end bound is made again where it is read instead of kept: the input
// stage's (a function of the scene, held anyway; kept for a downsample, which reads it through
// windows), which the composite reads at the end of the run.
bool Comparison::e2e_made_again(const std::string& n) const {
  if (n != "input") return false;
  for (const StageSpec& s : plan_.stages)
    if (s.kind == StageKind::down) {
      const std::vector<std::string> in = stage_inputs(plan_, s);
      if (std::find(in.begin(), in.end(), n) != in.end()) return false;
    }
  return true;
}

// R, G and B with the same bits (alpha is judged nowhere: a stage image's is 1 as read).
bool same_bits(ConstImageView a, ConstImageView b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y) {
    const float *p = a.row(y), *q = b.row(y);
    if (std::memcmp(p, q, std::size_t(a.width) * kChannels * sizeof(float)) == 0) continue;
    for (int x = 0; x < a.width; ++x)
      if (std::memcmp(p + std::size_t(x) * kChannels, q + std::size_t(x) * kChannels,
                      3 * sizeof(float)) != 0)
        return false;
  }
  return true;
}

ParityResult Comparison::run(double* oracle_ms) {
  sanitize_scene();
  input_e2e_ = input_bounds(sanitized_, ctx_);
  // The stages after the last capture are judged nowhere: neither recomputed nor bounded.
  std::size_t end = 0;
  for (std::size_t index = 0; index < plan_.stages.size(); ++index)
    if (streams_.captured(plan_.stages[index].name)) end = index + 1;
  for (std::size_t index = 0; index < end; ++index) {
    const StageSpec& spec = plan_.stages[index];
    spec_ = &spec;
    name_ = spec.name;
    const std::vector<std::string> in = stage_inputs(plan_, spec);
    oracle_full(spec, in);
    if (streams_.captured(name_)) {
      Held& h = captures_[name_] = load_(name_);
      // A capture of the input stage with the sanitised scene's bits in R, G and B (the usual
      // case) is read there: the composite reads it at the end of the run, and it need not be
      // held twice.
      if (spec.kind == StageKind::input && same_bits(h.view, sanitized_)) {
        h.owned = Image();
        h.view = sanitized_;
      }
    }
    // A blur or composite reads no full-run input for its bounds: release those now.
    if (!cpu_ && (spec.kind == StageKind::blur || spec.kind == StageKind::composite))
      for (const std::string& n : in)
        if (!streams_.read_after(n, static_cast<int>(index)) && full_.count(n)) {
          pool_.give(full_.at(n));
          full_.erase(n);
        }
    TermInputs terms = inputs();
    // A bright image that is not captured is the specification's (check --shaders uploads the
    // oracle's): only a captured one was read from the scene at interpolated coordinates.
    if (spec.kind == StageKind::bright && !streams_.captured(name_))
      terms.ctx.interpolated_reads = false;
    StageTerms t = stage_terms(spec, in, terms);
    if (streams_.captured(name_)) judge_captured(index, t);
    else keep_uncaptured(index, t);
    pool_.give(t.oracle);
    auto recycle = [this](auto& img) { pool_.give(img); };
    streams_.release_chain(static_cast<int>(index), recycle, captures_, computed_);
    streams_.release_read(static_cast<int>(index), recycle, full_, e2e_, carried_);
  }
  if (oracle_ms) *oracle_ms = oracle_time_;
  return finish();
}

// One band of a captured stage: its bounds made, then both comparisons (none when `judge` is
// false: a capture of another size).
void Comparison::band_captured(int y0, int y1, StageTerms& t, Tally& iso, Tally& e2e, Kept kept,
                               bool judge) {
  const CapturedStage cap = capture(name_);
  const StageOverride* over = stage_override(profile_, name_);
  const std::size_t n = std::size_t(y1 - y0) * t.oracle.width(), values = n * kChannels;
  const bool codes = judge && cap.code_bits > 0;
  BandScratch& s = band_scratch();
  float* bound = BandScratch::rows(s.bound, values);
  float* rounding = BandScratch::rows(s.rounding, values);
  float* inherited = t.inherited ? BandScratch::rows(s.inherited, values) : nullptr;
  float* e = BandScratch::rows(s.e2e, values);
  // The bound from the oracle as computed; the rounding part after an 8-bit capture's clamp.
  t.bound->rows(y0, y1, bound, codes ? nullptr : rounding);
  t.end_to_end(y0, y1, bound, e);
  if (kept.e2e) put_rows(*kept.e2e, y0, e, n);
  if (!judge) return;
  if (inherited) {
    t.inherited(y0, y1, bound, inherited);
    if (kept.inherited) put_rows(*kept.inherited, y0, inherited, n);
    add_rows(bound, inherited, n);
  }
  float* oracle = t.oracle.pixel(0, y0);
  const float* full = C(name_).row(y0);
  float* q = codes ? BandScratch::rows(s.codes, values) : nullptr;
  if (codes) {
    capture_codes(cap, oracle, q, n);
    add_rows(bound, q, n);
    t.bound->rows(y0, y1, nullptr, rounding);
    float* o2 = BandScratch::rows(s.oracle_e2e, values);
    float* q2 = BandScratch::rows(s.codes_e2e, values);
    std::copy(full, full + values, o2);
    capture_codes(cap, o2, q2, n);
    add_rows(e, q2, n);
    full = o2;
  }
  override_rows(over, bound, n);
  override_rows(over, e, n);
  if (kept.bound) put_rows(*kept.bound, y0, bound, n);
  // The gates measure the error beyond rounding: the stage's own (its storage and arithmetic
  // terms, scaled as an override scales the bound) and the capture's codes; with f16 storage,
  // also what stages without capture carry, which holds their roundings (llvmpipe's toward zero
  // is biased: half an ULP a stage on average, as systematic as the offsets the gates look for).
  if (over && over->scale != 1.0)
    for (std::size_t i = 0; i < values; ++i) rounding[i] = static_cast<float>(rounding[i] * over->scale);
  if (codes) add_rows(rounding, q, n);
  const float* slack = p_.storage == Storage::f16 ? inherited : nullptr;
  const std::size_t row = std::size_t(t.oracle.width()) * kChannels;
  for (int y = y0; y < y1; ++y) {
    const std::size_t at = std::size_t(y - y0) * row;
    judge_row(iso_rules_, y, cap.image.row(y), oracle + at, bound + at, rounding + at,
              slack ? slack + at : nullptr, iso);
    judge_row(e2e_rules_, y, cap.image.row(y), full + at, e + at, nullptr, nullptr, e2e);
  }
}

// Runs `band(y0, y1, tally index)` over the stage's rows in bands of `rows`, on every thread.
template <class Band>
void over_bands(int height, int rows, int threads, Band band) {
  const int bands = (height + rows - 1) / rows;
  parallel_rows(bands, threads, [&](int b0, int b1) {
    for (int b = b0; b < b1; ++b) band(b * rows, std::min(height, (b + 1) * rows), b);
  });
}

// A captured stage: both comparisons, band by band; then, when it is not PASS, its causes, and
// the images the report keeps.
void Comparison::judge_captured(std::size_t index, StageTerms& t) {
  const CapturedStage cap = capture(name_);
  const int w = t.oracle.width(), h = t.oracle.height();
  const bool fits = cap.image.width == w && cap.image.height == h;
  const bool codes = cap.code_bits > 0;
  const StageOverride* over = stage_override(profile_, name_);
  const ImageGates& gates = over && over->has_gates ? over->gates : profile_.gates;
  const bool uniform = fits && uniform_rgb(t.oracle.cview(), codes);
  const std::size_t worst = static_cast<std::size_t>(opt_.worst_count);
  iso_rules_ = {p_.storage, &profile_, worst, true, gates.window > 0 && !uniform ? gates.window_size : 0, w};
  e2e_rules_ = {p_.storage, &profile_, worst, false, 0, w};
  // Images kept whole: the end-to-end bound for the stages that read it; with an 8-bit capture,
  // whose clamp changes the oracle the bounds read, the bound and what inputs carry as they were
  // judged (without one, they are made again when needed).
  Image e_kept, bound_kept, inherited_kept;
  Kept kept;
  if (streams_.read_after(name_, static_cast<int>(index)) && !e2e_made_again(name_))
    kept.e2e = &(e_kept = pool_.take(w, h));
  if (fits && codes && (opt_.causes || opt_.keep_images)) kept.bound = &(bound_kept = Image::uninitialised(w, h));
  if (fits && codes && t.inherited) kept.inherited = &(inherited_kept = Image::uninitialised(w, h));
  pool_.clear();
  const int rows = judge_band(iso_rules_.window);
  std::vector<Tally> iso((h + rows - 1) / rows), e2e(iso.size());
  over_bands(h, rows, threads_, [&](int y0, int y1, int b) {
    band_captured(y0, y1, t, iso[b], e2e[b], kept, fits);
  });
  if (kept.e2e) e2e_[name_] = std::move(e_kept);
  if (!fits) {
    result_.isolated.push_back(size_fault(name_, cap.image, t.oracle.cview()));
    result_.end_to_end.push_back(size_fault(name_, cap.image, t.oracle.cview()));
    return;
  }
  Tally iso_total, e2e_total;
  for (Tally& b : iso) iso_total.merge(std::move(b), worst);
  for (Tally& b : e2e) e2e_total.merge(std::move(b), worst);
  StageComparison s = conclude(name_, std::move(iso_total), iso_rules_, iso_terms(t, cap, inherited_kept),
                               &gates, uniform);
  const ExtraTerms e2e_terms(*t.bound, {{"8-bit capture: half a code", codes_of(cap, C(name_))}});
  result_.end_to_end.push_back(conclude(name_, std::move(e2e_total), e2e_rules_, e2e_terms, nullptr, false));
  const bool keep = opt_.keep_images && !(opt_.keep_failing_only && s.verdict == Verdict::pass);
  if ((opt_.causes && s.verdict != Verdict::pass) || keep) {
    Image bound = bound_kept.empty() ? final_bound(t) : std::move(bound_kept);
    if (opt_.causes && s.verdict != Verdict::pass) test_causes_of(*spec_, s, t.oracle, bound);
    if (keep) {
      s.oracle = std::move(t.oracle);
      s.bound = std::move(bound);
    }
  }
  result_.isolated.push_back(std::move(s));
}

// The worst values' extra terms of an isolated comparison: what inputs without capture carry
// (made again for one row, or read from `inherited` where it was kept) and the capture's codes.
ExtraTerms Comparison::iso_terms(const StageTerms& t, const CapturedStage& cap,
                                 const Image& inherited) const {
  ExtraTerms::Value carried;
  if (!inherited.empty())
    carried = [&inherited](int x, int y, int c) { return double(inherited.pixel(x, y)[c]); };
  else if (t.inherited)
    carried = [&t](int x, int y, int c) {
      const std::size_t n = std::size_t(t.oracle.width()) * kChannels;
      std::vector<float> b(n), out(n);
      t.bound->rows(y, y + 1, b.data(), nullptr);
      t.inherited(y, y + 1, b.data(), out.data());
      return double(out[std::size_t(x) * kChannels + c]);
    };
  return ExtraTerms(*t.bound, {{"carried from stages without capture", carried},
                               {"8-bit capture: half a code", codes_of(cap, t.oracle.cview())}});
}

// Half a code of an 8-bit capture at each value of `oracle` (clamped first: the values as
// judged); nothing for a float capture.
ExtraTerms::Value Comparison::codes_of(const CapturedStage& cap, ConstImageView oracle) const {
  if (cap.code_bits <= 0) return {};
  return [cap, oracle](int x, int y, int c) {
    float o = oracle.pixel(x, y)[c];
    return double(capture_code(cap, o));
  };
}

// The isolated bound as judged, whole: the stage's, what inputs without capture carry, the
// profile's override (no 8-bit capture: judge_captured keeps that one as it goes).
Image Comparison::final_bound(const StageTerms& t) {
  const int w = t.oracle.width(), h = t.oracle.height();
  const StageOverride* over = stage_override(profile_, name_);
  Image out = Image::uninitialised(w, h);
  over_bands(h, judge_band(0), threads_, [&](int y0, int y1, int) {
    const std::size_t n = std::size_t(y1 - y0) * w;
    BandScratch& s = band_scratch();
    float* bound = BandScratch::rows(s.bound, n * kChannels);
    t.bound->rows(y0, y1, bound, nullptr);
    if (t.inherited) {
      float* inherited = BandScratch::rows(s.inherited, n * kChannels);
      t.inherited(y0, y1, bound, inherited);
      add_rows(bound, inherited, n);
    }
    override_rows(over, bound, n);
    put_rows(out, y0, bound, n);
  });
  return out;
}

// The cause hypotheses of a stage that is not PASS, each judged with the stage's bound plus its
// own rounding: a hypothesis changes the stage's arithmetic, which the bound was derived for, so
// 32 f32 ULPs of its value (the stages' longest chain, a 9-tap sum, rounds 2 x 9 + 3 times); and
// so is the oracle itself for the baseline, so that a hypothesis equal to the oracle scores the
// same.
void Comparison::test_causes_of(const StageSpec& spec, StageComparison& iso, Image& oracle,
                                const Image& bound) {
  const CapturedStage cap = capture(name_);
  const CauseContext cc{plan_, sanitized_, profile_, rounding_, threads_,
                        [this](const std::string& n) { return V(n); },
                        [this](const std::string& n) { return streams_.captured(n); }};
  auto score = [&](Image& variant) {
    if (cap.code_bits > 0) {
      std::vector<float> q(variant.values().size());
      capture_codes(cap, variant.data(), q.data(), variant.pixel_count());
    }
    return within_bound(cap.image, variant.cview(), bound, 32 * kU, p_.storage, profile_, threads_);
  };
  const double oracle_score = score(oracle);
  iso.causes = test_causes(cc, spec, oracle_score, score);
}

// A stage without capture: the oracle's recomputation stored as the device stores it, carrying
// its bound, what it inherited, and the storage rounding of the recomputed value.
void Comparison::keep_uncaptured(std::size_t index, StageTerms& t) {
  const int w = t.oracle.width(), h = t.oracle.height();
  const bool read_later = streams_.read_after(name_, static_cast<int>(index));
  Image e_kept = read_later && !e2e_made_again(name_) ? pool_.take(w, h) : Image();
  Image carried = read_later ? pool_.take(w, h) : Image();
  pool_.clear();
  over_bands(h, judge_band(0), threads_, [&](int y0, int y1, int) {
    const std::size_t n = std::size_t(y1 - y0) * w, values = n * kChannels;
    BandScratch& s = band_scratch();
    float* bound = BandScratch::rows(s.bound, values);
    float* e = BandScratch::rows(s.e2e, values);
    t.bound->rows(y0, y1, bound, nullptr);
    t.end_to_end(y0, y1, bound, e);
    if (t.inherited) {
      float* inherited = BandScratch::rows(s.inherited, values);
      t.inherited(y0, y1, bound, inherited);
      add_rows(bound, inherited, n);
    }
    float* unrounded = BandScratch::rows(s.kept, values);
    float* o = t.oracle.pixel(0, y0);
    std::copy(o, o + values, unrounded);
    store(ImageView{w, y1 - y0, w, o}, p_.storage, rounding_, 1);
    for (std::size_t i = 0; i < values; ++i) bound[i] += std::fabs(o[i] - unrounded[i]);
    if (!e_kept.empty()) put_rows(e_kept, y0, e, n);
    if (read_later) put_rows(carried, y0, bound, n);
  });
  computed_[name_] = std::move(t.oracle);
  if (!e_kept.empty()) e2e_[name_] = std::move(e_kept);
  if (read_later) carried_[name_] = std::move(carried);
}

ParityResult Comparison::finish() {
  for (const StageComparison& s : result_.isolated) {
    if (s.verdict != Verdict::pass && !result_.first_divergent_stage)
      result_.first_divergent_stage = s.stage;
    result_.verdict = std::max(result_.verdict, s.verdict);
  }
  for (const StageComparison& s : result_.end_to_end)
    result_.verdict = std::max(result_.verdict, s.verdict);
  return std::move(result_);
}

}  // namespace

ParityResult compare_captured(const Plan& plan, ConstImageView scene,
                              const CapturedStages& captured, const StageTrace& cpu,
                              const DeviceProfile& profile, const CompareOptions& opt) {
  std::vector<std::string> names;
  for (const auto& [name, c] : captured) names.push_back(name);
  const std::function<Held(const std::string&)> load = [&](const std::string& n) {
    const CapturedStage& c = captured.at(n);
    return Held{c.image, {}, c.code_bits, c.srgb};
  };
  return Comparison(plan, scene, names, load, &cpu, profile, opt).run(nullptr);
}

ParityResult check_with_oracle(const Plan& plan, ConstImageView scene,
                               const CapturedStages& captured, const DeviceProfile& profile,
                               const CompareOptions& opt, double* cpu_ms) {
  std::vector<std::string> names;
  for (const auto& [name, c] : captured) names.push_back(name);
  const std::function<Held(const std::string&)> load = [&](const std::string& n) {
    const CapturedStage& c = captured.at(n);
    return Held{c.image, {}, c.code_bits, c.srgb};
  };
  return Comparison(plan, scene, names, load, nullptr, profile, opt).run(cpu_ms);
}

ParityResult compare_streamed(const Plan& plan, ConstImageView scene,
                              const std::vector<std::string>& captured, const CaptureLoader& load,
                              const DeviceProfile& profile, const CompareOptions& opt,
                              double* oracle_ms) {
  const std::function<Held(const std::string&)> held = [&](const std::string& n) {
    OwnedCapture o = load(n);
    Held h{{}, std::move(o.image), o.code_bits, o.srgb};
    h.view = h.owned.cview();
    return h;
  };
  return Comparison(plan, scene, captured, held, nullptr, profile, opt).run(oracle_ms);
}

}  // namespace bloomref::parity
