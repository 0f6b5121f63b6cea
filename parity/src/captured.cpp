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

}  // namespace

ParityResult compare_captured(const Plan& plan, ConstImageView scene,
                              const CapturedStages& captured, const StageTrace& cpu,
                              const DeviceProfile& profile, const CompareOptions& opt) {
  const BloomParams& p = plan.params;
  const int threads = p.threads, w = scene.width, h = scene.height;
  const BoundContext ctx{&profile, p.storage, threads};
  const Kernel& kernel = kernel_for(p.kernel);
  const HalfRounding rounding = half_rounding_for(profile);
  ParityResult result;
  result.profile = profile;
  for (const auto& [name, cap] : captured)
    if (!find_stage(plan, name))
      throw ParamError("no stage '" + name + "' in this plan (" + to_string(p.method) + ", " +
                       std::to_string(p.passes) + " passes)");

  // The sanitised scene (unrounded): what the input pass computes before storing.
  Image sanitized(w, h);
  sanitize(scene, sanitized.view(), p.nonfinite, p.storage, threads);

  std::map<std::string, Image> computed;  // stages without capture: the oracle's, stored
  std::map<std::string, Image> carried;   // and the error each carries
  std::map<std::string, Image> e2e;       // end-to-end bound of each stage, on the CPU's images
  auto V = [&](const std::string& n) -> ConstImageView {
    const auto c = captured.find(n);
    return c != captured.end() ? c->second.image : computed.at(n).cview();
  };
  auto E = [&](const std::string& n) -> const Image* {
    const auto it = carried.find(n);
    return it == carried.end() ? nullptr : &it->second;
  };
  auto C = [&](const std::string& n) -> const Image& {
    const StageResult* r = cpu.find(n);
    if (!r) throw ParamError("the CPU trace has no stage '" + n + "'");
    return r->image;
  };
  const float strength = p.strength;

  for (const StageSpec& spec : plan.stages) {
    const std::string& name = spec.name;
    const std::vector<std::string> in = stage_inputs(plan, spec);
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

    const auto cap = captured.find(name);
    if (cap != captured.end()) {
      const CapturedStage& cs = cap->second;
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
      Image e_judged = e;
      if (!codes_e2e.empty()) add_into(e_judged, codes_e2e);
      overridden(bound);
      overridden(e_judged);
      // The gates' allowance: the capture's own rounding; and with f16 storage, what stages
      // without capture carry, which holds their roundings (llvmpipe's toward zero is biased:
      // half an ULP a stage on average, as systematic as the offsets the gates look for).
      const ExtraTerms terms(*b, {{"carried from stages without capture", &inherited},
                                  {"8-bit capture: half a code", &codes}});
      const ExtraTerms terms_e2e(*b, {{"8-bit capture: half a code", &codes_e2e}});
      StageComparison iso = judge(name, cs.image, oracle.cview(), bound, terms, p.storage,
                                  profile, opt, threads, &gates, codes.empty() ? nullptr : &codes,
                                  p.storage == Storage::f16 && !inherited.empty() ? &inherited
                                                                                  : nullptr);
      if (opt.causes && iso.verdict != Verdict::pass) {
        CauseContext cc{plan, sanitized.cview(), profile, rounding, threads,
                        [&](const std::string& n) { return V(n); },
                        [&](const std::string& n) { return captured.count(n) > 0; }};
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

}  // namespace bloomref::parity
