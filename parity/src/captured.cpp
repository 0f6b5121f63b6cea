// compare_captured: the stage-by-stage comparison of any subset of captured stages.
//
// Three images per stage: the isolated oracle (the stage recomputed from what the device had:
// the captures of the stages it reads, or, where a stage has no capture, the oracle's own
// recomputation of it), its bound, and the end-to-end bound (against the CPU's full run). A
// stage without capture is stored as the device would store it and carries an error: its own
// bound plus what it inherited, plus the storage rounding of the recomputed value; the stages
// that read it add that error, propagated through them, to their isolated bounds. A capture
// carries none: it is what the device had.
#include <algorithm>
#include <chrono>
#include <functional>
#include <cmath>
#include <map>
#include <memory>

#include "bloomref/error.h"
#include "bloomref/mip.h"
#include "bloomref/parallel.h"
#include "causes.h"
#include "chain.h"
#include "judge.h"
#include "tolerance.h"

namespace bloomref::parity {

using namespace detail;

namespace {

// A stage's bound terms plus extra per-value terms read from images (the error carried from
// stages without capture, an 8-bit capture's half code), for the report's worst values.
struct ExtraTerms : StageBounds {
  const StageBounds& inner;
  std::vector<std::pair<std::string, const Image*>> extra;
  ExtraTerms(const StageBounds& b, std::vector<std::pair<std::string, const Image*>> e)
      : inner(b), extra(std::move(e)) {}
  void fill(Image& bound) const override { inner.fill(bound); }
  void fill_rounding(Image& r) const override { inner.fill_rounding(r); }
  std::vector<Term> terms(int x, int y, int c) const override {
    std::vector<Term> t = inner.terms(x, y, c);
    for (const auto& [name, img] : extra)
      if (img && !img->empty()) t.push_back({name, img->pixel(x, y)[c]});
    return t;
  }
};

void add_into(Image& dst, const Image& a, double scale = 1.0) {
  for (std::size_t i = 0; i < dst.values().size(); ++i)
    dst.values()[i] += static_cast<float>(scale * a.values()[i]);
}

// 1 - exp(-h k) has slope k exp(-h k), largest at the low end of h +- e.
Image through_tonemap(ConstImageView h, const Image& e, double exposure) {
  Image out(h.width, h.height, 0.0f);
  for (int y = 0; y < h.height; ++y)
    for (int x = 0; x < h.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double hv = h.pixel(x, y)[c], ev = e.pixel(x, y)[c];
        out.pixel(x, y)[c] = std::isfinite(hv) && std::isfinite(ev)
                                 ? static_cast<float>(exposure * std::exp(-(hv - ev) * exposure) * ev)
                                 : INFINITY;
      }
  return out;
}

// Gamma's slope is unbounded near black: bound by the interval's image instead.
Image through_output(ConstImageView m, const Image& e, double gamma) {
  Image out(m.width, m.height, 0.0f);
  const double g = 1.0 / gamma;
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double mv = m.pixel(x, y)[c], ev = e.pixel(x, y)[c];
        out.pixel(x, y)[c] =
            std::isfinite(mv) && std::isfinite(ev)
                ? static_cast<float>(std::pow(std::max(mv + ev, 0.0), g) -
                                     std::pow(std::max(mv - ev, 0.0), g))
                : INFINITY;
      }
  return out;
}

double srgb_decode(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}
double srgb_encode(double v) {
  return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
}

// An 8-bit capture: the oracle clamped to [0, 1] (what the capture could hold) and half a code
// of the capture's encoding at that value, as its own term image.
Image capture_codes(const CapturedStage& cap, Image& oracle) {
  Image q(oracle.width(), oracle.height(), 0.0f);
  const double h = 0.5 / ((1 << cap.code_bits) - 1);
  for (std::size_t i = 0; i < oracle.values().size(); ++i) {
    if (i % 4 == 3) continue;
    float& o = oracle.values()[i];
    if (!std::isnan(o)) o = std::clamp(o, 0.0f, 1.0f);
    double step = h;
    if (cap.srgb && std::isfinite(o)) {
      const double e = srgb_encode(o);
      step = std::max(srgb_decode(std::min(e + h, 1.0)) - o, o - srgb_decode(std::max(e - h, 0.0)));
    }
    q.values()[i] = static_cast<float>(step * (1 + 1e-6));  // the decode's own rounding
  }
  return q;
}


// The images a comparison holds, each released once no later stage needs it: the captures
// (loaded when reached), the stages without capture (the oracle's, stored) and the error they
// carry, the oracle's full run and its end-to-end bounds.
class Streams {
 public:
  Streams(const Plan& plan, const std::vector<std::string>& captured, bool causes) {
    const auto& st = plan.stages;
    for (std::size_t i = 0; i < st.size(); ++i) index_[st[i].name] = static_cast<int>(i);
    for (const std::string& c : captured) captured_[c] = true;
    // A stage is needed until the last stage that reads it. The isolated chain (captures,
    // recomputed stages) is kept longer for the cause hypotheses, which recompute a failing
    // stage from the captures before it: until the first capture downstream of each uncaptured
    // reader has been judged, and pass k - 2 until pass k.
    for (int i = static_cast<int>(st.size()) - 1; i >= 0; --i)
      for (const std::string& in : stage_inputs(plan, st[i])) {
        read_[in] = std::max(get(read_, in), i);
        int until = i;
        if (causes && !captured_.count(st[i].name)) until = std::max(until, get(chain_, st[i].name));
        chain_[in] = std::max(get(chain_, in), until);
      }
    if (causes)
      for (const StageSpec& s : st)
        if (s.kind == StageKind::blur && s.pass >= 3) {
          const std::string back = "blur." + std::to_string(s.pass - 2);
          chain_[back] = std::max(get(chain_, back), index_[s.name]);
        }
  }
  bool captured(const std::string& n) const { return captured_.count(n) > 0; }
  /// Releases every image of the isolated chain no stage after `done` (an index into the plan)
  /// needs.
  template <class... Maps>
  void release_chain(int done, Maps&... maps) {
    (release_in(chain_, done, maps), ...);
  }
  /// The same for the oracle's full run and its bounds, which only the stages that read them
  /// need.
  template <class... Maps>
  void release_read(int done, Maps&... maps) {
    (release_in(read_, done, maps), ...);
  }

 private:
  static int get(const std::map<std::string, int>& m, const std::string& n) {
    const auto it = m.find(n);
    return it == m.end() ? -1 : it->second;
  }
  template <class Map>
  static void release_in(const std::map<std::string, int>& need, int done, Map& m) {
    for (auto it = m.begin(); it != m.end();)
      it = get(need, it->first) <= done ? m.erase(it) : std::next(it);
  }
  std::map<std::string, int> index_, read_, chain_;
  std::map<std::string, bool> captured_;
};

// The oracle's full run, stage by stage, as the CPU executor computes it: the same functions
// (the fast blur and finishing stages give the reference's bits), stored after each stage.
Image oracle_stage(const Plan& plan, const StageSpec& spec, ConstImageView sanitized,
                   const std::vector<ConstImageView>& in, int subtexel_bits, HalfRounding rounding) {
  const BloomParams& p = plan.params;
  const int threads = p.threads;
  Image out;
  switch (spec.kind) {
    case StageKind::input:
      out = Image::uninitialised(sanitized.width, sanitized.height);
      for (int y = 0; y < sanitized.height; ++y)
        std::copy(sanitized.row(y), sanitized.row(y) + std::size_t(sanitized.width) * kChannels,
                  out.view().row(y));
      break;
    case StageKind::bright:
      out = Image::uninitialised(sanitized.width, sanitized.height);
      extract_bright(sanitized, out.view(), p.threshold, threads);
      break;
    case StageKind::blur:
      out = Image::uninitialised(in[0].width, in[0].height);
      blur_pass_fast(in[0], out.view(), {spec.axis, &kernel_for(p.kernel), subtexel_bits}, threads);
      break;
    case StageKind::down: {
      const LevelSize& l = plan.levels[spec.pass - 1];
      out = Image::uninitialised(l.width, l.height);
      const bool first = spec.pass == 1;
      downsample(in[0], out.view(), {first, p.threshold, p.karis && first, subtexel_bits}, threads);
      break;
    }
    case StageKind::up:
    case StageKind::bloom: {
      const bool up = spec.kind == StageKind::up;
      out = up ? Image::uninitialised(in[1].width, in[1].height)
               : Image::uninitialised(sanitized.width, sanitized.height);
      upsample_tent(in[0], up ? in[1] : ConstImageView{}, out.view(), subtexel_bits, threads);
      break;
    }
    case StageKind::composite:
      out = Image::uninitialised(in[0].width, in[0].height);
      composite(in[0], in[1], out.view(), p.strength, threads);
      break;
    case StageKind::tonemap:
      out = Image::uninitialised(in[0].width, in[0].height);
      tonemap_fast(in[0], out.view(), p.exposure, threads);
      break;
    case StageKind::output:
      out = Image::uninitialised(in[0].width, in[0].height);
      encode_output_fast(in[0], out.view(), p.gamma, threads);
      break;
  }
  store(out.view(), p.storage, rounding, threads);
  return out;
}

// A capture the comparison reads: a view of the caller's image, or one it loaded and owns.
struct Held {
  ConstImageView view;
  Image owned;
  int code_bits = 0;
  bool srgb = false;
};

ParityResult compare_core(const Plan& plan, ConstImageView scene,
                          const std::vector<std::string>& captured_names,
                          const std::function<Held(const std::string&)>& load,
                          const StageTrace* cpu, const DeviceProfile& profile,
                          const CompareOptions& opt, double* oracle_ms) {
  const BloomParams& p = plan.params;
  const int threads = p.threads, w = scene.width, h = scene.height;
  const BoundContext ctx{&profile, p.storage, threads};
  const Kernel& kernel = kernel_for(p.kernel);
  const HalfRounding rounding = half_rounding_for(profile);
  ParityResult result;
  result.profile = profile;
  for (const std::string& name : captured_names)
    if (!find_stage(plan, name))
      throw ParamError("no stage '" + name + "' in this plan (" + to_string(p.method) + ", " +
                       std::to_string(p.passes) + " passes)");
  Streams streams(plan, captured_names, opt.causes);
  double oracle_time = 0;

  // The sanitised scene (unrounded): what the input pass computes before storing.
  Image sanitized(w, h);
  sanitize(scene, sanitized.view(), p.nonfinite, p.storage, threads);

  std::map<std::string, Held> captures;   // loaded when reached
  std::map<std::string, Image> computed;  // stages without capture: the oracle's, stored
  std::map<std::string, Image> carried;   // and the error each carries
  std::map<std::string, Image> full;      // the oracle's full run (when no trace is given)
  std::map<std::string, Image> e2e;       // end-to-end bound of each stage, on the full run
  auto V = [&](const std::string& n) -> ConstImageView {
    const auto c = captures.find(n);
    if (c != captures.end()) return c->second.view;
    const auto it = computed.find(n);
    return it != computed.end() ? it->second.cview() : ConstImageView{};
  };
  auto E = [&](const std::string& n) -> const Image* {
    const auto it = carried.find(n);
    return it == carried.end() ? nullptr : &it->second;
  };
  auto C = [&](const std::string& n) -> const Image& {
    if (!cpu) return full.at(n);
    const StageResult* r = cpu->find(n);    if (!r) throw ParamError("the CPU trace has no stage '" + n + "'");
    return r->image;
  };
  const float strength = p.strength;

  for (std::size_t index = 0; index < plan.stages.size(); ++index) {
    const StageSpec& spec = plan.stages[index];
    const std::string& name = spec.name;
    const std::vector<std::string> in = stage_inputs(plan, spec);
    if (!cpu) {
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<ConstImageView> cin;
      for (const std::string& n : in) cin.push_back(full.at(n).cview());
      full[name] = oracle_stage(plan, spec, sanitized.cview(), cin, profile.subtexel_bits, rounding);
      oracle_time += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    if (streams.captured(name)) captures[name] = load(name);
    const Image& c = C(name);
    Image oracle(c.width(), c.height()), bound(c.width(), c.height(), 0.0f);
    Image e(c.width(), c.height(), 0.0f);  // end-to-end bound
    Image inherited;  // the error carried in from inputs without capture (empty: none)
    std::unique_ptr<StageBounds> b;
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
        const ConstImageView src = V(in[0]);
        blur_pass(src, oracle.view(), {spec.axis, &kernel, profile.subtexel_bits}, threads);
        b = blur_bounds(src, oracle.cview(), spec.axis, kernel, ctx);
        b->fill(bound);
        e = propagate_blur(e2e.at(in[0]).cview(), spec.axis, kernel, threads);
        add_into(e, bound);
        if (const Image* ce = E(in[0]))
          inherited = propagate_blur(ce->cview(), spec.axis, kernel, threads);
        break;
      }
      case StageKind::down: {
        const int k = spec.pass;
        const ConstImageView src = V(in[0]);
        oracle = Image(plan.levels[k - 1].width, plan.levels[k - 1].height);
        bound = Image(oracle.width(), oracle.height(), 0.0f);
        const DownsampleOptions o{k == 1, p.threshold, p.karis && k == 1, profile.subtexel_bits};
        downsample(src, oracle.view(), o, threads);
        b = down_bounds(src, oracle.cview(), nullptr, k == 1, p.threshold, p.karis, ctx);
        b->fill(bound);
        if (const Image* ce = E(in[0])) {
          // The carried error enters each tap (and the threshold's band): the bound with it,
          // less the bound without, is what it adds.
          Image with(bound.width(), bound.height(), 0.0f);
          down_bounds(src, oracle.cview(), ce, k == 1, p.threshold, p.karis, ctx)->fill(with);
          inherited = std::move(with);
          add_into(inherited, bound, -1.0);
        }
        down_bounds(C(in[0]).cview(), c.cview(), &e2e.at(in[0]), k == 1, p.threshold, p.karis, ctx)
            ->fill(e);
        break;
      }
      case StageKind::up:
      case StageKind::bloom: {
        const bool up = spec.kind == StageKind::up;
        const BasicView<const float> none{};
        const ConstImageView small = V(in[0]);
        const ConstImageView cur = up ? V(in[1]) : none;
        oracle = up ? Image(cur.width, cur.height) : Image(w, h);
        bound = Image(oracle.width(), oracle.height(), 0.0f);
        upsample_tent(small, cur, oracle.view(), profile.subtexel_bits, threads);
        b = up_bounds(small, cur, oracle.cview(), nullptr, nullptr, ctx);
        b->fill(bound);
        const Image* es = E(in[0]);
        const Image* ec = up ? E(in[1]) : nullptr;
        if (es || ec) {
          Image with(bound.width(), bound.height(), 0.0f);
          up_bounds(small, cur, oracle.cview(), es, ec, ctx)->fill(with);
          inherited = std::move(with);
          add_into(inherited, bound, -1.0);
        }
        up_bounds(C(in[0]).cview(), up ? C(in[1]).cview() : none, c.cview(), &e2e.at(in[0]),
                  up ? &e2e.at(in[1]) : nullptr, ctx)
            ->fill(e);
        break;
      }
      case StageKind::composite: {
        const ConstImageView sc = V(in[0]), bl = V(in[1]);
        composite(sc, bl, oracle.view(), strength, threads);
        b = composite_bounds(sc, bl, oracle.cview(), strength, ctx);
        b->fill(bound);
        e = e2e.at(in[0]);
        add_into(e, e2e.at(in[1]), strength);
        add_into(e, bound);
        const Image *es = E(in[0]), *eb = E(in[1]);
        if (es || eb) {
          inherited = Image(w, h, 0.0f);
          if (es) add_into(inherited, *es);
          if (eb) add_into(inherited, *eb, strength);
        }
        break;
      }
      case StageKind::tonemap: {
        const ConstImageView hd = V(in[0]);
        tonemap(hd, oracle.view(), p.exposure, threads);
        b = tonemap_bounds(hd, oracle.cview(), p.exposure, ctx);
        b->fill(bound);
        e = through_tonemap(C(in[0]).cview(), e2e.at(in[0]), p.exposure);
        add_into(e, bound);
        if (const Image* ce = E(in[0])) inherited = through_tonemap(hd, *ce, p.exposure);
        break;
      }
      case StageKind::output: {
        const ConstImageView m = V(in[0]);
        encode_output(m, oracle.view(), p.gamma, threads);
        b = output_bounds(m, oracle.cview(), p.gamma, ctx);
        b->fill(bound);
        e = through_output(C(in[0]).cview(), e2e.at(in[0]), p.gamma);
        add_into(e, bound);
        if (const Image* ce = E(in[0])) inherited = through_output(m, *ce, p.gamma);
        break;
      }
    }
    if (!inherited.empty()) add_into(bound, inherited);
    const StageOverride* over = stage_override(profile, name);
    auto overridden = [&](Image& b) {
      if (over && (over->scale != 1.0 || over->absolute != 0.0))
        for (std::size_t i = 0; i < b.values().size(); ++i)
          b.values()[i] = static_cast<float>(b.values()[i] * over->scale + over->absolute);
    };
    const ImageGates& gates = over && over->has_gates ? over->gates : profile.gates;

    const auto cap = captures.find(name);
    if (cap != captures.end()) {
      const CapturedStage cs{cap->second.view, cap->second.code_bits, cap->second.srgb};
      Image codes, codes_e2e;
      Image oracle_e2e;
      const Image* e2e_oracle = &c;
      CapturedStage cs_bits = cs;  // the profile may say every capture holds 8-bit codes
      cs_bits.code_bits = std::max(cs.code_bits, profile.capture_code_bits);
      if (cs_bits.code_bits > 0) {
        codes = capture_codes(cs_bits, oracle);
        add_into(bound, codes);
        oracle_e2e = c;
        codes_e2e = capture_codes(cs_bits, oracle_e2e);
        e2e_oracle = &oracle_e2e;
      }
      // The end-to-end bound as judged (plus the capture's codes, the override): in place when
      // no later stage reads it, else a copy.
      const bool e_read_later = std::any_of(plan.stages.begin() + index + 1, plan.stages.end(),
                                            [&](const StageSpec& later) {
                                              const auto li = stage_inputs(plan, later);
                                              return std::find(li.begin(), li.end(), name) != li.end();
                                            });
      const bool e_changes = !codes_e2e.empty() || (over && (over->scale != 1.0 || over->absolute != 0.0));
      Image e_copy;
      if (e_changes && e_read_later) e_copy = e;
      Image& e_judged = e_changes && e_read_later ? e_copy : e;
      if (!codes_e2e.empty()) add_into(e_judged, codes_e2e);
      overridden(bound);
      overridden(e_judged);
      // The gates' allowance: the capture's own rounding; and with f16 storage, what stages
      // without capture carry, which holds their roundings (llvmpipe's toward zero is biased:
      // half an ULP a stage on average, as systematic as the offsets the gates look for).
      const ExtraTerms terms(*b, {{"carried from stages without capture", &inherited},
                                  {"8-bit capture: half a code", &codes}});
      const ExtraTerms terms_e2e(*b, {{"8-bit capture: half a code", &codes_e2e}});
      // The gates measure the error beyond rounding: the stage's own (its storage and
      // arithmetic terms, scaled as an override scales the bound) and the capture's codes.
      Image own_rounding(oracle.width(), oracle.height(), 0.0f);
      b->fill_rounding(own_rounding);
      if (over && over->scale != 1.0)
        for (float& v : own_rounding.values()) v = static_cast<float>(v * over->scale);
      if (!codes.empty()) add_into(own_rounding, codes);
      StageComparison iso = judge(name, cs.image, oracle.cview(), bound, terms, p.storage,
                                  profile, opt, threads, &gates, &own_rounding,
                                  p.storage == Storage::f16 && !inherited.empty() ? &inherited
                                                                                  : nullptr);
      if (opt.causes && iso.verdict != Verdict::pass) {
        CauseContext cc{plan, sanitized.cview(), profile, rounding, threads,
                        [&](const std::string& n) { return V(n); },
                        [&](const std::string& n) { return streams.captured(n); }};
        CompareOptions quick;
        quick.worst_count = 0;
        // A hypothesis changes the stage's arithmetic, which the bound was derived for: each
        // is judged with the bound plus its own rounding, 32 f32 ULPs of its value (the
        // stages' longest chain, a 9-tap sum, rounds 2 x 9 + 3 times), and so is the oracle
        // itself for the baseline, so that a hypothesis equal to the oracle scores the same.
        auto score = [&](Image& variant) {
          if (cs_bits.code_bits > 0) capture_codes(cs_bits, variant);
          Image relaxed = bound;
          for (std::size_t i = 0; i < relaxed.values().size(); ++i)
            relaxed.values()[i] += static_cast<float>(32 * kU * std::fabs(variant.values()[i]));
          return judge(name, cs.image, variant.cview(), relaxed, terms, p.storage, profile, quick,
                       threads)
              .within();
        };
        Image baseline = oracle;
        const double oracle_score = score(baseline);
        iso.causes = test_causes(cc, spec, oracle_score, score);
      }
      result.isolated.push_back(std::move(iso));
      result.end_to_end.push_back(judge(name, cs.image, e2e_oracle->cview(), e_judged, terms_e2e,
                                        p.storage, profile, opt, threads));
    } else {
      // Stored as the device stores it; the rounding adds to what it carries.
      Image stored = oracle;
      store(stored.view(), p.storage, rounding, threads);
      for (std::size_t i = 0; i < bound.values().size(); ++i)
        bound.values()[i] += std::fabs(stored.values()[i] - oracle.values()[i]);
      computed[name] = std::move(stored);
      carried[name] = std::move(bound);
    }
    e2e[name] = std::move(e);
    streams.release_chain(static_cast<int>(index), captures, computed, carried);
    streams.release_read(static_cast<int>(index), full, e2e);
  }
  if (oracle_ms) *oracle_ms = oracle_time;

  for (const StageComparison& s : result.isolated) {
    if (s.verdict != Verdict::pass && !result.first_divergent_stage)
      result.first_divergent_stage = s.stage;
    result.verdict = std::max(result.verdict, s.verdict);
  }
  for (const StageComparison& s : result.end_to_end)
    result.verdict = std::max(result.verdict, s.verdict);
  return result;
}

}  // namespace

ParityResult compare_captured(const Plan& plan, ConstImageView scene,
                              const CapturedStages& captured, const StageTrace& cpu,
                              const DeviceProfile& profile, const CompareOptions& opt) {
  std::vector<std::string> names;
  for (const auto& [name, c] : captured) names.push_back(name);
  return compare_core(plan, scene, names, [&](const std::string& n) {
    const CapturedStage& c = captured.at(n);
    return Held{c.image, {}, c.code_bits, c.srgb};
  }, &cpu, profile, opt, nullptr);
}

ParityResult check_with_oracle(const Plan& plan, ConstImageView scene,
                               const CapturedStages& captured, const DeviceProfile& profile,
                               const CompareOptions& opt, double* cpu_ms) {
  std::vector<std::string> names;
  for (const auto& [name, c] : captured) names.push_back(name);
  return compare_core(plan, scene, names, [&](const std::string& n) {
    const CapturedStage& c = captured.at(n);
    return Held{c.image, {}, c.code_bits, c.srgb};
  }, nullptr, profile, opt, cpu_ms);
}

ParityResult compare_streamed(const Plan& plan, ConstImageView scene,
                              const std::vector<std::string>& captured, const CaptureLoader& load,
                              const DeviceProfile& profile, const CompareOptions& opt,
                              double* oracle_ms) {
  return compare_core(plan, scene, captured, [&](const std::string& n) {
    OwnedCapture o = load(n);
    Held held{{}, std::move(o.image), o.code_bits, o.srgb};
    held.view = held.owned.cview();
    return held;
  }, nullptr, profile, opt, oracle_ms);
}

}  // namespace bloomref::parity
