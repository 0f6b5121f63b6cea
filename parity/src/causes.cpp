// The usual causes of a bloom stage that fails, each tested as the oracle run with that one
// change (docs/design.md, "Parity and the tolerance model"). The failing stage is recomputed from the same captures as
// its isolated oracle, through the stages without capture between them, with the change; the
// hypothesis's score is the fraction of values it brings within the stage's bound.
//
// Flipping and the R/B exchange are taken as properties of every capture (a readback's row
// order and channel order are the same for all the images one tool saved): the captures the
// stage reads are turned back before the stage is recomputed, and the result turned as the
// capture was.
#include "causes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <optional>

#include "bloomref/mip.h"
#include "tolerance.h"
#include "bloomref/parallel.h"
#include "bloomref/parity/variants.h"
#include "bloomref/stages.h"
#include "chain.h"

namespace bloomref::parity::detail {
namespace {

struct Hypothesis {
  std::string id, description, detail;
  bool flip = false, swap_rb = false;
  bool transform_inputs = true;  // flip / swap_rb hold for every capture, not the target alone
  bool stale = false;            // the pass was not drawn: its target holds the pass before last
  bool along_x = false;          // a vertical pass offsets along x (seed 001)
  Sampling sampling;  // its subtexel bits are the profile's
  const Kernel* kernel = nullptr;  // another kernel for every blur pass
  std::vector<float> weights;      // fitted weights, for the target pass only
  int pass_delta = 0;              // blur passes left out (-1) or added (+1)
  float strength_scale = 1.0f;     // the composite adds strength * scale * bloom
  bool ge = false, clamp_bright = false, f16 = false, no_exposure = false;
  bool clamp_blur = false;  // every blur pass's output clamped to [0, 1]
  float threshold = NAN;    // another threshold for the bright pass or the first level's soft
                            // threshold (fitted); NaN: the plan's
  int gamma_times = 1;
  bool pow_negative = false;  // gamma as pow(x, 1 / gamma) without max(x, 0): NaN below 0
  float gamma = 0.0f;         // another gamma (fitted); 0: the plan's
  float spacing = 1.0f;       // the target pass's taps this many times as far apart (fitted)
  float target_gain = 1.0f;   // the target stage's output times this (fitted)
  float mix_amount = NAN;     // composite as mix(scene, bloom, a) (fitted); NaN: scene + s bloom
  float add_amount = NAN;     // composite as scene + a bloom where mix is specified (fitted)
  float tent_gain = 1.0f;     // up.k as down.k + g tent(up.k+1) (fitted)
  float level_weight = NAN;   // a blended up.k's constant C (fitted); NaN: level_blend's
  std::optional<TexelStep> texel_step;  // the downsample's step from another size
  bool pow_negative_karis = false;  // the Karis average's pow of a negative channel: the
                                    // oracle's NaN there is undefined in GLSL (the capture's)
  int flip_input = -1;        // the composite reads one input flipped: 0 the scene, 1 the bloom
  bool rgba8 = false;         // every stage stored in an 8-bit unsigned normalised target
  bool r11g11b10 = false;     // every stage stored in R11F_G11F_B10F (packed unsigned floats)
  bool packed_toward_zero = false;  // ... rounded toward zero (llvmpipe), not to the nearest
  bool scene_stored = false;  // the scene texture too, which the bright pass reads
  std::optional<LumaSpace> space;  // the threshold's luminance taken of colour in this space
  bool unwritten = false;     // the bright output left unwritten below the threshold: those
                              // texels hold whatever the target held (the capture's values)
  bool nonfinite = false;     // NaN/Inf made at the target stage (the capture's, where the
                              // oracle's value is finite)
  bool axes_swapped = false;  // the blur starts on the other axis: every pass's axis swapped
  bool other_luma = false;    // the luminance with the other weights (Rec. 601 for 709, or back)
  std::string source;         // a mip stage reads this level where its first input is specified
  int params = 0;             // how many numbers were fitted to the capture
  bool sampled() const { return !sampling.is_default(); }
  /// Changes only the target's own output after the oracle computed it (a gain, the capture's
  /// values taken where the stage did not compute them): made from the oracle's image.
  bool after_oracle_only() const {
    return !flip && !swap_rb && !stale && !along_x && !sampled() && !kernel && weights.empty() &&
           pass_delta == 0 && strength_scale == 1.0f && !ge && !clamp_bright && !f16 &&
           !no_exposure && !clamp_blur && std::isnan(threshold) && gamma_times == 1 &&
           !pow_negative && gamma == 0.0f && spacing == 1.0f && std::isnan(mix_amount) &&
           std::isnan(add_amount) && tent_gain == 1.0f && std::isnan(level_weight) &&
           !texel_step &&
           !pow_negative_karis &&
           flip_input < 0 && !rgba8 && !r11g11b10 && !space && !scene_stored &&
           !axes_swapped && !other_luma && source.empty();
  }
};

struct NotApplicable {};

bool changes(const Hypothesis& h, StageKind k, bool is_target) {
  if (h.rgba8 || h.r11g11b10) return true;
  switch (k) {
    case StageKind::input: return h.f16;
    case StageKind::bright:
      return h.ge || h.clamp_bright || h.f16 || !std::isnan(h.threshold) || h.space ||
             h.other_luma;
    case StageKind::blur:
      return h.sampled() || h.kernel || h.clamp_blur || h.axes_swapped ||
             (is_target && (!h.weights.empty() || h.stale || h.along_x || h.spacing != 1.0f)) ||
             h.f16;
    case StageKind::down:
      return h.sampled() || h.ge || h.f16 || h.texel_step || !std::isnan(h.threshold) ||
             h.other_luma || h.space || (is_target && !h.source.empty());
    case StageKind::up:
      return h.sampled() || h.f16 ||
             (is_target && (!h.source.empty() || !std::isnan(h.level_weight)));
    case StageKind::bloom: return h.sampled() || h.f16;
    case StageKind::composite:
      return h.f16 || h.rgba8 || h.strength_scale != 1.0f || !std::isnan(h.mix_amount) ||
             !std::isnan(h.add_amount) ||
             h.flip_input >= 0;
    case StageKind::tonemap: return h.no_exposure || h.f16;
    case StageKind::output: return h.gamma_times != 1 || h.pow_negative || h.gamma > 0 || h.f16;
  }
  return false;
}

// Evaluates the target stage under one hypothesis; stages it does not change are read from the
// isolated oracle's own images.
class Evaluator {
 public:
  /// `oracle`: the target's isolated oracle when already computed (a hypothesis that changes
  /// only the target's output starts from a copy of it).
  Evaluator(const CauseContext& ctx, const Hypothesis& h, const StageSpec& target,
            const Image* oracle = nullptr)
      : ctx_(ctx), p_(ctx.plan.params), h_(h), target_(target), oracle_(oracle) {}

  // The part of down.k that up.k keeps (1, or 1 - C_k when the levels mix).
  float kept_of_current() const {
    return level_blend(p_, target_.pass, int(ctx_.plan.levels.size())).kept();
  }

  Image target() {
    Image out = oracle_ && oracle_->width() && h_.after_oracle_only() ? *oracle_ : compute(target_, true);
    if (h_.unwritten || h_.nonfinite || h_.pow_negative_karis) take_from_capture(out);
    if ((h_.rgba8 || h_.r11g11b10) && ctx_.target_bound) {
      round_within_bound(out);
    } else {
      write_all(out);
    }
    if (h_.target_gain != 1.0f)
      for (std::size_t i = 0; i < out.values().size(); ++i)
        if (i % kChannels != 3) out.data()[i] *= h_.target_gain;
    if (h_.tent_gain != 1.0f) {  // current + g (oracle - current): the tent's sum scaled by g
      const ConstImageView cur = value(stage_inputs(ctx_.plan, target_)[1]).view;
      const float keep = kept_of_current();  // what the blend keeps of the current level
      for (int y = 0; y < out.height(); ++y)
        for (int x = 0; x < out.width(); ++x)
          for (int c = 0; c < 3; ++c) {
            float& v = out.pixel(x, y)[c];
            const float d = keep * cur.pixel(x, y)[c];
            v = d + h_.tent_gain * (v - d);
          }
      // Stored as the level is: the bound's storage term is the oracle's value's, and this
      // value may lie in another binade.
      store_as_device(out, target_.kind);
    }
    if (h_.f16) store(out.view(), Storage::f16, ctx_.rounding, ctx_.threads);
    if (h_.flip) flip_vertically(out);
    if (h_.swap_rb) swap_red_blue(out);
    return out;
  }

 private:
  struct Val {
    ConstImageView view;
    bool changed;
  };

  Val value(const std::string& name) {
    const auto m = memo_.find(name);
    if (m != memo_.end()) return {m->second.cview(), true};
    if (name != target_.name && ctx_.captured(name)) {
      if (!h_.transform_inputs || (!h_.flip && !h_.swap_rb)) return {held(name), false};
      Image img = copy(held(name));
      if (h_.flip) flip_vertically(img);
      if (h_.swap_rb) swap_red_blue(img);
      return keep(name, std::move(img));
    }
    const StageSpec* spec = find_stage(ctx_.plan, name);
    if (h_.pass_delta != 0 && spec->kind == StageKind::blur && target_.kind != StageKind::blur &&
        name == bloom_stage_name(ctx_.plan))
      return keep(name, bloom_with_delta());
    bool changed = changes(h_, spec->kind, false);
    for (const std::string& in : stage_inputs(ctx_.plan, *spec)) changed |= value(in).changed;
    if (!changed) return {held(name), false};
    Image img = compute(*spec, false);
    store_as_device(img, spec->kind);
    return keep(name, std::move(img));
  }

  // A stage as the isolated oracle reads it; one the comparison has released (it streams its
  // images) makes the hypothesis not applicable.
  ConstImageView held(const std::string& name) const {
    const ConstImageView v = ctx_.view(name);
    if (!v.data) throw NotApplicable{};
    return v;
  }

  Val keep(const std::string& name, Image img) {
    auto it = memo_.insert_or_assign(name, std::move(img)).first;
    return {it->second.cview(), true};
  }

  // The capture's own values where the hypothesis says the stage did not compute them: the
  // texels the bright pass leaves dark (unwritten), or the values the capture holds as NaN or
  // Inf where the oracle's are finite (made there).
  void take_from_capture(Image& out) const {
    const ConstImageView cap = ctx_.view(target_.name);
    if (!cap.data || cap.width != out.width() || cap.height != out.height()) throw NotApplicable{};
    for (int y = 0; y < out.height(); ++y)
      for (int x = 0; x < out.width(); ++x) {
        float* o = out.pixel(x, y);
        const float* g = cap.pixel(x, y);
        if (h_.unwritten && o[0] == 0 && o[1] == 0 && o[2] == 0) std::copy(g, g + 3, o);
        if (h_.nonfinite)
          for (int c = 0; c < 3; ++c)
            if (std::isfinite(o[c]) && !std::isfinite(g[c])) o[c] = g[c];
        if (h_.pow_negative_karis && (std::isnan(o[0]) || std::isnan(o[1]) || std::isnan(o[2])))
          std::copy(g, g + 3, o);
      }
  }

  // The target stored as the hypothesis's format: the device's value before the write lies
  // within the bound of the oracle's, and the write rounds it monotonically, so the stored
  // value lies between the rounded ends of that range. The capture is taken where it lies
  // there, else the nearer end.
  void round_within_bound(Image& out) const {
    const ConstImageView cap = ctx_.view(target_.name);
    const Image& bound = *ctx_.target_bound;
    if (!cap.data || cap.width != out.width() || cap.height != out.height() ||
        bound.width() != out.width() || bound.height() != out.height()) {
      write_all(out);
      return;
    }
    for (int y = 0; y < out.height(); ++y)
      for (int x = 0; x < out.width(); ++x)
        for (int c = 0; c < 3; ++c) {
          float& v = out.pixel(x, y)[c];
          const float b = bound.cview().pixel(x, y)[c], g = cap.pixel(x, y)[c];
          const float lo = written(v - b, c), hi = written(v + b, c);
          v = std::isnan(g) || !(b < INFINITY) ? lo : std::min(std::max(written(g, c), lo), hi);
        }
  }

  // RGB clamped to [0, 1] as GLSL's clamp() and an 8-bit target do (NaN left as it is).
  static void clamp_to_unit(Image& img) {
    for (std::size_t i = 0; i < img.values().size(); ++i)
      if (i % kChannels != 3 && !std::isnan(img.data()[i]))
        img.data()[i] = std::min(std::max(img.data()[i], 0.0f), 1.0f);
  }

  static Image copy(ConstImageView v) {
    Image out(v.width, v.height);
    for (int y = 0; y < v.height; ++y)
      std::copy(v.row(y), v.row(y) + std::size_t(v.width) * kChannels, out.view().row(y));
    return out;
  }

  // `kind`: the stage the image is of (the mip chain's levels may be stored otherwise).
  void store_as_device(Image& img, StageKind kind = StageKind::blur) const {
    store(img.view(), stage_storage(p_, kind), ctx_.rounding, ctx_.threads);
    if (h_.f16) store(img.view(), Storage::f16, ctx_.rounding, ctx_.threads);
    write_all(img);
  }

  static float packed(float v, int mantissa, bool toward_zero) {
    return static_cast<float>(round_to_packed(v, mantissa, toward_zero));
  }
  // Channel c of a value as the hypothesis's target format stores it: an RGBA8 target's write
  // (GL 4.6, 2.3.5.2: clamped to [0, 1], the nearest of the 255ths; NaN as 0), a packed float's
  // (packed), or the value itself.
  float written(float v, int c) const {
    if (h_.rgba8) return round_to_unorm8(v);
    if (h_.r11g11b10) return packed(v, c == 2 ? 5 : 6, h_.packed_toward_zero);
    return v;
  }
  void write_all(Image& img) const {
    if (!h_.rgba8 && !h_.r11g11b10) return;
    for (std::size_t i = 0; i < img.values().size(); ++i)
      if (i % kChannels != 3) img.data()[i] = written(img.data()[i], int(i % kChannels));
  }

  Image blur(ConstImageView src, Axis axis, bool is_target) const {
    Image out(src.width, src.height);
    const Kernel& plan_kernel = kernel_for(p_.kernel);
    const Kernel& k = h_.kernel ? *h_.kernel : plan_kernel;
    Sampling smp = h_.sampling;
    smp.subtexel_bits = ctx_.profile.subtexel_bits;
    if (is_target && !h_.weights.empty())
      blur_pass_variant(src, out.view(), axis, plan_kernel.offsets_f32, h_.weights, smp,
                        ctx_.threads);
    else if (h_.sampled() || h_.kernel)
      blur_pass_variant(src, out.view(), axis, k.offsets_f32, k.weights_f32, smp, ctx_.threads);
    else
      blur_pass_fast(src, out.view(), {axis, &k, ctx_.profile.subtexel_bits}, ctx_.threads);
    return out;
  }

  // The threshold's luminance: the declared, or its other weights or space under the hypothesis.
  LumaRule luma() const {
    LumaRule r = luma_rule(p_);
    if (h_.other_luma) r.weights = r.weights == Luma::rec709 ? Luma::rec601 : Luma::rec709;
    if (h_.space) r.space = *h_.space;
    return r;
  }

  Axis axis_of(int pass) const {
    const bool declared = (pass % 2 == 1) == (p_.first_axis == FirstAxis::horizontal);
    return declared != h_.axes_swapped ? Axis::horizontal : Axis::vertical;
  }

  // The bloom of a plan with one pass fewer or more: from the last captured pass (or bright).
  Image bloom_with_delta() {
    const int n = p_.passes;
    int j = n;
    while (j > 0 && !ctx_.captured("blur." + std::to_string(j))) --j;
    if (j == n || n + h_.pass_delta < j) throw NotApplicable{};
    Image cur = copy(value(j == 0 ? "bright" : "blur." + std::to_string(j)).view);
    for (int k = j + 1; k <= n + h_.pass_delta; ++k) {
      cur = blur(cur.cview(), axis_of(k), false);
      store_as_device(cur);
    }
    return cur;
  }

  Image compute(const StageSpec& spec, bool is_target) {
    const std::vector<std::string> names = stage_inputs(ctx_.plan, spec);
    std::vector<ConstImageView> in;
    for (const std::string& n : names) in.push_back(value(n).view);
    if (is_target && !h_.source.empty()) {
      in[0] = value(h_.source).view;
      if (!in[0].data) throw NotApplicable{};
    }
    const int threads = ctx_.threads;
    Sampling smp = h_.sampling;
    smp.subtexel_bits = ctx_.profile.subtexel_bits;
    switch (spec.kind) {
      case StageKind::input:
        return copy(ctx_.sanitized);
      case StageKind::bright: {
        Image out(ctx_.sanitized.width, ctx_.sanitized.height);
        // A scene stored in the hypothesis's target format is what the bright pass reads.
        Image stored_scene;
        ConstImageView scene = ctx_.sanitized;
        if (h_.scene_stored) {
          stored_scene = copy(ctx_.sanitized);
          store_as_device(stored_scene);
          scene = stored_scene.cview();
        }
        const float threshold = std::isnan(h_.threshold) ? p_.threshold : h_.threshold;
        // The colour's space (a threshold set in gamma space): the texel itself is kept as it is.
        const LumaRule luma = this->luma();
        if (h_.ge || h_.clamp_bright)
          extract_bright_variant(scene, out.view(), threshold, h_.ge, h_.clamp_bright,
                                 threads, luma);
        else
          extract_bright(scene, out.view(), threshold, threads, false, nullptr, nullptr, luma);
        return out;
      }
      case StageKind::blur: {
        if (is_target && h_.pass_delta < 0) return copy(in[0]);
        if (is_target && h_.stale) return copy(value("blur." + std::to_string(spec.pass - 2)).view);
        if (is_target && h_.along_x) {
          const Kernel& k = kernel_for(p_.kernel);
          Image out(in[0].width, in[0].height);
          Sampling plain;
          plain.subtexel_bits = ctx_.profile.subtexel_bits;
          blur_pass_variant(in[0], out.view(), Axis::horizontal, k.offsets_f32, k.weights_f32, plain,
                            threads, 1.0f / static_cast<float>(in[0].height));
          return out;
        }
        if (is_target && h_.spacing != 1.0f) {
          const Kernel& k = kernel_for(p_.kernel);
          Image out(in[0].width, in[0].height);
          Sampling plain;
          plain.subtexel_bits = ctx_.profile.subtexel_bits;
          const int n = spec.axis == Axis::horizontal ? in[0].width : in[0].height;
          blur_pass_variant(in[0], out.view(), spec.axis, k.offsets_f32, k.weights_f32, plain,
                            threads, h_.spacing / static_cast<float>(n));
          return out;
        }
        Image out = blur(in[0], axis_of(spec.pass), true);
        if (is_target && h_.pass_delta > 0) {
          store_as_device(out);
          out = blur(out.cview(), axis_of(spec.pass + 1), false);
        }
        if (h_.clamp_blur) clamp_to_unit(out);
        return out;
      }
      case StageKind::down: {
        const LevelSize& l = ctx_.plan.levels[spec.pass - 1];
        Image out(l.width, l.height);
        const bool first = spec.pass == 1;
        // The sampling hypotheses are written for seed 002's chain only.
        if ((h_.sampled() || h_.ge) && p_.mip_variant()) throw NotApplicable{};
        if (h_.sampled() || h_.ge)
          downsample_variant(in[0], out.view(), first, p_.threshold, p_.karis && first, !h_.ge,
                             smp, threads, luma());
        else
        {
          BloomParams q = p_;
          if (h_.texel_step) q.texel_step = *h_.texel_step;
          if (!std::isnan(h_.threshold)) q.threshold = h_.threshold;
          q.luma = luma().weights;
          q.luma_space = luma().space;
          downsample(in[0], out.view(),
                     downsample_options(q, spec.pass, ctx_.sanitized.width,
                                        ctx_.sanitized.height, ctx_.profile.subtexel_bits),
                     threads);
        }
        return out;
      }
      case StageKind::up:
        if (p_.level_combine == LevelCombine::sum) {  // three.js's sum of the blurred levels
          if (h_.sampled()) throw NotApplicable{};
          Image out(ctx_.plan.levels[0].width, ctx_.plan.levels[0].height);
          sum_levels(in, out.view(), p_.level_factors, p_.level_radius, p_.level_strength,
                     ctx_.profile.subtexel_bits, threads);
          return out;
        }
        [[fallthrough]];
      case StageKind::bloom: {
        const bool up = spec.kind == StageKind::up;
        const ConstImageView cur = up ? in[1] : ConstImageView{};
        Image out = up ? Image(cur.width, cur.height)
                       : Image(ctx_.sanitized.width, ctx_.sanitized.height);
        if (h_.sampled() && p_.mip_variant()) throw NotApplicable{};
        if (h_.sampled())
          upsample_variant(in[0], cur, out.view(), smp, threads);
        else if (!up && p_.bloom_upscale == BloomUpscale::bilinear)
          upscale_bilinear(in[0], out.view(), ctx_.profile.subtexel_bits, threads);
        else
        {
          LevelBlend blend;
          if (up) blend = level_blend(p_, spec.pass, int(ctx_.plan.levels.size()));
          if (up && is_target && !std::isnan(h_.level_weight)) blend.weight = h_.level_weight;
          upsample_tent(in[0], cur, out.view(), ctx_.profile.subtexel_bits, threads, nullptr,
                        p_.upsample_radius, blend, p_.texel_step == TexelStep::target,
                        up ? p_.upsample : UpsampleFilter::tent);
        }
        return out;
      }
      case StageKind::composite: {
        Image out(in[0].width, in[0].height);
        Image flipped;
        if (h_.flip_input >= 0) {
          flipped = copy(in[std::size_t(h_.flip_input)]);
          flip_vertically(flipped);
          in[std::size_t(h_.flip_input)] = flipped.cview();
        }
        if (!std::isnan(h_.mix_amount)) {  // mix(scene, bloom, a) = scene + a (bloom - scene)
          const float a = h_.mix_amount;
          for (int y = 0; y < out.height(); ++y)
            for (int x = 0; x < out.width(); ++x) {
              const float *sc = in[0].pixel(x, y), *b = in[1].pixel(x, y);
              float* o = out.pixel(x, y);
              for (int c = 0; c < 3; ++c) o[c] = sc[c] + a * (b[c] - sc[c]);
              o[3] = 1.0f;
            }
          return out;
        }
        if (!std::isnan(h_.add_amount))
          composite(in[0], in[1], out.view(), h_.add_amount, threads);
        else if (p_.composite_mode == CompositeMode::mix)
          composite_mix(in[0], in[1], out.view(), p_.strength * h_.strength_scale, threads);
        else
          composite(in[0], in[1], out.view(), p_.strength * h_.strength_scale, threads);
        return out;
      }
      case StageKind::tonemap: {
        Image out(in[0].width, in[0].height);
        tonemap(in[0], out.view(), h_.no_exposure ? 1.0f : p_.exposure, threads);
        return out;
      }
      case StageKind::output: {
        Image out(in[0].width, in[0].height);
        if (h_.gamma_times == 0) return copy(in[0]);
        encode_output(in[0], out.view(), h_.gamma > 0 ? h_.gamma : p_.gamma, threads);
        if (h_.pow_negative)  // GLSL's pow(x, y) is undefined for x < 0: NaN on every GPU seen
          for (int y = 0; y < out.height(); ++y)
            for (int x = 0; x < out.width(); ++x)
              for (int c = 0; c < 3; ++c)
                if (in[0].pixel(x, y)[c] < 0) out.pixel(x, y)[c] = NAN;
        for (int t = 1; t < h_.gamma_times; ++t) {
          Image again(out.width(), out.height());
          encode_output(out.cview(), again.view(), p_.gamma, threads);
          out = std::move(again);
        }
        return out;
      }
    }
    return {};
  }

  const CauseContext& ctx_;
  const BloomParams& p_;
  const Hypothesis& h_;
  const StageSpec& target_;
  const Image* oracle_;
  std::map<std::string, Image> memo_;
};

// The stages the target is recomputed through: itself and, up to the captures, the stages it
// reads.
std::vector<std::string> segment(const CauseContext& ctx, const StageSpec& target) {
  std::vector<std::string> names;
  std::vector<std::string> todo{target.name};
  std::vector<std::string> seen;
  while (!todo.empty()) {
    const std::string n = todo.back();
    todo.pop_back();
    if (std::find(seen.begin(), seen.end(), n) != seen.end()) continue;
    seen.push_back(n);
    if (n != target.name && ctx.captured(n)) continue;
    names.push_back(n);
    for (const std::string& in : stage_inputs(ctx.plan, *find_stage(ctx.plan, n)))
      todo.push_back(in);
  }
  return names;
}

// Solves the m x m system a x = b (row-major) by Gaussian elimination with partial pivoting;
// nothing when a pivot is negligible against the matrix's scale.
std::optional<std::vector<double>> solve(std::vector<double> a, std::vector<double> b, int m) {
  double scale = 0;
  for (double v : a) scale = std::max(scale, std::fabs(v));
  if (!(scale > 0)) return std::nullopt;
  for (int col = 0; col < m; ++col) {
    int piv = col;
    for (int r = col + 1; r < m; ++r)
      if (std::fabs(a[r * m + col]) > std::fabs(a[piv * m + col])) piv = r;
    if (std::fabs(a[piv * m + col]) < 1e-13 * scale) return std::nullopt;
    for (int c = 0; c < m; ++c) std::swap(a[col * m + c], a[piv * m + c]);
    std::swap(b[col], b[piv]);
    for (int r = col + 1; r < m; ++r) {
      const double f = a[r * m + col] / a[col * m + col];
      for (int c = col; c < m; ++c) a[r * m + c] -= f * a[col * m + c];
      b[r] -= f * b[col];
    }
  }
  std::vector<double> x(m);
  for (int r = m - 1; r >= 0; --r) {
    double s = b[r];
    for (int c = r + 1; c < m; ++c) s -= a[r * m + c] * x[c];
    x[r] = s / a[r * m + r];
  }
  return x;
}

// The weights w (the kernel's count, symmetric pairs) that best explain `out` as a blur of
// `src` with the kernel's offsets, by least squares over every finite RGB value: out = w0 s0 +
// sum_i w_i (s+i + s-i), the samples taken as the specification's lookups take them.
std::optional<std::vector<float>> fit_weights(ConstImageView src, ConstImageView out, Axis axis,
                                              const Kernel& k, int subtexel_bits) {
  const bool hz = axis == Axis::horizontal;
  const int n = hz ? src.width : src.height, m = static_cast<int>(k.weights_f32.size());
  if (out.width != src.width || out.height != src.height) return std::nullopt;
  const float d = 1.0f / static_cast<float>(n);
  std::vector<double> ata(std::size_t(m) * m, 0.0), atb(m, 0.0);
  std::vector<double> r(m);
  for (int y = 0; y < src.height; ++y)
    for (int x = 0; x < src.width; ++x) {
      const int pos = hz ? x : y;
      const float uv = texel_centre(pos, n);
      const AxisTap<float> other =
          gl_axis_tap(texel_centre(hz ? y : x, hz ? src.height : src.width),
                      hz ? src.height : src.width, subtexel_bits);
      auto sample = [&](float s, float v[3]) {
        const AxisTap<float> t = gl_axis_tap(s, n, subtexel_bits);
        if (hz) sample_rgb(src, t, other, v);
        else sample_rgb(src, other, t, v);
      };
      float s0[3], sp[3], sm[3];
      sample(uv, s0);
      std::vector<std::array<float, 3>> pairs(m);
      for (int i = 1; i < m; ++i) {
        sample(uv + d * k.offsets_f32[i], sp);
        sample(uv - d * k.offsets_f32[i], sm);
        for (int c = 0; c < 3; ++c) pairs[i][c] = sp[c] + sm[c];
      }
      for (int c = 0; c < 3; ++c) {
        const double o = out.pixel(x, y)[c];
        r[0] = s0[c];
        for (int i = 1; i < m; ++i) r[i] = pairs[i][c];
        bool finite = std::isfinite(o);
        for (double v : r) finite &= std::isfinite(v);
        if (!finite) continue;
        for (int i = 0; i < m; ++i) {
          atb[i] += r[i] * o;
          for (int j = 0; j < m; ++j) ata[std::size_t(i) * m + j] += r[i] * r[j];
        }
      }
    }
  const auto w = solve(ata, atb, m);
  if (!w) return std::nullopt;
  return std::vector<float>(w->begin(), w->end());
}

// The factor k that best explains the target as the composite of the same scene and k times the
// bloom (least squares over the composite's values): a per-pass weight sum s != 1 scales the
// bloom of N passes by s^N. The target is taken back to the composite through the stages
// between (gamma: v^gamma; tone map: -ln(1 - v) / exposure, where v < 1).
struct CompositeFit {
  double add = NAN, mix = NAN;  // scene + add s bloom; mix(scene, bloom, mix)
};

// Both models of the composite fitted by least squares over its values (the target taken back
// to the composite through the stages between: gamma v^gamma, tone map -ln(1 - v) / exposure).
CompositeFit fit_composite(const CauseContext& ctx, const StageSpec& target) {
  const BloomParams& p = ctx.plan.params;
  std::vector<const StageSpec*> chain;  // target back to (not including) the composite
  const StageSpec* s = &target;
  while (s->kind != StageKind::composite) {
    if (s->kind != StageKind::output && s->kind != StageKind::tonemap) return {};
    chain.push_back(s);
    s = find_stage(ctx.plan, stage_inputs(ctx.plan, *s)[0]);
  }
  const std::vector<std::string> in = stage_inputs(ctx.plan, *s);
  const ConstImageView user = ctx.view(target.name), base = ctx.view(in[0]), bloom = ctx.view(in[1]);
  if (!user.data || !base.data || !bloom.data) return {};
  double num = 0, den = 0, mnum = 0, mden = 0;
  const bool mix = p.composite_mode == CompositeMode::mix;
  for (int y = 0; y < user.height; ++y)
    for (int x = 0; x < user.width; ++x)
      for (int c = 0; c < 3; ++c) {
        // The capture taken back through gamma and the tone map; `w` the square of the
        // slope of those stages there, so that each value counts by what it shows (a
        // saturated value taken back says little about the composite).
        double v = user.pixel(x, y)[c], slope = 1;
        for (const StageSpec* t : chain) {
          if (t->kind == StageKind::output) {
            const double in = std::pow(std::max(v, 0.0), double(p.gamma));
            slope *= in > 0 ? std::pow(in, 1.0 / p.gamma - 1) / p.gamma : 0.0;
            v = in;
          } else {
            slope *= p.exposure * (1 - v);
            v = v < 1 - 1e-6 ? -std::log1p(-v) / p.exposure : NAN;
          }
        }
        const double w = std::isfinite(slope) ? slope * slope : 0.0;
        // The specified model's bloom term (b, scaled by `add`) and the other model's (d,
        // whose amount is `mix`): scene + s bloom and mix, or the other way round.
        const double bl = bloom.pixel(x, y)[c], diff = bl - base.pixel(x, y)[c];
        const double b = double(p.strength) * (mix ? diff : bl);
        const double r = v - base.pixel(x, y)[c];
        const double d = mix ? bl : diff;
        if (!std::isfinite(r) || !std::isfinite(b) || !std::isfinite(d)) continue;
        num += w * r * b;
        den += w * b * b;
        mnum += w * r * d;
        mden += w * d * d;
      }
  CompositeFit f;
  if (den > 0) f.add = num / den;
  if (mden > 0) f.mix = mnum / mden;
  return f;
}

// The gamma g that best explains the output as pow(t, 1 / g) of its input t: the median of
// ln(t) / ln(out) over the values where both lie well inside (0, 1) (robust to the values a
// different bug touches). nullopt when it is the plan's within 0.1%, or nothing to fit.
std::optional<float> fit_gamma(const CauseContext& ctx, const StageSpec& target) {
  if (target.kind != StageKind::output) return std::nullopt;
  const ConstImageView user = ctx.view(target.name);
  const ConstImageView in = ctx.view(stage_inputs(ctx.plan, target)[0]);
  if (!user.data || !in.data || user.width != in.width || user.height != in.height)
    return std::nullopt;
  std::vector<double> g;
  const std::size_t values = std::size_t(user.width) * user.height * 3;
  const std::size_t step = std::max<std::size_t>(1, values / 1000000);
  std::size_t i = 0;
  for (int y = 0; y < user.height; ++y)
    for (int x = 0; x < user.width; ++x)
      for (int c = 0; c < 3; ++c, ++i) {
        if (i % step) continue;
        const double t = in.pixel(x, y)[c], o = user.pixel(x, y)[c];
        if (t > 1e-3 && t < 0.99 && o > 1e-3 && o < 0.999) g.push_back(std::log(t) / std::log(o));
      }
  if (g.size() < 16) return std::nullopt;
  std::nth_element(g.begin(), g.begin() + g.size() / 2, g.end());
  const double gamma = g[g.size() / 2];
  if (!std::isfinite(gamma) || gamma <= 0 || std::fabs(gamma / ctx.plan.params.gamma - 1) < 1e-3)
    return std::nullopt;
  return static_cast<float>(gamma);
}

// The thresholds a captured bright pass may have used: from the largest luminance among the
// scene texels it left dark (then `l > t` gives its mask) up to the smallest among those it
// kept; none when the mask fits no threshold or fits the plan's.
std::optional<std::pair<float, float>> fit_threshold(const CauseContext& ctx, const StageSpec& target) {
  if (target.kind != StageKind::bright) return std::nullopt;
  const ConstImageView user = ctx.view(target.name), scene = ctx.sanitized;
  if (!user.data || user.width != scene.width || user.height != scene.height) return std::nullopt;
  float dark = -INFINITY, kept = INFINITY;
  const LumaRule rule = luma_rule(ctx.plan.params);
  for (int y = 0; y < user.height; ++y)
    for (int x = 0; x < user.width; ++x) {
      const float* u = user.pixel(x, y);
      const float* s = scene.pixel(x, y);
      const float l = threshold_luminance(s[0], s[1], s[2], rule);
      if (!std::isfinite(l)) continue;
      if (u[0] == 0 && u[1] == 0 && u[2] == 0) dark = std::max(dark, l);
      else kept = std::min(kept, l);
    }
  const float t = ctx.plan.params.threshold;
  if (!(dark < kept) || !std::isfinite(dark) || !std::isfinite(kept)) return std::nullopt;
  if (dark < t && t < kept) return std::nullopt;  // the plan's threshold fits: not this
  return std::pair<float, float>(dark, kept);
}

// Sum of squared differences between `a` and `b` over finite RGB values.
double squared_residual(ConstImageView a, ConstImageView b) {
  double r = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double d = double(a.pixel(x, y)[c]) - b.pixel(x, y)[c];
        if (std::isfinite(d)) r += d * d;
      }
  return r;
}


// Golden-section search of `cost` over [lo, hi] (14 steps): its minimum, or `best` when that
// costs no more (`best_cost`).
template <class Cost>
double refine(const Cost& cost, double lo, double hi, double best, double best_cost) {
  const double g = (std::sqrt(5.0) - 1) / 2;
  double a = hi - g * (hi - lo), b = lo + g * (hi - lo), ca = cost(a), cb = cost(b);
  for (int i = 0; i < 14; ++i) {
    if (ca < cb) hi = b, b = a, cb = ca, a = hi - g * (hi - lo), ca = cost(a);
    else lo = a, a = b, ca = cb, b = lo + g * (hi - lo), cb = cost(b);
  }
  return std::min(ca, cb) < best_cost ? (ca < cb ? a : b) : best;
}

// The threshold of a first level's soft threshold (Prefilter::soft_knee, its knee the same
// fraction of it; or three.js's smoothstep, Prefilter::smoothstep) that best explains the
// captured down.1, by least squares: the plan's times 2^(j/4), j = -8..8 (from a threshold of 0:
// 2^(j/4) / 8, j = -12..8), then refined by golden-section search around the best. Nothing when
// no other threshold fits better, or the best is the plan's within 0.1% (of 0.01 from 0).
std::optional<float> fit_soft_threshold(const CauseContext& ctx, const StageSpec& target) {
  const BloomParams& p = ctx.plan.params;
  const bool soft = p.prefilter == Prefilter::soft_knee || p.prefilter == Prefilter::smoothstep;
  if (target.kind != StageKind::down || target.pass != 1 || !soft || !(p.threshold >= 0))
    return std::nullopt;
  const ConstImageView user = ctx.view(target.name), scene = ctx.sanitized;
  const LevelSize& l = ctx.plan.levels[0];
  if (!user.data || user.width != l.width || user.height != l.height) return std::nullopt;
  Image out(l.width, l.height);
  auto cost = [&](double t) {
    BloomParams q = p;
    q.threshold = static_cast<float>(t);
    downsample(scene, out.view(),
               downsample_options(q, 1, scene.width, scene.height, ctx.profile.subtexel_bits),
               ctx.threads);
    return squared_residual(out.cview(), user);
  };
  const double specified = cost(p.threshold);
  double best = p.threshold, best_cost = specified;
  // Around the specified threshold by quarter octaves; from a threshold of 0 (three.js's
  // default), the quarter octaves from 1/64 to 4.
  const double base = p.threshold > 0 ? double(p.threshold) : 1.0 / 8;
  for (int j = p.threshold > 0 ? -8 : -12; j <= 8; ++j) {
    if (j == 0 && p.threshold > 0) continue;
    const double t = base * std::exp2(j / 4.0);
    const double c = cost(t);
    if (c < best_cost) best = t, best_cost = c;
  }
  if (best == double(p.threshold)) return std::nullopt;
  const double t = refine(cost, best / 1.19, best * 1.19, best, best_cost);
  if (std::fabs(t - p.threshold) < 1e-3 * std::max(double(p.threshold), 1e-2)) return std::nullopt;
  return static_cast<float>(t);
}

// The factor k by which the target pass's taps are spaced (texel step k / n along its axis)
// that best explains the capture, by least squares: the likely values first (the other axis's
// texel size, as a pass reading the other texture's size or the wrong component takes it;
// twice, half), then refined by golden-section search around the best. Nothing when it is 1
// within 0.2% or nothing fits better than the specified spacing.
std::optional<float> fit_spacing(const CauseContext& ctx, const StageSpec& target, int threads) {
  if (target.kind != StageKind::blur) return std::nullopt;
  const ConstImageView src = ctx.view(stage_inputs(ctx.plan, target)[0]), user = ctx.view(target.name);
  if (!src.data || !user.data || user.width != src.width || user.height != src.height)
    return std::nullopt;
  const Kernel& k = kernel_for(ctx.plan.params.kernel);
  Sampling plain;
  plain.subtexel_bits = ctx.profile.subtexel_bits;
  const bool hz = target.axis == Axis::horizontal;
  const int n = hz ? src.width : src.height, other = hz ? src.height : src.width;
  Image out(src.width, src.height);
  auto cost = [&](double f) {
    blur_pass_variant(src, out.view(), target.axis, k.offsets_f32, k.weights_f32, plain, threads,
                      static_cast<float>(f / n));
    return squared_residual(out.cview(), user);
  };
  const double specified = cost(1.0);
  double best = 1.0, best_cost = specified;
  for (double f : {double(n) / other, double(other) / n, 2.0, 0.5, 1.5, 0.75, 3.0}) {
    if (std::fabs(f - 1) < 0.02 || f < 0.1 || f > 8) continue;
    const double c = cost(f);
    if (c < best_cost) best = f, best_cost = c;
  }
  if (best == 1.0) return std::nullopt;
  const double f = refine(cost, best / 1.25, best * 1.25, best, best_cost);
  // A fitted spacing on the other axis's texel size is that size, not a near miss of it.
  for (double snap : {double(n) / other, double(other) / n, 2.0, 0.5})
    if (std::fabs(f / snap - 1) < 0.002) return static_cast<float>(snap);
  if (std::fabs(f - 1) < 0.002) return std::nullopt;
  return static_cast<float>(f);
}

// The gain g that best explains `user` as g times `reference` (least squares over finite RGB
// values): a blur whose weights sum to g against the isolated oracle; with `base`, up.k less
// down.k against the tent (up.k = down.k + g tent(up.k+1)). `lift` is added to each user value
// (half a quantum of a storage that truncates, whose bias would pull the slope down by up to a
// quantum). Nothing when g is 1 within 1e-4, or not positive.
std::optional<float> fit_gain(ConstImageView user, ConstImageView reference,
                              ConstImageView base = {},
                              const std::function<double(double, int)>& lift = {}) {
  if (!user.data || !reference.data || user.width != reference.width ||
      user.height != reference.height ||
      (base.data && (base.width != user.width || base.height != user.height)))
    return std::nullopt;
  double num = 0, den = 0;
  for (int y = 0; y < user.height; ++y)
    for (int x = 0; x < user.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double uv = user.pixel(x, y)[c];
        const double u = uv + (lift ? lift(uv, c) : 0.0) - (base.data ? base.pixel(x, y)[c] : 0.0);
        const double r = reference.pixel(x, y)[c];
        if (!std::isfinite(u) || !std::isfinite(r)) continue;
        num += u * r;
        den += r * r;
      }
  if (!(den > 0)) return std::nullopt;
  const double g = num / den;
  if (!std::isfinite(g) || g <= 0 || std::fabs(g - 1) < 1e-4) return std::nullopt;
  return static_cast<float>(g);
}

// The shift s (texels added to both lookup coordinates, as a shader's offset does) that best
// explains the target pass from its input, by least squares over candidates and a golden-
// section refinement around the best. Nothing when no shift fits better than none, or when it
// is a half texel (half-texel-shift tests that one) or under 0.05 texel.
std::optional<float> fit_shift(const CauseContext& ctx, const StageSpec& target, int threads) {
  if (target.kind != StageKind::blur) return std::nullopt;
  const ConstImageView src = ctx.view(stage_inputs(ctx.plan, target)[0]), user = ctx.view(target.name);
  if (!src.data || !user.data || user.width != src.width || user.height != src.height)
    return std::nullopt;
  const Kernel& k = kernel_for(ctx.plan.params.kernel);
  Image out(src.width, src.height);
  auto cost = [&](double shift) {
    Sampling smp;
    smp.subtexel_bits = ctx.profile.subtexel_bits;
    smp.shift = static_cast<float>(shift);
    blur_pass_variant(src, out.view(), target.axis, k.offsets_f32, k.weights_f32, smp, threads);
    return squared_residual(out.cview(), user);
  };
  const double none = cost(0.0);
  double best = 0.0, best_cost = none;
  for (double c : {0.25, -0.25, 0.75, -0.75, 1.0, -1.0, 1.5, -1.5, 2.0, -2.0, 3.0, -3.0}) {
    const double v = cost(c);
    if (v < best_cost) best = c, best_cost = v;
  }
  if (best == 0.0) return std::nullopt;
  double f = refine(cost, best - 0.25, best + 0.25, best, best_cost);
  const double snapped = std::round(f * 4) / 4;  // quarter texels, as shaders write them
  if (std::fabs(f - snapped) < 0.01) f = snapped;
  if (std::fabs(std::fabs(f) - 0.5) < 0.02 || std::fabs(f) < 0.05) return std::nullopt;
  return static_cast<float>(f);
}

// The signature of a bright output left unwritten below the threshold, in a captured bright
// image: light where the oracle's is dark. Either it is not the texel's own colour at most of
// those texels (what the target held before: undefined in GL), or it is the texel's own colour
// at every dark texel that has any (a driver that writes the pass's other output there, as
// llvmpipe does: a threshold's change would light only the texels above another luminance).
enum class Unwritten { no, foreign, own_colour };
Unwritten unwritten_signature(const CauseContext& ctx, const StageSpec& target) {
  if (target.kind != StageKind::bright || !ctx.captured(target.name) || !ctx.target_bound)
    return Unwritten::no;
  const ConstImageView cap = ctx.view(target.name), scene = ctx.sanitized;
  if (!cap.data || cap.width != scene.width || cap.height != scene.height) return Unwritten::no;
  Image oracle(scene.width, scene.height);
  extract_bright(scene, oracle.view(), ctx.plan.params.threshold, ctx.threads, false, nullptr,
                 nullptr, luma_rule(ctx.plan.params));
  const Image& bound = *ctx.target_bound;
  std::uint64_t lit = 0, foreign = 0, coloured = 0, own = 0;
  for (int y = 0; y < scene.height; ++y)
    for (int x = 0; x < scene.width; ++x) {
      const float *o = oracle.pixel(x, y), *g = cap.pixel(x, y), *sc = scene.pixel(x, y);
      const float* b = bound.cview().pixel(x, y);
      if (o[0] != 0 || o[1] != 0 || o[2] != 0) continue;
      bool on = false, other = false, colour = false;
      for (int c = 0; c < 3; ++c) {
        on = on || !(std::fabs(g[c]) <= b[c]);
        other = other || !(std::fabs(g[c] - sc[c]) <= b[c] + 1e-3f * std::fabs(sc[c]));
        colour = colour || !(std::fabs(sc[c]) <= b[c]);  // a colour told from black
      }
      lit += on;
      foreign += on && other;
      coloured += colour;
      own += colour && on && !other;
    }
  if (lit == 0) return Unwritten::no;
  if (2 * foreign > lit) return Unwritten::foreign;
  return own == coloured && foreign == 0 ? Unwritten::own_colour : Unwritten::no;
}

// Whether the capture holds NaN or Inf where the isolated oracle's stage is finite.
bool nonfinite_signature(const CauseContext& ctx, const StageSpec& target, ConstImageView oracle) {
  const ConstImageView cap = ctx.view(target.name);
  if (!cap.data || !oracle.data || cap.width != oracle.width || cap.height != oracle.height)
    return false;
  for (int y = 0; y < cap.height; ++y)
    for (int x = 0; x < cap.width; ++x)
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(cap.pixel(x, y)[c]) && std::isfinite(oracle.pixel(x, y)[c])) return true;
  return false;
}

// A fitted number, and beside it the nearest number of two significant digits when that is
// within 1% of it.
std::vector<double> nearby_round(double v) {
  if (!std::isfinite(v) || v == 0) return {v};
  const double scale = std::pow(10.0, std::floor(std::log10(std::fabs(v))) - 1);
  const double r = std::round(v / scale) * scale;
  if (r != v && std::fabs(r / v - 1) < 0.01) return {v, r};
  return {v};
}

std::string weights_text(const std::vector<float>& w) {
  std::string s = "{";
  double sum = 0;
  for (std::size_t i = 0; i < w.size(); ++i) {
    char b[32];
    std::snprintf(b, sizeof b, "%s%.6g", i ? ", " : "", w[i]);
    s += b;
    sum += (i ? 2.0 : 1.0) * w[i];
  }
  char b[48];
  std::snprintf(b, sizeof b, "} (sum over the taps %.6g)", sum);
  return s + b;
}

// What a failing blur pass's residual (capture - isolated oracle) looks like, so that only the
// hypotheses it could fit are fitted and tried. Each figure is the squared correlation of the
// residual with the first-order change a hypothesis makes (1: the change explains all of it to
// first order); `edge` is the fraction of the values out of bound within `reach` texels of an
// edge (a wrap mode changes nothing farther in).
struct Signature {
  bool known = false;
  double gain = 1, shift = 1, spacing = 1, edge = 1;
};

// The fraction of a capture's finite RGB values that a storage format holds exactly (`holds`:
// value, channel): a stage written to that format holds nothing else.
// Stops at the first 1% of all values that are not held (the answer is then below 0.99).
double representable(ConstImageView cap, const std::function<bool(float, int)>& holds) {
  std::uint64_t n = 0, yes = 0;
  const std::uint64_t limit = std::uint64_t(cap.width) * cap.height * 3 / 100 + 1;
  for (int y = 0; y < cap.height; ++y)
    for (int x = 0; x < cap.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = cap.pixel(x, y)[c];
        if (!std::isfinite(v)) continue;
        ++n;
        yes += holds(v, c);
        if (n - yes > limit) return 0.0;
      }
  return n ? double(yes) / double(n) : 1.0;
}

bool r11_holds(float v, int c) {
  if (v < 0) return false;
  if (v == 0) return true;
  std::uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  const int low = 23 - (c == 2 ? 5 : 6);  // mantissa bits the packed float does not have
  const int e = int((bits >> 23) & 0xff) - 127;
  if (e < -14) return true;  // the packed format's denormals: fewer bits still, not tested
  return (bits & ((1u << low) - 1)) == 0 && e <= 15;
}

bool unorm8_holds(float v, int) {
  return v >= 0 && v <= 1 && std::fabs(v * 255.0f - std::round(v * 255.0f)) < 1e-3f;
}

bool f16_holds(float v, int) { return round_to_half(v) == v; }

double squared_correlation(double rd, double rr, double dd) {
  return rr > 0 && dd > 0 ? rd * rd / (rr * dd) : 0.0;
}

Signature blur_signature(const CauseContext& ctx, const StageSpec& target, ConstImageView oracle,
                         int reach) {
  Signature sg;
  const ConstImageView cap = ctx.view(target.name);
  if (!ctx.target_bound || !cap.data || !oracle.data || cap.width != oracle.width ||
      cap.height != oracle.height)
    return sg;
  const ConstImageView in = ctx.view(stage_inputs(ctx.plan, target)[0]);
  const bool have_in = in.data && in.width == cap.width && in.height == cap.height;
  const Kernel& k = kernel_for(ctx.plan.params.kernel);
  const bool hz = target.axis == Axis::horizontal;
  const int w = cap.width, h = cap.height;
  const ConstImageView b = ctx.target_bound->cview();
  // Sums over every `step`-th row (a statistic: about 250,000 pixels are enough), in parallel.
  const int step = std::max(1, static_cast<int>(std::int64_t(w) * h / 262144));
  const int rows = (h + step - 1) / step;
  // Shifts: the gradient (small shifts), and whole texels (1 and 2, either way), exactly.
  constexpr int kLags[4] = {1, -1, 2, -2};
  struct Sums {
    double rr = 0, ro = 0, oo = 0, rs = 0, ss = 0, rk = 0, kk = 0;
    double rl[4] = {0, 0, 0, 0}, ll[4] = {0, 0, 0, 0};
    std::uint64_t out = 0, near = 0;
  };
  std::vector<Sums> part(static_cast<std::size_t>(rows));
  auto at = [](ConstImageView v, int x, int y, int c) {
    return double(v.pixel(std::clamp(x, 0, v.width - 1), std::clamp(y, 0, v.height - 1))[c]);
  };
  parallel_rows(rows, ctx.threads, [&](int r0, int r1) {
    for (int row = r0; row < r1; ++row) {
      const int y = row * step;
      Sums& a = part[std::size_t(row)];
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          const double o = oracle.pixel(x, y)[c], r = cap.pixel(x, y)[c] - o;
          if (!std::isfinite(r)) continue;
          if (std::fabs(r) > b.pixel(x, y)[c]) {
            ++a.out;
            a.near += x < reach || y < reach || x >= w - reach || y >= h - reach;
          }
          // A shift by s on both axes: s (dO/dx + dO/dy).
          const double d = (at(oracle, x + 1, y, c) - at(oracle, x - 1, y, c) +
                            at(oracle, x, y + 1, c) - at(oracle, x, y - 1, c)) / 2;
          // Taps k times as far apart: (k - 1) sum over the taps of w_i i I'(x + i).
          double sp = 0;
          if (have_in)
            for (std::size_t i = 1; i < k.offsets_f64.size(); ++i) {
              const int o_i = static_cast<int>(std::lround(k.offsets_f64[i]));
              for (int sgn : {1, -1}) {
                const int t = sgn * o_i;
                const double g = hz ? at(in, x + t + 1, y, c) - at(in, x + t - 1, y, c)
                                    : at(in, x, y + t + 1, c) - at(in, x, y + t - 1, c);
                sp += k.weights_f64[i] * k.offsets_f64[i] * sgn * g / 2;
              }
            }
          if (!std::isfinite(d) || !std::isfinite(sp) || !std::isfinite(o)) continue;
          for (int l = 0; l < 4; ++l) {
            const double dl = at(oracle, x + kLags[l], y + kLags[l], c) - o;
            if (std::isfinite(dl)) a.rl[l] += r * dl, a.ll[l] += dl * dl;
          }
          a.rr += r * r;
          a.ro += r * o, a.oo += o * o;
          a.rs += r * d, a.ss += d * d;
          a.rk += r * sp, a.kk += sp * sp;
        }
    }
  });
  double rr = 0, ro = 0, oo = 0, rs = 0, ss = 0, rk = 0, kk = 0, rl[4] = {0, 0, 0, 0},
         ll[4] = {0, 0, 0, 0};
  std::uint64_t out = 0, near = 0;
  for (const Sums& a : part) {
    rr += a.rr, ro += a.ro, oo += a.oo, rs += a.rs, ss += a.ss, rk += a.rk, kk += a.kk;
    for (int l = 0; l < 4; ++l) rl[l] += a.rl[l], ll[l] += a.ll[l];
    out += a.out, near += a.near;
  }
  sg.known = true;
  sg.gain = squared_correlation(ro, rr, oo);
  sg.shift = squared_correlation(rs, rr, ss);
  for (int l = 0; l < 4; ++l) sg.shift = std::max(sg.shift, squared_correlation(rl[l], rr, ll[l]));
  sg.spacing = have_in ? squared_correlation(rk, rr, kk) : 1.0;
  sg.edge = out ? double(near) / double(out) : 1.0;
  return sg;
}

std::vector<Hypothesis> hypotheses(const CauseContext& ctx, const StageSpec& target,
                                   const std::string& only, Image& oracle) {
  const BloomParams& p = ctx.plan.params;
  const std::vector<std::string> names = segment(ctx, target);
  std::vector<StageKind> kinds;
  for (const std::string& n : names) kinds.push_back(find_stage(ctx.plan, n)->kind);
  auto has = [&](StageKind k) { return std::find(kinds.begin(), kinds.end(), k) != kinds.end(); };
  const bool sampled = has(StageKind::blur) || has(StageKind::down) || has(StageKind::up) ||
                       has(StageKind::bloom);
  // The target's isolated oracle (blur passes and upsamples: the fitted gain's reference; the
  // group Karis average: where it is NaN), and a blur pass's residual signature.
  const bool group_karis = target.kind == StageKind::down && target.pass == 1 && p.karis &&
                           p.karis_form == KarisForm::group_srgb;
  if (target.kind == StageKind::blur || target.kind == StageKind::up || group_karis) try {
      oracle = Evaluator(ctx, Hypothesis{}, target).target();
    } catch (const NotApplicable&) {
    }
  Signature sg;
  if (target.kind == StageKind::blur && oracle.width() && only.empty()) {
    const Kernel& kern = kernel_for(p.kernel);
    double most = 0;
    for (double o : kern.offsets_f64) most = std::max(most, std::fabs(o));
    const int passes = static_cast<int>(std::count(kinds.begin(), kinds.end(), StageKind::blur));
    sg = blur_signature(ctx, target, oracle.cview(), passes * (static_cast<int>(std::ceil(most)) + 1));
  }
  std::vector<Hypothesis> out;
  // `only`: the cause named at the failing stage before this one (of the same kind), tried
  // alone first; hypotheses of other ids are made into a scratch list and dropped.
  std::vector<Hypothesis> dropped;
  auto want = [&](const char* id) { return only.empty() || only == id; };
  auto add = [&](std::string id, std::string words) {
    Hypothesis h;
    std::vector<Hypothesis>& to = only.empty() || only == id ? out : dropped;
    h.id = std::move(id);
    h.description = std::move(words);
    to.push_back(h);
    return &to.back();
  };
  // The luminance with the other weights: Rec. 601 luma where Rec. 709 is specified (the
  // weights of many shipped blooms), or the other way round.
  auto add_other_luma = [&] {
    const bool declared709 = p.luma == Luma::rec709;
    Hypothesis* h = add("luma-weights", declared709
                                            ? "the luminance with Rec. 601's weights (0.299, 0.587, "
                                              "0.114) where Rec. 709's are specified"
                                            : "the luminance with Rec. 709's weights (0.2126, "
                                              "0.7152, 0.0722) where Rec. 601's are specified");
    h->other_luma = true;
    h->detail = declared709 ? "--luma rec601 declares it" : "--luma rec709 declares it";
  };
  // The threshold's luminance taken of colour in another space than the declared one.
  auto add_other_spaces = [&] {
    static const std::pair<LumaSpace, const char*> spaces[] = {
        {LumaSpace::srgb, "sRGB-encoded colour"},
        {LumaSpace::gamma, "gamma-encoded colour"},
        {LumaSpace::linear, "linear colour"}};
    for (const auto& [space, words] : spaces) {
      if (space == p.luma_space) continue;
      Hypothesis* h = add("threshold-color-space",
                          std::string("the threshold compared with the luminance of ") + words);
      h->space = space;
      h->detail = "--luma-space " + to_string(space) + " declares it";
    }
  };
  // A stage written to a storage format holds only values it can hold: a capture of the target
  // in float that does not (1% of values allowed: an edge case of the format) rules it out.
  const ConstImageView target_cap = ctx.captured(target.name) ? ctx.view(target.name) : ConstImageView{};
  auto stored_as = [&](bool (*holds)(float, int)) {
    return !target_cap.data || representable(target_cap, holds) >= 0.99;
  };
  // Flip and swap: of every capture (a readback's order), or of this stage's output alone.
  for (bool every : {true, false}) {
    Hypothesis* h = add("flipped-vertically",
                        every ? "images flipped vertically (bottom row first, as glReadPixels "
                                "returns them)"
                              : "image flipped vertically (this stage's output)");
    h->flip = true;
    h->transform_inputs = every;
    h = add("rb-swapped", every ? "R and B swapped (BGRA read as RGBA)"
                                : "R and B swapped (this stage's output)");
    h->swap_rb = true;
    h->transform_inputs = every;
  }
  if (has(StageKind::output)) {
    add("gamma-missing", "gamma not applied")->gamma_times = 0;
    add("gamma-twice", "gamma applied twice")->gamma_times = 2;
    add("pow-negative",
        "negative values through pow (gamma without max(x, 0); GLSL's pow is undefined for "
        "x < 0)")->pow_negative = true;
  }
  if (has(StageKind::tonemap) && p.exposure != 1.0f)
    add("exposure-ignored", "exposure ignored (tone map with exposure 1)")->no_exposure = true;
  // A blur pass's residual rules out what it does not look like (Signature): a shift where it
  // is not along the image's gradient, a wrap mode where the values out of bound are not near
  // an edge, GL_NEAREST where every tap sits on a texel centre (nothing changes).
  bool centred = true;
  for (double o : kernel_for(p.kernel).offsets_f64) centred = centred && o == std::floor(o);
  if (sampled) {
    if (!sg.known || sg.shift >= 0.1) {
      add("half-texel-shift", "half-texel shift (lookups at texel corners, +0.5 texel)")
          ->sampling.shift = 0.5f;
      add("half-texel-shift", "half-texel shift (lookups at texel corners, -0.5 texel)")
          ->sampling.shift = -0.5f;
    }
    if (!sg.known || sg.edge >= 0.5) {
      add("wrap-repeat", "GL_REPEAT instead of GL_CLAMP_TO_EDGE")->sampling.wrap = Wrap::repeat;
      add("wrap-mirrored-repeat", "GL_MIRRORED_REPEAT instead of GL_CLAMP_TO_EDGE")
          ->sampling.wrap = Wrap::mirrored_repeat;
      add("padded-target",
          "taps past the image's edge read black (a render target larger than the image, its "
          "padding cleared; or GL_CLAMP_TO_BORDER)")
          ->sampling.wrap = Wrap::border;
    }
    if (!(sg.known && centred && p.method == Method::gaussian))
      add("nearest-filter", "GL_NEAREST instead of GL_LINEAR")->sampling.nearest = true;
  }
  if (has(StageKind::blur))
    add("blur-clamped", "blur passes clamped to [0, 1] (an 8-bit target, or clamp() in the shader)")
        ->clamp_blur = true;
  if (target.kind == StageKind::blur && target.pass >= 3)
    add("pass-not-drawn", "blur pass not drawn (its ping-pong target still holds the pass before last)")
        ->stale = true;
  if (target.kind == StageKind::blur && target.axis == Axis::vertical)
    add("offsets-along-x", "vertical pass offsets along x (the bug in seed 001's blur shader)")
        ->along_x = true;
  // A blur pass in the segment: the bloom is not captured (or the target is a pass).
  if (p.method == Method::gaussian && p.passes > 0 && has(StageKind::blur)) {
    // Of the bloom as a whole (a stage after the passes), the pass count is a setting; a pass
    // that leaves its input as it was is a bug of that pass, not of the count.
    const bool count = target.kind != StageKind::blur;
    Hypothesis* h = add("pass-skipped", "one blur pass too few");
    h->pass_delta = -1;
    if (count) h->detail = "--passes " + std::to_string(p.passes - 1) + " declares it";
    h = add("pass-added", "one blur pass too many");
    h->pass_delta = 1;
    if (count) h->detail = "--passes " + std::to_string(p.passes + 1) + " declares it";
    if (p.first_axis == FirstAxis::horizontal) {
      h = add("vertical-first", "the blur starts with a vertical pass (each pass's axis is the other one)");
      h->detail = "--first-axis vertical declares it";
    } else {
      h = add("horizontal-first", "the blur starts with a horizontal pass (each pass's axis is the other one)");
      h->detail = "--first-axis horizontal declares it";
    }
    h->axes_swapped = true;
  }
  if (has(StageKind::bright)) {
    add("threshold-ge", "`>=` instead of `>` at the threshold")->ge = true;
    add("bright-clamped", "bright pass clamped to [0, 1] (an 8-bit target or saturate())")
        ->clamp_bright = true;
    add_other_spaces();
    add_other_luma();
    if (const Unwritten u = unwritten_signature(ctx, target); u != Unwritten::no) {
      // Foreign values are taken from the capture, a value per dark texel: counted as many
      // parameters, so that any cause that explains as much is named first. The texels' own
      // colour is a fixed change (the bright image is the scene).
      Hypothesis* h = add("bright-unwritten",
                          u == Unwritten::foreign
                              ? "the bright output not written below the threshold: those texels "
                                "hold what the target held (undefined in GL)"
                              : "the bright output not written below the threshold: the driver "
                                "wrote the pass's other output, the scene, there (undefined in GL)");
      h->unwritten = true;
      h->params = u == Unwritten::foreign ? 50 : 0;
    }
  } else if (std::find(names.begin(), names.end(), "down.1") != names.end()) {
    add("threshold-ge", "threshold tie on the other side (`>` where the specification keeps ties)")
        ->ge = true;
    // The first level's luminance: its lookups' threshold, three.js's high pass, or seed 002's
    // per-tap Karis weight.
    if (p.prefilter == Prefilter::per_lookup || p.prefilter == Prefilter::smoothstep ||
        (p.karis && p.karis_form == KarisForm::per_tap))
      add_other_luma();
    if (p.prefilter == Prefilter::per_lookup) add_other_spaces();
  }
  if (want("f16-storage") && p.storage == Storage::f32 && stored_as(f16_holds)) {
    Hypothesis* h = add("f16-storage", "f16 storage where f32 was declared");
    h->f16 = true;
    h->detail = "--storage f16 declares half-float targets";
  }
  // Not where every stage is specified so (it is no change there).
  if (want("rgba8-storage") && p.storage != Storage::rgba8 && stored_as(unorm8_holds))
    add("rgba8-storage", "stages stored in 8-bit targets (RGBA8: clamped to [0, 1], 255ths)")->rgba8 =
        true;
  // The scene's texture in the format matters only to a bright pass recomputed here.
  const bool bright_here = has(StageKind::bright);
  // Not where the chain's levels are specified so (it is no change there).
  const bool r11 = want("r11g11b10-storage") && p.level_storage() != Storage::r11g11b10 &&
                   stored_as(r11_holds);
  for (bool scene : {false, true})
    for (bool toward_zero : {false, true}) {
      if ((scene && !bright_here) || !r11) continue;
      Hypothesis* h = add("r11g11b10-storage",
                          scene ? "stages and the scene stored as R11F_G11F_B10F (6-bit mantissas, "
                                  "5 for blue, no sign)"
                                : "stages stored as R11F_G11F_B10F (6-bit mantissas, 5 for blue, "
                                  "no sign)");
      h->r11g11b10 = true;
      h->packed_toward_zero = toward_zero;
      h->scene_stored = scene;
    }
  // Both models of the composite, fitted once (scene + k bloom, and mix).
  const CompositeFit composite_fit = has(StageKind::composite) ? fit_composite(ctx, target) : CompositeFit{};
  if (has(StageKind::composite)) {
    add("bloom-zeroed", "the bloom term zeroed (an unset strength or bloom flag)")->strength_scale = 0;
    Hypothesis* h = add("one-input-flipped", "the composite reads the bloom flipped vertically");
    h->flip_input = 1;
    h = add("one-input-flipped", "the composite reads the scene flipped vertically");
    h->flip_input = 0;
    // The fitted amount, and the nearest number of two significant digits (a constant a
    // person wrote) when it is within 1%: the better of the two is kept.
    const bool mix = p.composite_mode == CompositeMode::mix;
    for (const double a : nearby_round(composite_fit.mix))
      if (std::isfinite(a) && a > 0 && (mix || a < 1)) {
        h = mix ? add("composite-mode", "composite by scene + a bloom where mix(scene, bloom, s) was meant")
                : add("composite-mode", "composite by mix(scene, bloom, a) where scene + bloom was meant");
        (mix ? h->add_amount : h->mix_amount) = static_cast<float>(a);
        h->params = 1;
        char b[96];
        std::snprintf(b, sizeof b, mix ? "the composite fits scene + a bloom with a = %.4g"
                                       : "the composite fits mix with a = %.4g", a);
        h->detail = b;
      }
  }
  // Fitted last: they can mimic a simpler cause (a copy of the input is weights {1, 0, ...}),
  // and a tie goes to the hypothesis listed first.
  if (const double k = composite_fit.add;
      std::isfinite(k) && k > 0 && std::fabs(k - 1) >= 1e-4) {
    // Scaled by the exposure itself: the bloom weighted by it before the tone map applies it.
    const bool exposure = p.exposure != 1.0f && std::fabs(k / p.exposure - 1) < 0.01;
    Hypothesis* h = exposure ? add("exposure-twice",
                                   "exposure applied twice to the bloom (weighted by it before "
                                   "the tone map applies it)")
                             : add("bloom-scaled",
                                   "bloom scaled (blur weights not summing to 1, or another strength)");
    // The exposure itself, not the fit near it: a fixed change.
    h->strength_scale = exposure ? p.exposure : static_cast<float>(k);
    h->params = exposure ? 0 : 1;
    char b[96];
    std::snprintf(b, sizeof b, exposure ? "the bloom fits best scaled by %.4g, the exposure"
                                        : "the bloom fits best scaled by %.6g", k);
    h->detail = b;
    }
  if (const auto t = fit_soft_threshold(ctx, target))
    for (const double v : nearby_round(*t)) {
      Hypothesis* h = add("threshold-other", "another threshold");
      h->threshold = static_cast<float>(v);
      h->params = 1;
      char b[160];
      std::snprintf(b, sizeof b,
                    "the soft threshold fits %.4g (specified %.6g; --threshold declares it)", v,
                    double(p.threshold));
      h->detail = b;
    }
  if (const auto t = fit_threshold(ctx, target)) {
    Hypothesis* h = add("threshold-other", "another threshold");
    h->threshold = t->first;
    h->params = 1;
    char b[160];
    std::snprintf(b, sizeof b,
                  "the bright mask fits a threshold from %.6g up to %.6g (specified %.6g; "
                  "--threshold declares it)",
                  double(t->first), double(t->second), double(p.threshold));
    h->detail = b;
  }
  if (const auto g = fit_gamma(ctx, target)) {
    Hypothesis* h = add("gamma-other", "another gamma");
    h->gamma = *g;
    h->params = 1;
    char b[96];
    std::snprintf(b, sizeof b, "the output fits gamma %.4g (specified %.4g; --gamma declares it)", *g,
                  double(p.gamma));
    h->detail = b;
  }
  if (target.kind == StageKind::blur)
    if (const auto f = (want("tap-spacing") || want("anisotropic-blur")) && (!sg.known || sg.spacing >= 0.2)
                           ? fit_spacing(ctx, target, ctx.threads)
                           : std::nullopt) {
      const bool hz = target.axis == Axis::horizontal;
      const ConstImageView src = ctx.view(stage_inputs(ctx.plan, target)[0]);
      const int n = hz ? src.width : src.height, other = hz ? src.height : src.width;
      const bool other_axis = *f == static_cast<float>(double(n) / other) && n != other;
      Hypothesis* h = add(other_axis ? "anisotropic-blur" : "tap-spacing",
                          other_axis ? "the pass's taps spaced by the other axis's texel size"
                                     : "taps spaced another distance apart");
      h->spacing = *f;
      h->params = 1;
      char b[200];
      std::snprintf(b, sizeof b, "taps %.3gx as far apart on %s%s", double(*f), hz ? "x" : "y",
                    other_axis ? (hz ? " (1 / height where 1 / width was meant)"
                                     : " (1 / width where 1 / height was meant)")
                               : *f == 2.0f || *f == 0.5f ? " (the texel size of another level?)" : "");
      h->detail = b;
    }
  if (const auto f = want("texel-shift") && (!sg.known || sg.shift >= 0.1)
                         ? fit_shift(ctx, target, ctx.threads)
                         : std::nullopt) {
    Hypothesis* h = add("texel-shift", "lookups shifted by a constant offset");
    h->sampling.shift = *f;
    h->params = 1;
    char b[160];
    std::snprintf(b, sizeof b,
                  "lookups %.3g texels off on both axes (an offset in another resolution's texels?)",
                  double(*f));
    h->detail = b;
  }
  if (const ConstImageView cap = ctx.view(target.name); cap.data) {
    bool any = false;
    for (int y = 0; y < cap.height && !any; ++y)
      for (int i = 0; i < cap.width * kChannels && !any; ++i)
        any = i % kChannels != 3 && !std::isfinite(cap.row(y)[i]);
    Image own;  // the isolated oracle, made here unless made above
    if (any && !oracle.width()) try {
        own = Evaluator(ctx, Hypothesis{}, target).target();
      } catch (const NotApplicable&) {
      }
    const Image& o = oracle.width() ? oracle : own;
    if (any && o.width() && nonfinite_signature(ctx, target, o.cview())) {
      Hypothesis* h = add("nonfinite-spread",
                          "NaN/Inf made at this stage (a division by zero, a log or pow of a "
                          "negative, an overflow), carried by every stage after it");
      h->nonfinite = true;
      h->params = 20;
    }
  }
  if (group_karis && oracle.width()) {
    // pow(group, 1 / 2.2) of a group with a negative channel (an out-of-gamut scene): NaN in
    // the oracle, undefined in GLSL; a device that gives a number there (max(NaN, 0.0001) is
    // 0.0001 on llvmpipe) shows the same bug as the oracle's NaN does.
    const ConstImageView cap = ctx.view(target.name);
    bool seen = false;
    for (std::size_t i = 0; cap.data && i < oracle.values().size() && !seen; ++i)
      seen = i % kChannels != 3 && std::isnan(oracle.data()[i]);
    if (seen) {
      Hypothesis* hy = add("pow-negative",
                           "pow of a negative value: the Karis average encodes a group with a "
                           "negative channel by pow(x, 1 / 2.2), undefined in GLSL (an "
                           "out-of-gamut scene; clamp it, or take max(x, 0) before pow)");
      hy->pow_negative_karis = true;
    }
  }
  if (target.kind == StageKind::down && p.method == Method::mip) {
    // The step taken from another size than the one specified, where the two differ on this
    // level: the texture's, the host's halved float size (an odd level above), or the target's
    // (0.5 / size: a source not exactly twice the target).
    const int k = target.pass, w = ctx.sanitized.width, h = ctx.sanitized.height;
    const DownsampleOptions spec_opt = downsample_options(p, k, w, h, ctx.profile.subtexel_bits);
    const int sw = k == 1 ? w : ctx.plan.levels[std::size_t(k - 2)].width;
    const int sh = k == 1 ? h : ctx.plan.levels[std::size_t(k - 2)].height;
    auto step_of = [&](const DownsampleOptions& o) {
      return std::pair<float, float>(o.step_width > 0 ? o.step_width : float(sw),
                                     o.step_height > 0 ? o.step_height : float(sh));
    };
    const LevelSize& l = ctx.plan.levels[std::size_t(k - 1)];
    for (const TexelStep other : {TexelStep::texture, TexelStep::halved_float, TexelStep::target}) {
      if (other == p.texel_step) continue;
      BloomParams q = p;
      q.texel_step = other;
      const auto s = step_of(downsample_options(q, k, w, h, ctx.profile.subtexel_bits));
      if (s == step_of(spec_opt)) continue;
      static const char* const kWhat[] = {"the texture's integer size", "the host's halved float size",
                                          "the target's size (0.5 / size)"};
      Hypothesis* hy = add("level-size-rounding",
                           std::string("the downsample's step from ") + kWhat[int(other)] +
                               " where " + kWhat[int(p.texel_step)] + " is specified");
      hy->texel_step = other;
      const auto specified = step_of(spec_opt);
      char b[240];
      std::snprintf(b, sizeof b,
                    "level %d (%dx%d) reads a %dx%d level with the step 1 / %gx%g where 1 / %gx%g "
                    "is specified",
                    k, l.width, l.height, sw, sh, double(s.first), double(s.second),
                    double(specified.first), double(specified.second));
      hy->detail = b;
    }
  }
  const bool summed = target.kind == StageKind::up && p.level_combine == LevelCombine::sum;
  if ((target.kind == StageKind::down || target.kind == StageKind::up) && target.pass >= 1 &&
      !summed) {
    // A level read from the wrong place in the chain (an index off by one): the level one
    // further along it (the source's own source), or, for an upsample, its own level's
    // downsample where the next level's result is specified.
    const std::vector<std::string> in = stage_inputs(ctx.plan, target);
    std::vector<std::string> others;
    if (const StageSpec* src = find_stage(ctx.plan, in[0]))
      if (src->kind == target.kind && !stage_inputs(ctx.plan, *src).empty())
        others.push_back(stage_inputs(ctx.plan, *src)[0]);
    if (target.kind == StageKind::up && in.size() > 1) others.push_back(in[1]);
    for (const std::string& o : others) {
      if (!ctx.view(o).data) continue;
      Hypothesis* h = add("mip-level-offset", "a mip level read from the wrong level (an index off by one)");
      h->source = o;
      h->detail = target.name + " reads " + o + " where " + in[0] + " is specified";
    }
  }
  if (target.kind == StageKind::up && oracle.width() && !summed) {
    // up.k = down.k + tent: the tent's part scaled (weights summing to g, or added g times).
    // The tent computed afresh, unrounded: the stored level less down.k would hold the
    // level's rounding, which biases a least-squares slope toward 0.
    const std::vector<std::string> in = stage_inputs(ctx.plan, target);
    const ConstImageView small = ctx.view(in[0]), cur = ctx.view(in[1]);
    std::vector<std::optional<float>> candidates;
    if (small.data && cur.data) {
      Image tent(cur.width, cur.height);
      upsample_tent(small, ConstImageView{}, tent.view(), ctx.profile.subtexel_bits, ctx.threads,
                    nullptr, p.upsample_radius, LevelBlend{}, p.texel_step == TexelStep::target,
                    p.upsample);
      // A blended level: up.k = C tent + keep down.k; the fit is of the tent's part.
      const LevelBlend blend = level_blend(p, target.pass, int(ctx.plan.levels.size()));
      // Another constant W: up.k - down.k = W (tent - down.k) under mix, W tent under add; W
      // by least squares over the finite values, and its two-digit neighbour.
      if (!blend.plain()) {
        const ConstImageView user = ctx.view(target.name);
        const bool mix = blend.combine != LevelCombine::add;  // mix and lerp: W (tent - down.k)
        double num = 0, den = 0;
        for (int y = 0; y < cur.height; ++y)
          for (int x = 0; x < cur.width; ++x)
            for (int c = 0; c < 3; ++c) {
              const double d = cur.pixel(x, y)[c], t = tent.pixel(x, y)[c];
              const double u = double(user.pixel(x, y)[c]) - d, r = mix ? t - d : t;
              if (!std::isfinite(u) || !std::isfinite(r)) continue;
              num += u * r;
              den += r * r;
            }
        const double w = den > 0 ? num / den : NAN;
        if (std::isfinite(w) && w > 0 && std::fabs(w - blend.weight) > 1e-4 * blend.weight)
          for (const double v : nearby_round(w)) {
            Hypothesis* h = add("level-blend-constant",
                                "a level blended with another constant than the specified one");
            h->level_weight = static_cast<float>(v);
            h->params = 1;
            char b[200];
            std::snprintf(b, sizeof b, "%s blends the tent with constant %.4g where %.4g is specified",
                          target.name.c_str(), v, double(blend.weight));
            h->detail = b;
          }
      }
      Image kept;
      ConstImageView base = cur;
      if (!blend.plain()) {
        const float keep = blend.kept();
        kept = Image(cur.width, cur.height);
        for (int y = 0; y < cur.height; ++y)
          for (int x = 0; x < cur.width; ++x)
            for (int c = 0; c < 3; ++c) {
              kept.pixel(x, y)[c] = cur.pixel(x, y)[c] * keep;
              tent.pixel(x, y)[c] *= blend.weight;
            }
        base = kept.cview();
      }
      candidates.push_back(fit_gain(ctx.view(target.name), tent.cview(), base));
      // A level stored by truncation: the slope of the values lifted by half a quantum too.
      const Storage st = stage_storage(p, target);
      if (st != Storage::f32 && ctx.profile.half_toward_zero)
        candidates.push_back(fit_gain(
            ctx.view(target.name), tent.cview(), base,
            [&](double v, int c) { return 0.5 * storage_term(v, st, ctx.profile, c); }));
    }
    std::vector<double> tried;
    for (const std::optional<float>& g : candidates)
      for (const double v : g ? nearby_round(*g) : std::vector<double>{})
        if (std::find(tried.begin(), tried.end(), v) == tried.end()) {
          tried.push_back(v);
          Hypothesis* h = add("upsample-gain", "an upsample whose tent does not sum to 1");
          h->tent_gain = static_cast<float>(v);
          h->params = 1;
          char b[160];
          std::snprintf(b, sizeof b, "the tent added to the level fits %.4g times the specified one",
                        v);
          h->detail = b;
        }
  }
  if (target.kind == StageKind::blur || target.kind == StageKind::up) {
    if (const auto g = oracle.width() ? fit_gain(ctx.view(target.name), oracle.cview()) : std::nullopt) {
      const bool blur = target.kind == StageKind::blur;
      Hypothesis* h = add(blur ? "weight-sum" : "upsample-gain",
                          blur ? "blur weights not summing to 1" : "an upsample whose gain is not 1");
      h->target_gain = *g;
      h->params = 1;
      char b[160];
      std::snprintf(b, sizeof b, blur ? "the weights sum to %.4g: each pass scales the bloom by it"
                                      : "the level fits %.4g times the oracle's", double(*g));
      h->detail = b;
    }
  }
  if (target.kind == StageKind::blur) {
    const Kernel& k = kernel_for(p.kernel);
    const ConstImageView src = ctx.view(stage_inputs(ctx.plan, target)[0]);
    // A residual that is the oracle's own image scaled (a weight sum) is weight-sum's with one
    // parameter: five fitted weights could not be named before it.
    const bool fit = want("wrong-weights") && src.data && (!sg.known || sg.gain < 0.99);
    if (auto w = !fit ? std::nullopt : fit_weights(src, ctx.view(target.name), target.axis, k, ctx.profile.subtexel_bits)) {
      Hypothesis* h = add("wrong-weights", "wrong kernel weights");
      h->weights = *w;
      h->params = static_cast<int>(w->size());
      h->detail = "fitted weights " + weights_text(*w) + "; specified " + weights_text(k.weights_f32);
    }
  }
  return out;
}

}  // namespace

std::string describe_residual(const CauseContext& ctx, const StageSpec& target) {
  const ConstImageView cap = ctx.view(target.name);
  Image oracle;
  try {
    oracle = Evaluator(ctx, Hypothesis{}, target).target();
  } catch (const NotApplicable&) {
    return "";
  }
  if (!cap.data || !ctx.target_bound || cap.width != oracle.width() || cap.height != oracle.height())
    return "";
  const ConstImageView o = oracle.cview(), b = ctx.target_bound->cview();
  const int w = cap.width, h = cap.height, edge = 4;
  double sum_c = 0, sum_o = 0, most = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        if (std::isfinite(o.pixel(x, y)[c])) most = std::max(most, double(std::fabs(o.pixel(x, y)[c])));
  std::uint64_t out = 0, near = 0, lit = 0, dark = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const double g = cap.pixel(x, y)[c], v = o.pixel(x, y)[c];
        if (!std::isfinite(g) || !std::isfinite(v)) continue;
        sum_c += g, sum_o += v;
        if (std::fabs(g - v) <= b.pixel(x, y)[c]) continue;
        ++out;
        near += x < edge || y < edge || x >= w - edge || y >= h - edge;
        lit += std::fabs(v) >= 0.1 * most;
        dark += std::fabs(v) < 0.01 * most;
      }
  char buf[320];
  std::string s;
  if (sum_o != 0) {
    std::snprintf(buf, sizeof buf, "total %.4gx the oracle's", sum_c / sum_o);
    s = buf;
  }
  if (out > 0) {
    auto pc = [out](std::uint64_t n) { return 100.0 * double(n) / double(out); };
    std::snprintf(buf, sizeof buf,
                  "%s%llu values out of bound: %.0f%% within %d texels of an edge, %.0f%% on lit "
                  "texels (a tenth of the brightest or more), %.0f%% in the dark (under a "
                  "hundredth)",
                  s.empty() ? "" : "; ", static_cast<unsigned long long>(out), pc(near), edge,
                  pc(lit), pc(dark));
    s += buf;
  }
  if (target.kind == StageKind::blur) {
    const Kernel& k = kernel_for(ctx.plan.params.kernel);
    double reach = 0;
    for (double off : k.offsets_f64) reach = std::max(reach, std::fabs(off));
    const Signature sg = blur_signature(ctx, target, o, static_cast<int>(std::ceil(reach)) + 1);
    if (sg.known) {
      const std::pair<double, const char*> like[] = {
          {sg.gain, "a gain"}, {sg.shift, "a shift"}, {sg.spacing, "a change of the kernel's width"}};
      const auto best = *std::max_element(std::begin(like), std::end(like));
      std::snprintf(buf, sizeof buf, "; most like %s (squared correlation %.2f)", best.second, best.first);
      s += buf;
    }
  }
  return s;
}

namespace {

// Whether a hypothesis's image lies within the stage's bound of the isolated oracle's at every
// value: a change that is no change on this scene (every capture flipped, through a symmetric
// kernel) moves values by rounding only, which may carry a value that is out of bound by a
// little across it. Such a hypothesis explains nothing. `oracle` is made here when empty.
bool indistinguishable(const CauseContext& ctx, const StageSpec& target, Image& oracle,
                       const Image& img) {
  if (!oracle.width()) try {
      oracle = Evaluator(ctx, Hypothesis{}, target).target();
    } catch (const NotApplicable&) {
      return false;
    }
  if (oracle.width() != img.width() || oracle.height() != img.height()) return false;
  const Image& bound = *ctx.target_bound;
  if (bound.width() != img.width() || bound.height() != img.height()) return false;
  for (std::size_t i = 0; i < img.values().size(); ++i) {
    if (i % kChannels == 3) continue;
    const float a = oracle.data()[i], b = img.data()[i];
    if (std::isnan(a) != std::isnan(b)) return false;
    if (std::isfinite(a) && std::isfinite(b) && std::fabs(double(a) - b) > bound.data()[i])
      return false;
    if (std::isinf(a) != std::isinf(b) || (std::isinf(a) && a != b)) return false;
  }
  return true;
}

// A hypothesis sampling other positions than the oracle's carries its own coordinates' float
// error where the oracle's bound (made for the oracle's neighbourhood) may be all but 0: a
// lookup on a texel centre whose fraction comes out a few ULPs off it blends that much of a
// neighbour (measured: 5.4e-8 of a light across GL_REPEAT's wrap on a 192-texel row). Allowed:
// 64 f32 ULPs of the largest value, far below any error a cause is named for.
double sampling_allowance(const Hypothesis& h, const Image& img) {
  if (!(h.sampled() || h.spacing != 1.0f || h.along_x || h.kernel || !h.weights.empty())) return 0;
  double most = 0;
  for (std::size_t i = 0; i < img.values().size(); ++i)
    if (i % kChannels != 3 && std::isfinite(img.data()[i]))
      most = std::max(most, double(std::fabs(img.data()[i])));
  return 64 * 0x1p-24 * most;  // the hypothesis is computed in f32
}

// The one fitted number of a hypothesis with one (Hypothesis::params 1), or null.
float* fitted_value(Hypothesis& h) {
  if (h.params != 1) return nullptr;
  if (h.target_gain != 1.0f) return &h.target_gain;
  if (h.tent_gain != 1.0f) return &h.tent_gain;
  if (!std::isnan(h.level_weight)) return &h.level_weight;
  if (h.spacing != 1.0f) return &h.spacing;
  if (h.sampling.shift != 0.0f) return &h.sampling.shift;
  if (!std::isnan(h.threshold)) return &h.threshold;
  if (h.gamma > 0.0f) return &h.gamma;
  if (!std::isnan(h.mix_amount)) return &h.mix_amount;
  if (!std::isnan(h.add_amount)) return &h.add_amount;
  if (h.strength_scale != 1.0f) return &h.strength_scale;
  return nullptr;
}

// The range of a likely cause's fitted number that still explains the failure: outward from
// the value by 0.1%, 1%, 10% and 100% of it until a step does not, then four halvings of that
// step. `explains(h)` scores one variant.
void fit_interval(Hypothesis h, CauseFit& fit, const std::function<bool(const Hypothesis&)>& explains) {
  float* x = fitted_value(h);
  if (!x) return;
  const double v = *x, scale = std::max(std::fabs(v), 1e-3);
  auto end = [&](double sign) {
    double good = 0, bad = NAN;
    for (double step : {1e-3, 1e-2, 1e-1, 1.0}) {
      *x = static_cast<float>(v + sign * step * scale);
      if (!explains(h)) {
        bad = step;
        break;
      }
      good = step;
    }
    if (std::isnan(bad)) return v + sign * good * scale;  // explains a doubling and more
    for (int i = 0; i < 4; ++i) {
      const double mid = 0.5 * (good + bad);
      *x = static_cast<float>(v + sign * mid * scale);
      (explains(h) ? good : bad) = mid;
    }
    return v + sign * good * scale;
  };
  fit.value = v;
  fit.low = end(-1);
  fit.high = end(+1);
}

// Every hypothesis of `only` (all when empty), scored, best first.
std::vector<CauseFit> try_causes(const CauseContext& ctx, const StageSpec& target,
                                 double oracle_within,
                                 const std::function<double(Image&, double)>& within,
                                 const std::string& only) {
  std::vector<CauseFit> fits;
  std::vector<Hypothesis> made;  // each fit's hypothesis
  Image oracle;
  for (const Hypothesis& h : hypotheses(ctx, target, only, oracle)) {
    Image img;
    try {
      img = Evaluator(ctx, h, target, &oracle).target();
    } catch (const NotApplicable&) {
      continue;
    }
    const double f = within(img, sampling_allowance(h, img));
    if (f > oracle_within && ctx.target_bound && indistinguishable(ctx, target, oracle, img))
      continue;
    // It must bring within bound a tenth of what the oracle as specified leaves out: a change
    // that moves a few values (f16 rounding near a large error) explains nothing.
    if (!(f > oracle_within) || f - oracle_within < 0.1 * (1 - oracle_within)) continue;
    // Two hypotheses of one id (the half-texel shift's two signs): keep the better. The colour
    // spaces of the threshold are different causes: two that explain as much are both said.
    auto same = std::find_if(fits.begin(), fits.end(), [&](const CauseFit& c) {
      return c.id == h.id && (!h.space || c.description == h.description);
    });
    if (same != fits.end()) {
      if (f > same->within) {
        *same = {h.id, h.description, h.detail, f, oracle_within, h.params};
        made[std::size_t(same - fits.begin())] = h;
      }
      continue;
    }
    fits.push_back({h.id, h.description, h.detail, f, oracle_within, h.params});
    made.push_back(h);
  }
  // Ranked by what they explain less 0.2% of the values per fitted parameter: five fitted
  // weights absorb any symmetric change of kernel, so a one-parameter cause (a tap spacing, a
  // gain) that explains about as much is named before them.
  auto score = [](const CauseFit& c) { return c.within - 0.002 * c.params; };
  std::vector<std::size_t> order(fits.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return score(fits[a]) > score(fits[b]); });
  std::vector<CauseFit> sorted;
  for (std::size_t i : order) sorted.push_back(fits[i]);
  if (ctx.interval && !sorted.empty() && sorted.front().likely()) {
    // The variant scored as above (its own coordinates' allowance kept from the fit).
    const Hypothesis& best = made[order.front()];
    fit_interval(best, sorted.front(), [&](const Hypothesis& h) {
      try {
        Image img = Evaluator(ctx, h, target, &oracle).target();
        CauseFit c{h.id, "", "", within(img, sampling_allowance(h, img)), oracle_within, h.params};
        return c.likely();
      } catch (const NotApplicable&) {
        return false;
      }
    });
  }
  fits = std::move(sorted);
  // A flexible fit behind a simpler cause describes the capture rather than explaining it.
  for (std::size_t i = 1; i < fits.size(); ++i)
    if (fits[i].id == "wrong-weights")
      fits[i].description = "the pass acts as a kernel of other weights (a description)";
  // Causes the captures cannot tell from the first: a fixed change and a fitted one that both
  // explain a sparse scene's few decisions (a threshold taken in sRGB and another threshold,
  // when only a few lights are near either) are said together.
  if (!fits.empty() && fits.front().likely())
    for (std::size_t i = 1; i < fits.size(); ++i) {
      const CauseFit& c = fits.front();
      CauseFit& o = fits[i];
      o.as_likely = o.likely() && (o.id != c.id || o.description != c.description) &&
                    o.within >= c.within - 0.0005 &&
                    o.params <= c.params + 1 && o.id != "wrong-weights";
    }
  return fits;
}

}  // namespace

std::vector<CauseFit> test_causes(const CauseContext& ctx, const StageSpec& target,
                                  double oracle_within,
                                  const std::function<double(Image&, double)>& within) {
  // The same bug at every pass: the cause named at the failing stage before this one, tried
  // alone, is named again when it explains this one too (the full search there found no
  // other cause as good); otherwise every hypothesis is tried.
  if (!ctx.prior.empty()) {
    std::vector<CauseFit> again = try_causes(ctx, target, oracle_within, within, ctx.prior);
    if (!again.empty() && again.front().likely()) {
      CauseFit& c = again.front();
      c.detail += (c.detail.empty() ? "" : "; ") + std::string("as at ") + ctx.prior_stage +
                  " (the other causes not tried again)";
      return again;
    }
  }
  return try_causes(ctx, target, oracle_within, within, "");
}

}  // namespace bloomref::parity::detail
