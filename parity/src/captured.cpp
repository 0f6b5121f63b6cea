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
#include <optional>
#include <set>
#include <tuple>
#include <cfloat>
#include <cstdio>

#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "causes.h"
#include "chain.h"
#include "energy.h"
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

// What a band adds up for the gain gates (energy.h), per channel: finite values only (NaN/Inf
// where the other side has none fails by itself). `tile_*` per 32-column tile of the band.
constexpr int kTile = 32;
struct EnergySums {
  using Sum = std::array<double, 3>;
  Sum err{}, err_e2e{}, oracle{}, full{}, l1{}, l1_e2e{}, l1_own{}, up{}, down{}, most{}, rounding{};
  Sum storage{};  // a stage without capture: the oracle's value's own storage rounding
  Sum carried{}, judged{};  // a captured stage: what inputs without capture carry, its bound
  double tile_ratio = 0;
  int tile_x = -1, tile_y = -1;
  // The envelope gate's: the capture's error, and the envelope's distance from the oracle
  // either way (plus the rounding terms), over the values where all are finite; how many
  // values lie beyond it, and the worst tile's total error over its envelope's.
  Sum env_err{}, env_up{}, env_down{};
  std::size_t env_values = 0, env_outside = 0;
  double env_tile_ratio = 0;
  void merge(const EnergySums& b) {
    for (int c = 0; c < 3; ++c) {
      err[c] += b.err[c], err_e2e[c] += b.err_e2e[c], oracle[c] += b.oracle[c];
      full[c] += b.full[c], l1[c] += b.l1[c], l1_e2e[c] += b.l1_e2e[c], l1_own[c] += b.l1_own[c];
      up[c] += b.up[c], down[c] += b.down[c], most[c] += b.most[c], rounding[c] += b.rounding[c];
      storage[c] += b.storage[c], carried[c] += b.carried[c], judged[c] += b.judged[c];
    }
    if (b.tile_ratio > tile_ratio) tile_ratio = b.tile_ratio, tile_x = b.tile_x, tile_y = b.tile_y;
    for (int c = 0; c < 3; ++c)
      env_err[c] += b.env_err[c], env_up[c] += b.env_up[c], env_down[c] += b.env_down[c];
    env_values += b.env_values;
    env_outside += b.env_outside;
    env_tile_ratio = std::max(env_tile_ratio, b.env_tile_ratio);
  }
};

// A total error against its budgets: the ratio, over the sign's budget. A stage whose every
// value errs by exactly its bound, one way (f16 rounding toward zero on a constant image), has
// a total error equal to the sum of its bounds: the budget is widened by far more than the
// double sums' rounding (n 2^-53 of it) so that such a stage sits at 1, not above.
double budget_ratio(double err, double up, double down) {
  const double b = (err > 0 ? up : down) * (1 + 1e-6);
  if (err == 0) return 0;
  if (!(b >= 0) || !std::isfinite(b)) return 0;  // no budget can be derived (NaN/Inf around)
  return b > 0 ? std::fabs(err) / b : INFINITY;
}

// The error and budgets of one stage, for the stages after it: what its value may be off by
// in total, against the isolated oracle (`chain`: zero for a capture) and the full run (`e2e`),
// a bound on the total variation of its isolated error (`tv`) and one on the sum of its
// magnitudes (`mass`).
struct Energy {
  SignedBudget chain, e2e;
  std::array<double, 3> tv{};
  std::array<double, 3> mass{};  // a bound on the sum of the isolated error's magnitudes
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
  void band_captured(int y0, int y1, StageTerms& t, Tally& iso, Tally& e2e, Kept kept, bool judge,
                     EnergySums& es);
  void deviation_band(int y0, int y1, float*& up, float*& down) const;
  void energy_band(int y0, int y1, bool gl, const float* oracle, const float* full,
                   const float* bound, const float* rounding, const float* inherited,
                   const float* e, const float* up,
                   const float* down, EnergySums& es) const;
  struct Budgets {
    SignedBudget iso, e2e;
    std::optional<std::array<double, 3>> tv, mass;
  };
  Budgets signed_budgets(const std::vector<std::string>& in, const EnergySums& es) const;
  // The likely cause named at the last failing stage of each kind, and that stage.
  std::map<StageKind, std::pair<std::string, std::string>> last_cause_;
  void carried_into(StageComparison& s, const EnergySums& es) const;
  void gain_gates(StageComparison& iso, StageComparison& e2e, const EnergySums& es,
                  const std::vector<std::string>& in);
  ExtraTerms iso_terms(const StageTerms& t, const CapturedStage& cap, const Image& inherited) const;
  ExtraTerms::Value codes_of(const CapturedStage& cap, ConstImageView oracle) const;
  Image final_bound(const StageTerms& t);
  void test_causes_of(const StageSpec& spec, StageComparison& iso, Image& oracle,
                      const Image& bound);
  void keep_uncaptured(std::size_t index, StageTerms& t);
  // A stage's envelope: below and above every value a device the profile allows could write
  // there, given only what it read (docs/design.md, "Envelopes").
  struct Envelope {
    Image lo, hi;
    bool empty() const { return hi.empty(); }
  };
  Envelope carried_range(const std::string& n) const;
  void make_envelope(const StageSpec& spec);
  void make_finish_envelope(const StageSpec& spec);
  void widen(const float* base, float* H, float* L, std::size_t values) const;
  void envelope_rows(int y0, int y1, const float* oracle, const float* up, const float* down,
                     float* H, float* L) const;
  void narrow_to_envelope(const Image& oracle, ConstImageView cap, Image& bound) const;
  void envelope_band(int y0, int y1, ConstImageView cap, const float* oracle,
                     const float* rounding, const float* up, const float* down,
                     EnergySums& es) const;
  void envelope_gate(StageComparison& iso, const EnergySums& es) const;
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
  // How a stage's output is stored: the mip chain's levels as the chain stores them.
  Storage storage_at(const StageSpec& s) const { return stage_storage(p_, s); }
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
  std::map<std::string, Energy> energy_;   // each stage's, for the stages that read it
  std::unique_ptr<BlurDeviation> deviation_;  // of the blur pass being judged (when usable)
  std::map<std::string, Envelope> envelope_;  // of stages without capture, for their readers
  Envelope env_;                           // of the stage being judged or kept (or none)
  bool env_from_deviation_ = false;        // its envelope is the oracle +- deviation_
  bool intervals_done_ = false;            // a fitted cause's interval found (the first stage)
  int stage_width_ = 0;                    // its width
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
  store(out.view(), storage_at(spec), rounding_, threads_);
  full_[spec.name] = std::move(out);
  oracle_time_ +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The comparison's images, by stage name, as the stages' terms read them.
TermInputs Comparison::inputs() {
  BoundContext ctx = ctx_;
  if (spec_) ctx.storage = storage_at(*spec_);
  return {plan_, profile_, ctx, sanitized_, pool_,
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
    const bool judged = streams_.captured(name_);
    if (judged) judge_captured(index, t);
    else keep_uncaptured(index, t);
    pool_.give(t.oracle);
    auto recycle = [this](auto& img) { pool_.give(img); };
    streams_.release_chain(static_cast<int>(index), recycle, captures_, computed_);
    streams_.release_read(static_cast<int>(index), recycle, full_, e2e_, carried_);
    if (judged && opt_.stop_at_first_fail &&
        (result_.isolated.back().verdict == Verdict::fail ||
         result_.end_to_end.back().verdict == Verdict::fail))
      break;
  }
  if (oracle_ms) *oracle_ms = oracle_time_;
  return finish();
}

// One band of a captured stage: its bounds made, then both comparisons (none when `judge` is
// false: a capture of another size).
void Comparison::band_captured(int y0, int y1, StageTerms& t, Tally& iso, Tally& e2e, Kept kept,
                               bool judge, EnergySums& es) {
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
  if (inherited) {
    // The carried part as judged: a profile's override scales it with the rest of the bound.
    const double scale = over ? over->scale : 1.0;
    for (std::size_t i = 0; i < values; ++i)
      if (i % kChannels != 3 && std::isfinite(bound[i]) && std::isfinite(inherited[i]))
        es.carried[i % kChannels] += scale * inherited[i], es.judged[i % kChannels] += bound[i];
  }
  // The gates measure the error beyond rounding: the stage's own (its storage and arithmetic
  // terms, scaled as an override scales the bound) and the capture's codes; with f16 (or
  // packed, or 8-bit) storage, also what stages without capture carry, which holds their
  // roundings (llvmpipe's toward zero is biased: half an ULP a stage on average, as systematic
  // as the offsets the gates look for).
  if (over && over->scale != 1.0)
    for (std::size_t i = 0; i < values; ++i) rounding[i] = static_cast<float>(rounding[i] * over->scale);
  if (codes) add_rows(rounding, q, n);
  const float* slack = p_.storage != Storage::f32 ? inherited : nullptr;
  float *up, *down;
  deviation_band(y0, y1, up, down);
  energy_band(y0, y1, true, oracle, full, bound, rounding, inherited, e, up, down, es);
  if ((!env_.empty() || env_from_deviation_) && !codes)
    envelope_band(y0, y1, cap.image, oracle, rounding, up, down, es);
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

// A stage without capture give or take the error it carries (E), rounded outward: the range
// a device's image of it lies in, for the envelopes of the stages that read it.
Comparison::Envelope Comparison::carried_range(const std::string& n) const {
  const ConstImageView v = V(n);
  const ConstImageView e = E(n)->cview();
  Envelope r{Image::uninitialised(v.width, v.height), Image::uninitialised(v.width, v.height)};
  for (int y = 0; y < v.height; ++y) {
    const float *a = v.row(y), *b = e.row(y);
    float *l = r.lo.pixel(0, y), *h = r.hi.pixel(0, y);
    for (std::size_t i = 0; i < std::size_t(v.width) * kChannels; ++i) {
      const bool alpha = i % kChannels == 3;
      l[i] = alpha ? a[i] : next_down(a[i] - b[i]);
      h[i] = alpha ? a[i] : next_up(a[i] + b[i]);
    }
  }
  return r;
}

// The envelope of a blur pass (env_), from what it reads: a capture exactly, the envelope of a
// pass without capture before it, or another stage without capture give or take the error it
// carries. Weights and the bilinear interpolant are non-negative, so a device's pass is
// monotone in its input: its value lies between the lowest and the highest its lookups could
// take (BlurDeviation: exact over the profile's shifts) on the envelope's low and high images,
// widened (widen). None where a shift reaches a texel.
void Comparison::make_envelope(const StageSpec& spec) {
  env_ = Envelope{};
  if (spec.kind != StageKind::blur) return;
  const std::string in = stage_inputs(plan_, spec)[0];
  ConstImageView lo, hi;
  Envelope own;
  const auto prev = envelope_.find(in);
  if (streams_.captured(in)) {
    lo = hi = V(in);
  } else if (prev != envelope_.end()) {
    lo = prev->second.lo.cview();
    hi = prev->second.hi.cview();
  } else if (E(in)) {
    own = carried_range(in);
    lo = own.lo.cview();
    hi = own.hi.cview();
  } else {
    return;
  }
  if (!lo.data || !hi.data) return;
  const BlurDeviation dl(lo, spec.axis, kernel_, profile_), dh(hi, spec.axis, kernel_, profile_);
  if (!dl.usable() || !dh.usable()) return;
  Envelope env{oracle_stage(plan_, spec, sanitized_, {lo}, profile_.subtexel_bits, pool_),
               oracle_stage(plan_, spec, sanitized_, {hi}, profile_.subtexel_bits, pool_)};
  const int w = env.hi.width();
  over_bands(env.hi.height(), judge_band(0), threads_, [&](int y0, int y1, int) {
    const std::size_t values = std::size_t(y1 - y0) * w * kChannels;
    float* const up = BandScratch::rows(band_scratch().envelope, 4 * values);
    float *const down = up + values, *const up_lo = down + values, *const down_lo = up_lo + values;
    dh.rows(y0, y1, up, down);
    dl.rows(y0, y1, up_lo, down_lo);
    float *H = env.hi.pixel(0, y0), *L = env.lo.pixel(0, y0);
    for (std::size_t i = 0; i < values; ++i) up[i] += H[i], down_lo[i] = L[i] - down_lo[i];
    widen(nullptr, up, down_lo, values);
    std::copy(up, up + values, H);
    std::copy(down_lo, down_lo + values, L);
  });
  if (prev != envelope_.end()) envelope_.erase(prev);
  env_ = std::move(env);
}

// The envelope of a finishing stage (the composite, the tone map, the output; env_) whose
// inputs include a stage without capture that has one. Each is monotone in every input (the
// composite for a strength in [0, 1] under mix, or not negative under add; the tone map for a
// positive exposure; the output for a positive gamma), so the envelope is the stage's value at
// its inputs' low and high ends: captures exactly, stages without capture their envelope or
// the error they carry. The composite's reads at interpolated coordinates may blend in up to
// 2d of the neighbours' difference (d: coordinate_error; bilinear weights off their texel sum
// to at most 2d); then each end is widened by the stage's arithmetic (the composite's two
// roundings twice over; exp's (3 + 2|x|) ULP, absolute, and the series', at most 64 ULPs of 1;
// pow's exp2 and log2 ULPs relative, (8 + 6|y log2 x|) ULP, and log2's 2^-21 absolute as 2^-20
// relative), the denormal floor and one storage rounding. None where d reaches a texel.
void Comparison::make_finish_envelope(const StageSpec& spec) {
  const StageKind k = spec.kind;
  if (k != StageKind::composite && k != StageKind::tonemap && k != StageKind::output) return;
  env_ = Envelope{};
  const std::vector<std::string> in = stage_inputs(plan_, spec);
  bool any = false;
  for (const std::string& n : in) any = any || envelope_.count(n);
  if (!any) return;
  const double s = p_.strength;
  if (k == StageKind::composite &&
      (p_.composite_mode == CompositeMode::mix ? !(s >= 0 && s <= 1) : !(s >= 0)))
    return;
  if ((k == StageKind::tonemap && !(p_.exposure > 0)) || (k == StageKind::output && !(p_.gamma > 0)))
    return;
  std::vector<ConstImageView> lo, hi;
  std::vector<Envelope> own;
  own.reserve(in.size());
  for (const std::string& n : in) {
    const auto e = envelope_.find(n);
    if (streams_.captured(n)) {
      lo.push_back(V(n));
      hi.push_back(V(n));
    } else if (e != envelope_.end()) {
      lo.push_back(e->second.lo.cview());
      hi.push_back(e->second.hi.cview());
    } else if (E(n)) {
      const Envelope& c = own.emplace_back(carried_range(n));
      lo.push_back(c.lo.cview());
      hi.push_back(c.hi.cview());
    } else {
      return;
    }
    if (!lo.back().data || lo.back().width != lo[0].width || lo.back().height != lo[0].height) return;
  }
  const int w = lo[0].width, h = lo[0].height;
  const double d = k == StageKind::composite && opt_.interpolated_reads
                       ? std::max(coordinate_error(w, profile_), coordinate_error(h, profile_))
                       : 0.0;
  if (d >= 1) return;
  const double U = profile_.unit_roundoff, floor = denormal_floor(profile_);
  const Storage st = storage_at(spec);
  // A read at interpolated coordinates: the texel's value moved toward its 3x3 neighbours'
  // extreme by up to 2d of the difference.
  auto read = [d](ConstImageView v, int x, int y, int c, bool up) {
    const double at = v.pixel(x, y)[c];
    if (d == 0) return at;
    double ext = at;
    for (int j = std::max(0, y - 1); j <= std::min(v.height - 1, y + 1); ++j)
      for (int i = std::max(0, x - 1); i <= std::min(v.width - 1, x + 1); ++i)
        ext = up ? std::max(ext, double(v.pixel(i, j)[c])) : std::min(ext, double(v.pixel(i, j)[c]));
    return at + 2 * d * (ext - at);
  };
  Envelope env{Image::uninitialised(w, h), Image::uninitialised(w, h)};
  const double y_exp = 1.0 / p_.gamma;
  over_bands(h, judge_band(0), threads_, [&](int y0, int y1, int) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        float *H = env.hi.pixel(x, y), *L = env.lo.pixel(x, y);
        H[3] = L[3] = 1.0f;
        for (int c = 0; c < 3; ++c) {
          double top = 0, bottom = 0, margin_top = 0, margin_bottom = 0;
          if (k == StageKind::composite) {
            const double ah = read(hi[0], x, y, c, true), al = read(lo[0], x, y, c, false);
            const double bh = read(hi[1], x, y, c, true), bl = read(lo[1], x, y, c, false);
            const double a = p_.composite_mode == CompositeMode::mix ? 1 - s : 1.0;
            top = a * ah + s * bh;
            bottom = a * al + s * bl;
            margin_top = 4 * U * (std::fabs(ah) + std::fabs(s * bh) + std::fabs(top));
            margin_bottom = 4 * U * (std::fabs(al) + std::fabs(s * bl) + std::fabs(bottom));
          } else if (k == StageKind::tonemap) {
            top = -std::expm1(-double(hi[0].pixel(x, y)[c]) * p_.exposure);
            bottom = -std::expm1(-double(lo[0].pixel(x, y)[c]) * p_.exposure);
            margin_top = margin_bottom = 64 * U;
          } else {
            const double th = std::max(double(hi[0].pixel(x, y)[c]), 0.0);
            const double tl = std::max(double(lo[0].pixel(x, y)[c]), 0.0);
            top = std::pow(th, y_exp);
            bottom = std::pow(tl, y_exp);
            auto rel = [&](double t) {
              return (8 + 6 * std::fabs(y_exp * std::log2(std::max(t, 0x1p-126)))) * U + 0x1p-20;
            };
            margin_top = top * rel(th) + std::pow(0x1p-126, y_exp);
            margin_bottom = bottom * rel(tl) + std::pow(0x1p-126, y_exp);
          }
          const double t = top + margin_top + floor, b = bottom - margin_bottom - floor;
          H[c] = next_up(static_cast<float>(t + storage_term(t, st, profile_, c)));
          L[c] = next_down(static_cast<float>(b - storage_term(b, st, profile_, c)));
        }
      }
  });
  for (const std::string& n : in) envelope_.erase(n);
  env_ = std::move(env);
}

// The envelope's ends from a pass's highest and lowest sums (H and L; with `base`, base + H and
// base - L), widened by the pass's arithmetic (32 f32 ULPs of the profile's unit roundoff,
// above the (3 + 2 taps) roundings of a 9-tap pass), the denormal floor and its storage, and
// rounded outward to float.
void Comparison::widen(const float* base, float* H, float* L, std::size_t values) const {
  const Storage st = storage_at(*spec_);
  const double arithmetic = 32 * profile_.unit_roundoff, floor = denormal_floor(profile_);
  if (st == Storage::f32) {  // no storage term (storage_term): loops that vectorise
    const auto ends = [&](auto with_base) {
      for (std::size_t i = 0; i < values; i += kChannels)
        for (std::size_t c = 0; c < 3; ++c) {
          double a = H[i + c], b = L[i + c];
          if constexpr (decltype(with_base)::value) a = base[i + c] + a, b = base[i + c] - b;
          H[i + c] = next_up(static_cast<float>(a + std::fabs(a) * arithmetic + floor));
          L[i + c] = next_down(static_cast<float>(b - std::fabs(b) * arithmetic - floor));
        }
    };
    if (base) ends(std::true_type{});
    else ends(std::false_type{});
    return;
  }
  for (std::size_t i = 0; i < values; ++i) {
    const int c = static_cast<int>(i % kChannels);
    if (c == 3) continue;
    const double a = base ? double(base[i]) + H[i] : double(H[i]);
    const double b = base ? double(base[i]) - L[i] : double(L[i]);
    H[i] = next_up(static_cast<float>(a + std::fabs(a) * arithmetic + floor +
                                      storage_term(a, st, profile_, c)));
    L[i] = next_down(static_cast<float>(b - std::fabs(b) * arithmetic - floor -
                                        storage_term(b, st, profile_, c)));
  }
}

// The envelope's rows [y0, y1) of the stage being judged into H and L: env_'s, or (a blur pass
// that read a capture) the oracle's rows moved by its lookups' deviation either way.
void Comparison::envelope_rows(int y0, int y1, const float* oracle, const float* up,
                               const float* down, float* H, float* L) const {
  const std::size_t n = std::size_t(y1 - y0) * stage_width_ * kChannels;
  if (!env_.empty()) {
    std::copy(env_.hi.cview().row(y0), env_.hi.cview().row(y0) + n, H);
    std::copy(env_.lo.cview().row(y0), env_.lo.cview().row(y0) + n, L);
    return;
  }
  std::copy(up, up + n, H);
  std::copy(down, down + n, L);
  widen(oracle, H, L, n);
}

// The bound causes are scored with when the stage has an envelope: each value's bound narrowed
// to the envelope's distance from the oracle on the side the capture lies. A stage that fails
// by a gate has its values within their bounds, and every hypothesis would score as the oracle
// does; within the envelope, the one that makes the capture's values explains them.
void Comparison::narrow_to_envelope(const Image& oracle, ConstImageView cap, Image& bound) const {
  const int w = oracle.width();
  over_bands(oracle.height(), judge_band(0), threads_, [&](int y0, int y1, int) {
    const std::size_t n = std::size_t(y1 - y0) * w * kChannels;
    float* const rows = BandScratch::rows(band_scratch().envelope, 2 * n);
    float *up = nullptr, *down = nullptr;
    if (env_.empty()) deviation_band(y0, y1, up, down);
    envelope_rows(y0, y1, oracle.cview().row(y0), up, down, rows, rows + n);
    const float *o = oracle.cview().row(y0), *g = cap.row(y0);
    float* b = bound.pixel(0, y0);
    for (std::size_t i = 0; i < n; ++i) {
      if (i % kChannels == 3) continue;
      const double d = std::max(g[i] >= o[i] ? double(rows[i]) - o[i] : o[i] - double(rows[n + i]), 0.0);
      if (d < b[i]) b[i] = static_cast<float>(d);
    }
  });
}

// A band's envelope sums (EnergySums::env_*), of the captured blur pass being judged: each
// value's error against the envelope's distance from the oracle on its side, plus the stage's
// rounding terms (the oracle's own, which the envelope's arithmetic term may not cover for a
// value near 0), whole and per tile.
void Comparison::envelope_band(int y0, int y1, ConstImageView cap, const float* oracle,
                               const float* rounding, const float* up, const float* down,
                               EnergySums& es) const {
  const int w = stage_width_, tiles = (w + kTile - 1) / kTile;
  const std::size_t values = std::size_t(y1 - y0) * w * kChannels;
  float* const rows = BandScratch::rows(band_scratch().envelope, 2 * values);
  envelope_rows(y0, y1, oracle, up, down, rows, rows + values);
  for (int y = y0; y < y1; ++y) {
    const std::size_t at0 = std::size_t(y - y0) * w * kChannels;
    const float *H = rows + at0, *L = rows + values + at0, *g = cap.row(y);
    for (int t = 0; t < tiles; ++t) {
      EnergySums::Sum te{}, tu{}, td{};
      for (int x = t * kTile; x < std::min(w, (t + 1) * kTile); ++x)
        for (int c = 0; c < 3; ++c) {
          const std::size_t i = std::size_t(x) * kChannels + c;
          const double o = oracle[at0 + i], v = g[i], hi = H[i], lo = L[i];
          if (!std::isfinite(o) || !std::isfinite(v) || !std::isfinite(hi) || !std::isfinite(lo))
            continue;
          const double r = rounding ? rounding[at0 + i] : 0.0;
          const double up = std::max(hi - o, 0.0) + r, down = std::max(o - lo, 0.0) + r;
          te[c] += v - o, tu[c] += up, td[c] += down;
          ++es.env_values;
          es.env_outside += v > hi + r || v < lo - r;
        }
      for (int c = 0; c < 3; ++c) {
        es.env_err[c] += te[c], es.env_up[c] += tu[c], es.env_down[c] += td[c];
        es.env_tile_ratio = std::max(es.env_tile_ratio, budget_ratio(te[c], tu[c], td[c]));
      }
    }
  }
}

// The envelope gate of a captured blur pass that read a stage without capture: no device the
// profile allows could write a value beyond the envelope, nor a total beyond the envelope's
// (over the image and over each tile). More than the profile's over_fraction of the values
// beyond it, or a total beyond it, fails.
void Comparison::envelope_gate(StageComparison& s, const EnergySums& es) const {
  if (es.env_values == 0) return;
  const StageOverride* over = stage_override(profile_, name_);
  if (over && (over->scale != 1.0 || over->absolute != 0.0)) return;  // widened on purpose
  const ImageGates& gates = over && over->has_gates ? over->gates : profile_.gates;
  s.envelope_outside = double(es.env_outside) / double(es.env_values);
  int worst = 0;
  double whole = 0;
  for (int c = 0; c < 3; ++c) {
    const double r = budget_ratio(es.env_err[c], es.env_up[c], es.env_down[c]);
    if (r > whole) whole = r, worst = c;
  }
  s.envelope_ratio = std::max(whole, es.env_tile_ratio);
  const bool by_values = gates.over_fraction > 0 && s.envelope_outside > gates.over_fraction;
  const bool by_total = gates.gain > 0 && s.envelope_ratio > gates.gain;
  if (!by_values && !by_total) return;
  char buf[240];
  if (by_total && whole > gates.gain) {
    const double total = es.oracle[worst];
    const double reach = total != 0 ? 1 + es.env_up[worst] / std::fabs(total) : INFINITY;
    std::snprintf(buf, sizeof buf,
                  "the total of %s is %.4gx the oracle's; from what this pass read, a device the "
                  "profile allows reaches %.4gx at most (envelope gate: %.3gx its budget)",
                  worst == 0 ? "R" : worst == 1 ? "G" : "B", s.gain[worst], reach, whole);
  } else if (by_values) {
    std::snprintf(buf, sizeof buf,
                  "%.3g%% of the values lie beyond what any device the profile allows could "
                  "write from what this pass read (envelope gate: %.3g%% allowed)",
                  100 * s.envelope_outside, 100 * gates.over_fraction);
  } else {
    std::snprintf(buf, sizeof buf,
                  "a tile's total error is %.3gx what any device the profile allows could make "
                  "from what this pass read (envelope gate)",
                  es.env_tile_ratio);
  }
  if (s.gate.empty()) {
    s.gate_id = "envelope";
    s.gate = buf;
  }
  if (s.nonfinite_mismatch == 0 && s.beyond_tier == 0) {
    s.verdict = Verdict::fail;
    s.reason = "image gate: " + s.gate;
  }
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
  iso_rules_ = {storage_at(*spec_), &profile_, worst, true, gates.window > 0 && !uniform ? gates.window_size : 0, w};
  e2e_rules_ = {storage_at(*spec_), &profile_, worst, false, 0, w};
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
  deviation_.reset();
  stage_width_ = w;
  if (spec_->kind == StageKind::blur && !codes && fits) {
    deviation_ = std::make_unique<BlurDeviation>(V(stage_inputs(plan_, *spec_)[0]), spec_->axis,
                                                 kernel_, profile_);
    if (!deviation_->usable()) deviation_.reset();
    // From a captured input the envelope is the oracle's pass and its lookups' deviation
    // (envelope_band makes it band by band); otherwise it is carried (make_envelope).
    if (!streams_.captured(stage_inputs(plan_, *spec_)[0])) make_envelope(*spec_);
    else env_from_deviation_ = deviation_ != nullptr;
  }
  if (!codes && fits) make_finish_envelope(*spec_);
  std::vector<EnergySums> energy(iso.size());
  over_bands(h, rows, threads_, [&](int y0, int y1, int b) {
    band_captured(y0, y1, t, iso[b], e2e[b], kept, fits, energy[b]);
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
  StageComparison s_e2e = conclude(name_, std::move(e2e_total), e2e_rules_, e2e_terms, nullptr, false);
  EnergySums es;
  for (const EnergySums& b : energy) es.merge(b);
  gain_gates(s, s_e2e, es, stage_inputs(plan_, *spec_));
  carried_into(s, es);
  const bool enveloped = !env_.empty() || env_from_deviation_;
  if (enveloped) envelope_gate(s, es);
  result_.end_to_end.push_back(std::move(s_e2e));
  const bool keep = opt_.keep_images && !(opt_.keep_failing_only && s.verdict == Verdict::pass);
  if ((opt_.causes && s.verdict != Verdict::pass) || keep) {
    Image bound = bound_kept.empty() ? final_bound(t) : std::move(bound_kept);
    if (opt_.causes && s.verdict != Verdict::pass) {
      // Only a failure by a gate, every value within its bound: a value's bound already
      // separates the hypotheses of a failure by values, each with its own sampling.
      if (enveloped && !codes && s.over_bound == 0 && s.nonfinite_mismatch == 0) {
        Image narrowed = bound;
        narrow_to_envelope(t.oracle, cap.image, narrowed);
        test_causes_of(*spec_, s, t.oracle, narrowed);
      } else {
        test_causes_of(*spec_, s, t.oracle, bound);
      }
    }
    if (keep) {
      s.oracle = std::move(t.oracle);
      s.bound = std::move(bound);
    }
  }
  deviation_.reset();
  env_ = Envelope{};
  env_from_deviation_ = false;
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
  CauseContext cc{plan_, sanitized_, profile_, rounding_, threads_,
                  [this](const std::string& n) { return V(n); },
                  [this](const std::string& n) { return streams_.captured(n); }, &bound, "", "",
                  !intervals_done_};
  intervals_done_ = true;  // the first stage whose causes are searched only
  const auto prior = last_cause_.find(spec.kind);
  if (prior != last_cause_.end()) cc.prior = prior->second.first, cc.prior_stage = prior->second.second;
  auto score = [&](Image& variant, double absolute) {
    if (cap.code_bits > 0) {
      std::vector<float> q(variant.values().size());
      capture_codes(cap, variant.data(), q.data(), variant.pixel_count());
    }
    // A variant's own packed quantum, not the oracle's: its bound holds that one already.
    return within_bound(cap.image, variant.cview(), bound, 32 * kU, storage_at(spec), profile_, threads_,
                        absolute, &variant != &oracle);
  };
  const double oracle_score = score(oracle, 0.0);
  iso.causes = test_causes(cc, spec, oracle_score, score);
  if (iso.causes.empty() || !iso.causes.front().likely()) iso.residual = describe_residual(cc, spec);
  // The stage where a cause was found by the full search stays its source while it is found
  // again.
  if (!iso.causes.empty() && iso.causes.front().likely() &&
      (prior == last_cause_.end() || prior->second.first != iso.causes.front().id))
    last_cause_[spec.kind] = {iso.causes.front().id, spec.name};
}

// A stage without capture: the oracle's recomputation stored as the device stores it, carrying
// its bound, what it inherited, and the storage rounding of the recomputed value.
void Comparison::keep_uncaptured(std::size_t index, StageTerms& t) {
  const int w = t.oracle.width(), h = t.oracle.height();
  const bool read_later = streams_.read_after(name_, static_cast<int>(index));
  Image e_kept = read_later && !e2e_made_again(name_) ? pool_.take(w, h) : Image();
  Image carried = read_later ? pool_.take(w, h) : Image();
  pool_.clear();
  deviation_.reset();
  stage_width_ = w;
  if (spec_->kind == StageKind::blur && read_later) {
    deviation_ = std::make_unique<BlurDeviation>(V(stage_inputs(plan_, *spec_)[0]), spec_->axis,
                                                 kernel_, profile_);
    if (!deviation_->usable()) deviation_.reset();
    make_envelope(*spec_);
  }
  if (read_later) make_finish_envelope(*spec_);
  const int rows = judge_band(0);
  std::vector<EnergySums> energy(std::size_t((h + rows - 1) / rows));
  over_bands(h, rows, threads_, [&](int y0, int y1, int b) {
    const std::size_t n = std::size_t(y1 - y0) * w, values = n * kChannels;
    BandScratch& s = band_scratch();
    float* bound = BandScratch::rows(s.bound, values);
    float* rounding = BandScratch::rows(s.rounding, values);
    float* e = BandScratch::rows(s.e2e, values);
    t.bound->rows(y0, y1, bound, rounding);
    t.end_to_end(y0, y1, bound, e);
    float* inherited = nullptr;
    if (t.inherited) {
      inherited = BandScratch::rows(s.inherited, values);
      t.inherited(y0, y1, bound, inherited);
      add_rows(bound, inherited, n);
    }
    float* unrounded = BandScratch::rows(s.kept, values);
    float* o = t.oracle.pixel(0, y0);
    std::copy(o, o + values, unrounded);
    store(ImageView{w, y1 - y0, w, o}, storage_at(*spec_), rounding_, 1);
    EnergySums& es = energy[std::size_t(b)];
    for (std::size_t i = 0; i < values; ++i) {
      const float r = std::fabs(o[i] - unrounded[i]);
      bound[i] += r;
      if (i % kChannels != 3) es.storage[i % kChannels] += r;
    }
    if (read_later) {
      float *up, *down;
      deviation_band(y0, y1, up, down);
      energy_band(y0, y1, false, nullptr, nullptr, bound, rounding, inherited, e, up, down, es);
    }
    if (!e_kept.empty()) put_rows(e_kept, y0, e, n);
    if (read_later) put_rows(carried, y0, bound, n);
  });
  if (read_later) {
    EnergySums es;
    for (const EnergySums& b : energy) es.merge(b);
    Energy& en = energy_[name_];
    const Budgets sb = signed_budgets(stage_inputs(plan_, *spec_), es);
    en.chain = sb.iso;
    en.e2e = sb.e2e;
    // Without a signed budget, the error's variation is bounded by its per-value bound: each
    // value is in two differences along each axis.
    en.tv = sb.tv ? *sb.tv : std::array<double, 3>{4 * es.l1[0], 4 * es.l1[1], 4 * es.l1[2]};
    // The sum of the per-value bounds bounds the error's magnitudes too.
    for (int c = 0; c < 3; ++c) en.mass[c] = sb.mass ? std::min((*sb.mass)[c], es.l1[c]) : es.l1[c];
    for (int c = 0; c < 3; ++c) {
      en.chain.up[c] = std::min(en.chain.up[c], es.l1[c]);
      en.chain.down[c] = std::min(en.chain.down[c], es.l1[c]);
      en.e2e.up[c] = std::min(en.e2e.up[c], es.l1_e2e[c]);
      en.e2e.down[c] = std::min(en.e2e.down[c], es.l1_e2e[c]);
    }
  }
  deviation_.reset();
  if (!env_.empty() && read_later) envelope_[name_] = std::move(env_);
  env_ = Envelope{};
  computed_[name_] = std::move(t.oracle);
  if (!e_kept.empty()) e2e_[name_] = std::move(e_kept);
  if (read_later) carried_[name_] = std::move(carried);
}

// A band's sums for the gain gates (EnergySums), of the captured stage being judged (`gl`:
// its errors and budgets) or of a stage without capture (its budgets only).
// The deviation rows of the blur pass being judged or kept (deviation_), made once a band into
// its scratch for the gain gates and the envelope; null when it has none.
void Comparison::deviation_band(int y0, int y1, float*& up, float*& down) const {
  up = down = nullptr;
  if (!deviation_) return;
  const std::size_t values = std::size_t(y1 - y0) * stage_width_ * kChannels;
  up = BandScratch::rows(band_scratch().judged, 2 * values);
  down = up + values;
  deviation_->rows(y0, y1, up, down);
}

void Comparison::energy_band(int y0, int y1, bool gl, const float* oracle,
                             const float* full, const float* bound, const float* rounding,
                             const float* inherited, const float* e, const float* up,
                             const float* down, EnergySums& es) const {
  const int width = stage_width_;
  const std::size_t row = std::size_t(width) * kChannels;
  const int tiles = (width + kTile - 1) / kTile;
  const ConstImageView cap = gl ? capture(name_).image : ConstImageView{};
  const float limit = static_cast<float>(storage_limit(p_.storage));
  // Sums in lanes R, G, B, A (A dropped at the end), texel by texel: loops that vectorise. Each
  // keeps four partial sums, texels 4k, 4k+1, 4k+2, 4k+3 in their own, added together at the
  // end: one running sum would wait for each add before the next.
  using Lanes = std::array<double, 4>;
  auto sum = [](Lanes& a, std::size_t n, auto value) {
    std::array<Lanes, 4> part{};
    std::size_t i = 0;
    for (; i + 4 * kChannels <= n; i += 4 * kChannels)
      for (std::size_t k = 0; k < 4; ++k)
        for (std::size_t c = 0; c < 4; ++c) part[k][c] += value(i + k * kChannels + c);
    for (; i < n; i += kChannels)
      for (std::size_t c = 0; c < 4; ++c) part[0][c] += value(i + c);
    for (std::size_t c = 0; c < 4; ++c) a[c] += (part[0][c] + part[1][c]) + (part[2][c] + part[3][c]);
  };
  auto add = [&sum](Lanes& a, const float* v, std::size_t n) {
    sum(a, n, [v](std::size_t i) { return double(v[i]); });
  };
  auto add_diff = [&sum](Lanes& a, const float* v, const float* w, std::size_t n) {
    sum(a, n, [v, w](std::size_t i) { return double(v[i]) - double(w[i]); });
  };
  auto add_max = [&sum](Lanes& a, const float* v, const float* w, std::size_t n) {
    sum(a, n, [v, w](std::size_t i) { return double(std::max(v[i], w[i])); });
  };
  Lanes se{}, sr{}, su{}, sd{}, sm{}, sb{}, si{}, err{}, orc{}, l1{}, err2{}, full2{};
  // Per tile of the band: its total error, the sum of its bounds, its signed budgets.
  const std::size_t n_tiles = static_cast<std::size_t>(tiles);
  thread_local std::vector<Lanes> te, tb, tl, tu, td;
  for (std::vector<Lanes>* v : {&te, &tb, &tl, &tu, &td}) v->assign(n_tiles, Lanes{});
  auto plus = [](Lanes& a, const Lanes& b) {
    for (std::size_t c = 0; c < 4; ++c) a[c] += b[c];
  };
  // What every value adds, judged or not: a tile's sums, each added to the band's.
  auto every_value = [&](std::size_t i0, std::size_t n, Lanes& r, Lanes& i, Lanes& u, Lanes& d,
                         Lanes& b) {
    Lanes et{}, mt{};
    add(et, e + i0, n);
    add(r, rounding + i0, n);
    add(b, bound + i0, n);
    if (inherited) add(i, inherited + i0, n);
    if (up) {
      add(u, up + i0, n);
      add(d, down + i0, n);
      add_max(mt, up + i0, down + i0, n);
    }
    plus(se, et), plus(sr, r), plus(sb, b), plus(si, i), plus(su, u), plus(sd, d), plus(sm, mt);
  };
  for (int y = y0; y < y1; ++y) {
    const std::size_t at0 = std::size_t(y - y0) * row;
    if (!gl) {
      Lanes r{}, i{}, u{}, d{}, b{};
      every_value(at0, row, r, i, u, d, b);
      continue;
    }
    const float* g = cap.row(y);
    for (std::size_t t = 0; t < n_tiles; ++t) {
      const std::size_t x0 = t * kTile, x1 = std::min<std::size_t>(width, x0 + kTile);
      const std::size_t i0 = at0 + x0 * kChannels, n = (x1 - x0) * kChannels;
      const float *gv = g + x0 * kChannels, *ov = oracle + i0, *fv = full + i0, *bv = bound + i0,
                  *ev = e + i0;
      Lanes rt{}, it{}, ut{}, dt{}, bt{};
      every_value(i0, n, rt, it, ut, dt, bt);
      // A run whose values are all finite, within range, with finite bounds (the usual case)
      // is judged whole; otherwise value by value, as judge_row judges them.
      // (Bitwise |, no branch: a loop that vectorises.)
      int odd = 0;
      for (std::size_t i = 0; i < n; i += kChannels)
        for (std::size_t c = 0; c < 3; ++c)
          odd |= !(std::fabs(gv[i + c]) <= limit) | !(std::fabs(ov[i + c]) <= limit) |
                 !(std::fabs(fv[i + c]) <= limit) | !(bv[i + c] <= FLT_MAX) | !(ev[i + c] <= FLT_MAX);
      const bool plain = odd == 0;
      // The tile's budgets take every value (a larger budget is still a bound).
      plus(tl[t], rt), plus(tl[t], it);
      if (up) plus(tu[t], ut), plus(td[t], dt);
      if (plain) {
        Lanes diff{};
        add_diff(diff, gv, ov, n);
        plus(err, diff), plus(te[t], diff);
        add(orc, ov, n);
        plus(l1, bt), plus(tb[t], bt);
        add_diff(err2, gv, fv, n);
        add(full2, fv, n);
        continue;
      }
      for (std::size_t i = 0; i < n; ++i) {
        const std::size_t c = i & 3;
        if (c == 3) continue;
        if (judged_as_number(ov[i], gv[i], p_.storage, profile_, bv[i])) {
          err[c] += double(gv[i]) - ov[i];
          orc[c] += ov[i];
          l1[c] += bv[i];
          te[t][c] += double(gv[i]) - ov[i];
          tb[t][c] += bv[i];
        }
        if (judged_as_number(fv[i], gv[i], p_.storage, profile_, ev[i])) {
          err2[c] += double(gv[i]) - fv[i];
          full2[c] += fv[i];
        }
      }
    }
  }
  for (std::size_t t = 0; gl && t < n_tiles; ++t)
    for (int c = 0; c < 3; ++c) {
      const double b_up = up ? tu[t][c] + tl[t][c] : INFINITY, b_down = up ? td[t][c] + tl[t][c] : INFINITY;
      const double r = budget_ratio(te[t][c], std::min(tb[t][c], b_up), std::min(tb[t][c], b_down));
      if (r > es.tile_ratio) es.tile_ratio = r, es.tile_x = static_cast<int>(t) * kTile, es.tile_y = y0;
    }
  for (int c = 0; c < 3; ++c) {
    es.l1_e2e[c] += se[c], es.rounding[c] += sr[c], es.l1_own[c] += sb[c] - si[c];
    es.up[c] += su[c], es.down[c] += sd[c], es.most[c] += sm[c];
    es.l1[c] += gl ? l1[c] : sb[c];
    es.err[c] += err[c], es.oracle[c] += orc[c], es.err_e2e[c] += err2[c], es.full[c] += full2[c];
  }
}

// The signed budgets of the stage being judged (its total error against the isolated oracle,
// and against the full run), from its band sums (with a stage without capture's storage
// rounding: the oracle's value as stored) and what its inputs carry. Only a blur pass and the
// composite have budgets tighter than the sum of their per-value bounds (otherwise infinite,
// and no `tv`); `tv` bounds the total variation of the isolated error (for the stages that
// read it).
Comparison::Budgets Comparison::signed_budgets(const std::vector<std::string>& in,
                                               const EnergySums& es) const {
  SignedBudget iso, e2e;
  std::array<double, 3> t{}, m{};
  const Budgets none{SignedBudget::infinite(), SignedBudget::infinite(), std::nullopt, std::nullopt};
  if (spec_->kind == StageKind::blur && deviation_) {
    const std::string& i = in[0];
    for (int c = 0; c < 3; ++c) {
      iso.up[c] = es.up[c] + es.rounding[c] + es.storage[c];
      iso.down[c] = es.down[c] + es.rounding[c] + es.storage[c];
      // The error a pass creates is at most max(up, down) at each value; its total variation
      // at most 4 times its sum (each value is in two differences along each axis).
      t[c] = 4 * (es.most[c] + es.rounding[c] + es.storage[c]);
      m[c] = es.most[c] + es.rounding[c] + es.storage[c];
    }
    e2e = iso;
    e2e.add_both(es.rounding);  // the full run's own storage rounding
    const auto ei = energy_.find(i);
    if (ei == energy_.end()) return none;
    const bool hz = spec_->axis == Axis::horizontal;
    const std::vector<double> excess =
        edge_weight_excess(hz ? V(i).width : V(i).height, kernel_);
    if (!streams_.captured(i)) {
      // The device's lookups of the error carried in: its sum moves by at most the shifts
      // times the error's variation (a shift moves weight to a neighbour), and by the weight
      // clamp-to-edge gives texels near the edges. Equally, a texel's total weight over the
      // device's lookups differs from the oracle's by at most s per axis (s = the shifts'
      // span; weights sum to 1 over the taps), so the sum moves by at most (2s + s^2) times
      // the error's magnitudes: the smaller of the two applies.
      const double s = deviation_->shift_sum(), k = s * (1 + s), a = s * (2 + s);
      const std::array<double, 3> leak = edge_leak(E(i)->cview(), spec_->axis, excess);
      std::array<double, 3> second{};
      for (int c = 0; c < 3; ++c) {
        const double by_variation = k * ei->second.tv[c];
        second[c] = std::min(by_variation, a * ei->second.mass[c]);
        t[c] += ei->second.tv[c] + 4 * by_variation;
        m[c] += (1 + a) * ei->second.mass[c] + leak[c];
      }
      iso.add(ei->second.chain);
      iso.add_both(second);
      iso.add_both(leak);
      e2e.add_both(second);
    }
    e2e.add(ei->second.e2e);
    const BoundRows r = e2e_rows(i);
    if (!r.image) return {iso, SignedBudget::infinite(), t, m};
    e2e.add_both(edge_leak(r.image->cview(), spec_->axis, excess));
  } else if (spec_->kind == StageKind::composite) {
    // hdr = scene + strength * bloom: the inputs' totals pass through, scaled.
    std::array<double, 3> own{};
    for (int c = 0; c < 3; ++c) own[c] = es.l1_own[c] + es.storage[c];
    iso.add_both(own);
    e2e.add_both(own);
    e2e.add_both(es.rounding);
    for (std::size_t j = 0; j < in.size(); ++j) {
      const auto ej = energy_.find(in[j]);
      if (ej == energy_.end()) return none;
      const double scale = j == 1 ? std::fabs(p_.strength) : 1.0;
      if (!streams_.captured(in[j])) {
        iso.add(ej->second.chain, scale);
        if (opt_.interpolated_reads) {
          // Reads at interpolated coordinates: a shift of at most the coordinate error.
          const ConstImageView v = V(in[j]);
          const AxisShift sx = lookup_shift(v.width, profile_, 0.0), sy = lookup_shift(v.height, profile_, 0.0);
          const double k = sx.minus + sx.plus + sy.minus + sy.plus;
          const double a = k + (sx.minus + sx.plus) * (sy.minus + sy.plus);  // as for a blur
          std::array<double, 3> second{};
          for (int c = 0; c < 3; ++c)
            second[c] = scale * std::min(k * ej->second.tv[c], a * ej->second.mass[c]);
          iso.add_both(second);
          e2e.add_both(second);
        }
        for (int c = 0; c < 3; ++c) t[c] += scale * ej->second.tv[c];
      }
      e2e.add(ej->second.e2e, scale);
    }
    for (int c = 0; c < 3; ++c) t[c] += 4 * (own[c] + es.rounding[c]);
  } else {
    return none;
  }
  if (spec_->kind == StageKind::blur) return {iso, e2e, t, m};
  return {iso, e2e, t, std::nullopt};  // the composite's magnitudes: the per-value bounds' sum
}

// The stages without capture a captured stage's bound carries the error of (back through
// stages without capture to the captures or the scene), and their share of its bound.
void Comparison::carried_into(StageComparison& s, const EnergySums& es) const {
  double carried = 0, judged = 0;
  for (int c = 0; c < 3; ++c) carried += es.carried[c], judged += es.judged[c];
  if (!(carried > 0) || !(judged > 0)) return;
  s.carried_share = std::min(1.0, carried / judged);
  std::set<std::string> from;
  std::vector<std::string> open = stage_inputs(plan_, *spec_);
  while (!open.empty()) {
    const std::string n = open.back();
    open.pop_back();
    if (streams_.captured(n) || !from.insert(n).second) continue;
    if (const StageSpec* st = find_stage(plan_, n))
      for (const std::string& i : stage_inputs(plan_, *st)) open.push_back(i);
  }
  for (const StageSpec& st : plan_.stages)
    if (from.count(st.name)) s.carried_from.push_back(st.name);
}

// The gain gates of a captured stage: its total error per channel against the smaller of two
// budgets, each a bound on it: the sum of the per-value bounds as judged, and the signed budget
// (signed_budgets); over the whole image and (isolated) each tile.
void Comparison::gain_gates(StageComparison& iso, StageComparison& e2e, const EnergySums& es,
                            const std::vector<std::string>& in) {
  const Budgets sb = signed_budgets(in, es);
  SignedBudget signed_iso = sb.iso;
  const SignedBudget& signed_e2e = sb.e2e;
  // A profile's override widens the stage's per-value bounds (and so their sum) by a factor and
  // a constant the signed budget knows nothing of: the sum alone then.
  const StageOverride* over = stage_override(profile_, name_);
  if (over && (over->scale != 1.0 || over->absolute != 0.0)) signed_iso = SignedBudget::infinite();
  const ImageGates& gates = over && over->has_gates ? over->gates : profile_.gates;
  const double limit = gates.gain;
  Energy& mine = energy_[name_];
  mine.chain = SignedBudget{};
  mine.tv = {};
  mine.mass = {};
  for (int c = 0; c < 3; ++c) {
    mine.e2e.up[c] = std::min(es.l1_e2e[c], signed_e2e.up[c]);
    mine.e2e.down[c] = std::min(es.l1_e2e[c], signed_e2e.down[c]);
  }
  auto apply = [&](StageComparison& s, const EnergySums::Sum& err, const EnergySums::Sum& total,
                   const EnergySums::Sum& l1, const SignedBudget& sb, bool tiles) {
    for (int c = 0; c < 3; ++c) {
      const double up = std::min(l1[c], sb.up[c]), down = std::min(l1[c], sb.down[c]);
      const double r = budget_ratio(err[c], up, down);
      s.gain[c] = total[c] != 0 ? (total[c] + err[c]) / total[c] : 1.0;
      s.gain_allowed[c] = total[c] != 0 ? std::min(up, down) / std::fabs(total[c]) : INFINITY;
      s.gain_ratio = std::max(s.gain_ratio, r);
    }
    if (tiles) {
      s.tile_gain_ratio = es.tile_ratio;
      s.tile_x = es.tile_x;
      s.tile_y = es.tile_y;
    }
    const bool whole = limit > 0 && s.gain_ratio > limit, tile = limit > 0 && s.tile_gain_ratio > limit;
    if (!whole && !tile) return;
    static const char* names[3] = {"R", "G", "B"};
    std::string what;
    if (whole) {
      int c = 0;
      for (int k = 1; k < 3; ++k)
        if (budget_ratio(err[k], std::min(l1[k], sb.up[k]), std::min(l1[k], sb.down[k])) >
            budget_ratio(err[c], std::min(l1[c], sb.up[c]), std::min(l1[c], sb.down[c])))
          c = k;
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "the total of %s is %.4gx the oracle's; the profile allows %.3g%% either way "
                    "(gain gate: %.3gx its budget)",
                    names[c], s.gain[c], 100 * s.gain_allowed[c], s.gain_ratio);
      what = buf;
    } else {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "the total error of the %dx%d tile at (%d, %d) is %.3gx its budget (tile gain gate)",
                    kTile, judge_band(iso_rules_.window), s.tile_x, s.tile_y, s.tile_gain_ratio);
      what = buf;
    }
    if (s.gate.empty()) {
      s.gate_id = whole ? "gain" : "tile-gain";
      s.gate = what;
    }
    if (s.nonfinite_mismatch == 0 && s.beyond_tier == 0) {
      s.verdict = Verdict::fail;
      s.reason = "image gate: " + s.gate;
    }
  };
  apply(iso, es.err, es.oracle, es.l1, signed_iso, true);
  apply(e2e, es.err_e2e, es.full, es.l1_e2e, signed_e2e, false);
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
