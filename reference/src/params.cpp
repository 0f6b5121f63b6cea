#include "bloomref/params.h"

#include <cmath>
#include <sstream>

#include "bloomref/error.h"

namespace bloomref {
namespace {

template <class E, std::size_t N>
E parse_enum(const char* what, const std::string& s, const std::pair<const char*, E> (&table)[N]) {
  std::string known;
  for (const auto& [name, value] : table) {
    if (s == name) return value;
    known += (known.empty() ? "" : ", ") + std::string(name);
  }
  throw ParamError(std::string(what) + " '" + s + "' is not one of: " + known);
}

template <class E, std::size_t N>
std::string name_of(E v, const std::pair<const char*, E> (&table)[N]) {
  for (const auto& [name, value] : table)
    if (v == value) return name;
  return "?";
}

constexpr std::pair<const char*, Method> kMethods[] = {{"gaussian", Method::gaussian},
                                                       {"mip", Method::mip}};
constexpr std::pair<const char*, KernelName> kKernels[] = {{"discrete9", KernelName::discrete9},
                                                           {"linear5", KernelName::linear5}};
constexpr std::pair<const char*, Precision> kPrecisions[] = {{"f32", Precision::f32},
                                                             {"f64", Precision::f64}};
constexpr std::pair<const char*, NonFinite> kPolicies[] = {{"zero", NonFinite::zero},
                                                           {"clamp", NonFinite::clamp},
                                                           {"propagate", NonFinite::propagate},
                                                           {"error", NonFinite::error}};
constexpr std::pair<const char*, CompositeOrder> kOrders[] = {
    {"before-tonemap", CompositeOrder::before_tonemap},
    {"after-tonemap", CompositeOrder::after_tonemap}};
constexpr std::pair<const char*, CompositeMode> kModes[] = {{"add", CompositeMode::add},
                                                            {"mix", CompositeMode::mix}};
constexpr std::pair<const char*, FirstAxis> kAxes[] = {{"horizontal", FirstAxis::horizontal},
                                                       {"vertical", FirstAxis::vertical}};
constexpr std::pair<const char*, Luma> kLumas[] = {{"rec709", Luma::rec709}, {"rec601", Luma::rec601}};
constexpr std::pair<const char*, LumaSpace> kLumaSpaces[] = {
    {"linear", LumaSpace::linear}, {"srgb", LumaSpace::srgb}, {"gamma", LumaSpace::gamma}};
constexpr std::pair<const char*, Prefilter> kPrefilters[] = {
    {"per-lookup", Prefilter::per_lookup}, {"bright", Prefilter::bright}, {"none", Prefilter::none},
    {"soft-knee", Prefilter::soft_knee}, {"smoothstep", Prefilter::smoothstep}};
constexpr std::pair<const char*, KarisForm> kKarisForms[] = {
    {"per-tap", KarisForm::per_tap},
    {"group-srgb", KarisForm::group_srgb},
    {"group-linear", KarisForm::group_linear}};
constexpr std::pair<const char*, TexelStep> kTexelSteps[] = {
    {"texture", TexelStep::texture}, {"halved-float", TexelStep::halved_float},
    {"target", TexelStep::target}};
constexpr std::pair<const char*, BloomUpscale> kUpscales[] = {
    {"tent", BloomUpscale::tent}, {"bilinear", BloomUpscale::bilinear}};
constexpr std::pair<const char*, LevelCombine> kCombines[] = {
    {"add", LevelCombine::add}, {"mix", LevelCombine::mix}, {"lerp", LevelCombine::lerp},
    {"sum", LevelCombine::sum}};
constexpr std::pair<const char*, LevelWeights> kWeights[] = {
    {"one", LevelWeights::one}, {"bevy", LevelWeights::bevy}, {"constant", LevelWeights::constant}};
constexpr std::pair<const char*, KneeForm> kKneeForms[] = {{"bevy", KneeForm::bevy},
                                                            {"unity", KneeForm::unity}};
constexpr std::pair<const char*, FirstDownsample> kFirstDownsamples[] = {
    {"13-tap", FirstDownsample::taps13}, {"bilinear", FirstDownsample::bilinear},
    {"box4", FirstDownsample::box4}};
constexpr std::pair<const char*, DownsampleFilter> kDownsamples[] = {
    {"13-tap", DownsampleFilter::taps13}, {"gaussian", DownsampleFilter::gaussian},
    {"separable", DownsampleFilter::separable}, {"box4", DownsampleFilter::box4}};
constexpr std::pair<const char*, UpsampleFilter> kUpsamples[] = {
    {"tent", UpsampleFilter::tent}, {"bilinear", UpsampleFilter::bilinear}};
constexpr std::pair<const char*, LevelCount> kLevelCounts[] = {{"fixed", LevelCount::fixed},
                                                                {"unity", LevelCount::unity},
                                                                {"threejs", LevelCount::threejs}};
constexpr std::pair<const char*, Storage> kStorages[] = {
    {"f32", Storage::f32}, {"f16", Storage::f16}, {"r11g11b10", Storage::r11g11b10},
    {"rgba8", Storage::rgba8}};
constexpr std::pair<const char*, PlanMode> kPlans[] = {{"adaptive", PlanMode::adaptive},
                                                       {"full", PlanMode::full}};
constexpr std::pair<const char*, BlurImpl> kBlurs[] = {{"fast", BlurImpl::fast},
                                                       {"reference", BlurImpl::reference},
                                                       {"approx", BlurImpl::approx}};

std::string str(float v) {
  std::ostringstream o;
  o.precision(9);
  o << v;
  return o.str();
}

void require(bool ok, const std::string& message) {
  if (!ok) throw ParamError(message);
}

}  // namespace

void validate(const BloomParams& p) {
  require(p.levels >= 1 && p.levels <= 16,
          "--levels must be in [1, 16], got " + std::to_string(p.levels));
  require(p.storage != Storage::r11g11b10 || p.nonfinite != NonFinite::propagate,
          "--nonfinite propagate keeps NaN and Inf in the scene, which an R11F_G11F_B10F target "
          "holds as the device chooses (llvmpipe writes NaN as 0): give --nonfinite zero or "
          "clamp with --storage r11g11b10");
  require(p.first_level_height >= 0 && p.first_level_height <= 16384,
          "--first-level-height must be in [0, 16384] (0 = half the image), got " +
              std::to_string(p.first_level_height));
  require(p.knee >= 0 && p.knee <= 1, "--knee must be in [0, 1], got " + str(p.knee));
  require(p.prefilter != Prefilter::soft_knee || p.threshold >= 0,
          "--prefilter soft-knee needs --threshold >= 0, got " + str(p.threshold));
  require(std::isfinite(p.low_frequency_boost) && p.low_frequency_boost >= 0,
          "--low-frequency-boost must be finite and >= 0, got " + str(p.low_frequency_boost));
  require(p.low_frequency_boost_curvature >= 0 && p.low_frequency_boost_curvature < 1,
          "--low-frequency-boost-curvature must be in [0, 1), got " +
              str(p.low_frequency_boost_curvature));
  require(p.high_pass_frequency > 0 && p.high_pass_frequency <= 1,
          "--high-pass-frequency must be in (0, 1], got " + str(p.high_pass_frequency));
  require(p.level_combine != LevelCombine::mix || p.strength <= 1,
          "--level-combine mix needs --strength in [0, 1], got " + str(p.strength));
  require(std::isfinite(p.level_weight) && p.level_weight >= 0 && p.level_weight <= 1,
          "--level-weight must be in [0, 1], got " + str(p.level_weight));
  require(std::isfinite(p.clamp_max) && p.clamp_max >= 0,
          "--clamp-max must be finite and >= 0 (0 = no clamp), got " + str(p.clamp_max));
  require(!p.karis || p.first_downsample == FirstDownsample::taps13,
          "--karis needs --first-downsample 13-tap (the Karis average weights its 13 taps)");
  require(p.first_downsample != FirstDownsample::bilinear || p.prefilter != Prefilter::per_lookup,
          "--first-downsample bilinear has no taps to threshold: use --prefilter soft-knee, "
          "bright or none");
  require(p.downsample == DownsampleFilter::taps13 || p.downsample == DownsampleFilter::box4 ||
              p.texel_step == TexelStep::texture,
          "--downsample " + to_string(p.downsample) +
              " steps by the source texture's size: --texel-step texture");
  require(p.upsample == UpsampleFilter::tent ||
              (p.upsample_radius == 0.0f && p.texel_step == TexelStep::texture),
          "--upsample bilinear reads one texel centre: --upsample-radius 0, --texel-step texture");
  require(std::isfinite(p.upsample_radius) && p.upsample_radius >= 0 && p.upsample_radius < 1,
          "--upsample-radius must be in [0, 1) (texture coordinates; 0 = one texel), got " +
              str(p.upsample_radius));
  require(p.first_axis == FirstAxis::horizontal || p.method == Method::gaussian,
          "--first-axis vertical needs --method gaussian (the mip chain has no blur passes)");
  require(p.composite_mode == CompositeMode::add || p.strength <= 1,
          "--composite-mode mix needs --strength in [0, 1], got " + str(p.strength));
  require(std::isfinite(p.threshold), "--threshold must be finite, got " + str(p.threshold));
  // three.js's chain (preset threejs): its pieces need each other.
  const bool threejs = p.level_count == LevelCount::threejs;
  require(p.level_combine != LevelCombine::sum || threejs,
          "--level-combine sum adds the blurred mips after the high pass: --level-count threejs");
  require(!threejs || p.first_downsample == FirstDownsample::bilinear,
          "--level-count threejs starts with the high pass, one lookup at half size: "
          "--first-downsample bilinear");
  require(p.prefilter != Prefilter::smoothstep || p.first_downsample == FirstDownsample::bilinear,
          "--prefilter smoothstep is three.js's high pass on one lookup: --first-downsample "
          "bilinear");
  require(std::isfinite(p.smooth_width) && p.smooth_width > 0,
          "--smooth-width must be finite and > 0, got " + str(p.smooth_width));
  // GLSL's smoothstep is undefined where its edges meet: threshold + width must be above the
  // threshold in f32, as the shader adds them.
  require(p.prefilter != Prefilter::smoothstep || p.threshold + p.smooth_width > p.threshold,
          "--smooth-width " + str(p.smooth_width) + " vanishes beside --threshold " +
              str(p.threshold) + " in float: smoothstep's edges would meet");
  const int blurred = threejs ? p.levels : p.levels - 1;
  if (p.downsample == DownsampleFilter::separable) {
    require(int(p.level_kernels.size()) >= blurred,
            "--level-kernels needs a radius for each of the " + std::to_string(blurred) +
                " blurred levels, got " + std::to_string(p.level_kernels.size()));
    for (int r : p.level_kernels)
      require(r >= 1 && r <= 64, "--level-kernels: each radius must be in [1, 64], got " +
                                     std::to_string(r));
    for (float s : p.level_sigmas)
      require(std::isfinite(s) && s >= 0.1f && s <= 64,
              "--level-sigmas: each sigma must be in [0.1, 64], got " + str(s));
  }
  if (p.level_combine == LevelCombine::sum) {
    require(int(p.level_factors.size()) >= p.levels,
            "--level-factors needs a factor for each of the " + std::to_string(p.levels) +
                " blurred levels, got " + std::to_string(p.level_factors.size()));
    for (float f : p.level_factors)
      require(std::isfinite(f), "--level-factors must be finite, got " + str(f));
    require(p.level_radius >= 0 && p.level_radius <= 1,
            "--level-radius must be in [0, 1], got " + str(p.level_radius));
    require(std::isfinite(p.level_strength) && p.level_strength >= 0,
            "--level-strength must be finite and >= 0, got " + str(p.level_strength));
  }
  require(std::isfinite(p.exposure) && p.exposure > 0,
          "--exposure must be finite and > 0, got " + str(p.exposure));
  require(std::isfinite(p.gamma) && p.gamma > 0,
          "--gamma must be finite and > 0, got " + str(p.gamma));
  require(std::isfinite(p.strength) && p.strength >= 0,
          "--strength must be finite and >= 0, got " + str(p.strength));
  require(p.passes >= 0 && p.passes <= 1000,
          "--passes must be in [0, 1000], got " + std::to_string(p.passes));
  require(p.subtexel_bits >= 0 && p.subtexel_bits <= 23,
          "subtexel bits must be in [0, 23] (0 = exact float weights), got " +
              std::to_string(p.subtexel_bits));
  require(p.threads >= 0 && p.threads <= 1024,
          "--threads must be in [0, 1024] (0 = all), got " + std::to_string(p.threads));
}

void refuse_ignored_options(const BloomParams& p, const OptionGiven& given) {
  const BloomParams d;
  // `changed`: the value differs from its default (what decides without `given`); `mode`:
  // whether the pipeline reads the option.
  const auto needs = [&given](bool changed, bool mode, const std::string& option,
                              const std::string& what) {
    const bool set = given ? given(option) : changed;
    require(!set || mode, option + " does nothing without " + what);
  };
  const bool mip = p.method == Method::mip;
  // The mip chain's choices under --method gaussian: each by name when the caller knows what
  // was given (a preset's under --method gaussian are not); else any that differs from seed
  // 002's chain.
  static const char* const kMipOnly[] = {
      "--karis", "--prefilter", "--texel-step", "--upsample-radius", "--bloom-upscale",
      "--chain-storage", "--first-level-height", "--level-combine", "--level-weights",
      "--knee-form", "--clamp-max", "--first-downsample", "--downsample", "--upsample",
      "--level-count", "--composite"};
  if (given) {
    for (const char* o : kMipOnly) needs(false, mip, o, "--method mip");
  } else {
    require(mip || (!p.mip_variant() && !p.karis),
            "--prefilter, --karis, --karis-form, --texel-step, --upsample-radius, "
            "--bloom-upscale, --chain-storage, --first-level-height, --level-combine, "
            "--level-weights, --knee-form, --clamp-max, --first-downsample, --downsample, "
            "--upsample and --level-count do nothing without --method mip");
  }
  needs(p.levels != d.levels, mip, "--levels", "--method mip");
  needs(p.passes != d.passes, !mip, "--passes", "--method gaussian");
  needs(p.kernel != d.kernel, !mip, "--kernel", "--method gaussian");
  needs(p.first_axis != d.first_axis, !mip, "--first-axis", "--method gaussian");
  needs(p.blur != d.blur, !mip && p.precision == Precision::f32, "--blur",
        "--method gaussian at --precision f32");
  needs(p.subtexel_bits != d.subtexel_bits, p.precision == Precision::f32, "--subtexel-bits",
        "--precision f32");
  // What the first level's prefilter reads: the threshold unless it has none; the luminance
  // (weights and space) where a luminance is compared (the soft knee takes the largest
  // channel), or seed 002's per-tap Karis weight reads it.
  const bool thresholds = !mip || p.prefilter != Prefilter::none;
  const bool luminance = !mip || p.prefilter == Prefilter::per_lookup ||
                         p.prefilter == Prefilter::bright ||
                         p.prefilter == Prefilter::smoothstep ||
                         (p.karis && p.karis_form == KarisForm::per_tap);
  const std::string prefilters = "a prefilter that reads it (--prefilter per-lookup, bright";
  needs(p.threshold != d.threshold, thresholds, "--threshold",
        prefilters + ", soft-knee or smoothstep)");
  needs(p.luma != d.luma, luminance, "--luma", prefilters + " or smoothstep, or per-tap --karis)");
  needs(p.luma_space != d.luma_space, luminance, "--luma-space",
        prefilters + " or smoothstep, or per-tap --karis)");
  needs(p.karis_form != d.karis_form, p.karis, "--karis-form", "--karis");
  needs(p.knee != d.knee, p.prefilter == Prefilter::soft_knee, "--knee",
        "--prefilter soft-knee");
  needs(p.knee_form != d.knee_form, p.prefilter == Prefilter::soft_knee, "--knee-form",
        "--prefilter soft-knee");
  needs(p.smooth_width != d.smooth_width, p.prefilter == Prefilter::smoothstep,
        "--smooth-width", "--prefilter smoothstep");
  needs(p.first_level_height != d.first_level_height, p.level_count == LevelCount::fixed,
        "--first-level-height", "--level-count fixed");
  const bool separable = p.downsample == DownsampleFilter::separable;
  needs(p.level_kernels != d.level_kernels, separable, "--level-kernels",
        "--downsample separable");
  needs(!p.level_sigmas.empty(), separable, "--level-sigmas", "--downsample separable");
  // A flag: refused when set (given as --no-level-normalise it asks for nothing).
  needs(p.level_normalise, separable || !p.level_normalise, "--level-normalise",
        "--downsample separable");
  const bool sum = p.level_combine == LevelCombine::sum;
  needs(p.level_factors != d.level_factors, sum, "--level-factors", "--level-combine sum");
  needs(p.level_radius != d.level_radius, sum, "--level-radius", "--level-combine sum");
  needs(p.level_strength != d.level_strength, sum, "--level-strength", "--level-combine sum");
  // Under the sum there are no upsamples: nothing blends levels or reads one with the tent,
  // unless the full-size bloom does.
  const std::string chain = "a chain of upsamples (--level-combine add, mix or lerp)";
  needs(p.level_weights != d.level_weights, !sum, "--level-weights", chain);
  needs(p.upsample != d.upsample, !sum, "--upsample", chain);
  needs(p.upsample_radius != d.upsample_radius, !sum || p.bloom_upscale == BloomUpscale::tent,
        "--upsample-radius", chain + " or --bloom-upscale tent");
  needs(p.level_weight != d.level_weight, !sum && p.level_weights == LevelWeights::constant,
        "--level-weight", "--level-weights constant");
  const bool bevy = !sum && p.level_weights == LevelWeights::bevy;
  needs(p.low_frequency_boost != d.low_frequency_boost, bevy, "--low-frequency-boost",
        "--level-weights bevy");
  needs(p.low_frequency_boost_curvature != d.low_frequency_boost_curvature, bevy,
        "--low-frequency-boost-curvature", "--level-weights bevy");
  needs(p.high_pass_frequency != d.high_pass_frequency, bevy, "--high-pass-frequency",
        "--level-weights bevy");
}

std::string to_string(Method v) { return name_of(v, kMethods); }
std::string to_string(KernelName v) { return name_of(v, kKernels); }
std::string to_string(Storage v) { return name_of(v, kStorages); }
std::string to_string(Precision v) { return name_of(v, kPrecisions); }
std::string to_string(NonFinite v) { return name_of(v, kPolicies); }
std::string to_string(PlanMode v) { return name_of(v, kPlans); }
std::string to_string(BlurImpl v) { return name_of(v, kBlurs); }
std::string to_string(CompositeOrder v) { return name_of(v, kOrders); }
std::string to_string(CompositeMode v) { return name_of(v, kModes); }
std::string to_string(FirstAxis v) { return name_of(v, kAxes); }
std::string to_string(Luma v) { return name_of(v, kLumas); }
std::string to_string(LumaSpace v) { return name_of(v, kLumaSpaces); }
std::string to_string(Prefilter v) { return name_of(v, kPrefilters); }
std::string to_string(KarisForm v) { return name_of(v, kKarisForms); }
std::string to_string(TexelStep v) { return name_of(v, kTexelSteps); }
std::string to_string(BloomUpscale v) { return name_of(v, kUpscales); }
std::string to_string(LevelCombine v) { return name_of(v, kCombines); }
std::string to_string(LevelWeights v) { return name_of(v, kWeights); }
std::string to_string(KneeForm v) { return name_of(v, kKneeForms); }
std::string to_string(FirstDownsample v) { return name_of(v, kFirstDownsamples); }
std::string to_string(DownsampleFilter v) { return name_of(v, kDownsamples); }
std::string to_string(UpsampleFilter v) { return name_of(v, kUpsamples); }
std::string to_string(LevelCount v) { return name_of(v, kLevelCounts); }
KneeForm parse_knee_form(const std::string& s) { return parse_enum("--knee-form", s, kKneeForms); }
FirstDownsample parse_first_downsample(const std::string& s) {
  return parse_enum("--first-downsample", s, kFirstDownsamples);
}
DownsampleFilter parse_downsample_filter(const std::string& s) {
  return parse_enum("--downsample", s, kDownsamples);
}
UpsampleFilter parse_upsample_filter(const std::string& s) {
  return parse_enum("--upsample", s, kUpsamples);
}
LevelCount parse_level_count(const std::string& s) {
  return parse_enum("--level-count", s, kLevelCounts);
}
LevelCombine parse_level_combine(const std::string& s) {
  return parse_enum("--level-combine", s, kCombines);
}
LevelWeights parse_level_weights(const std::string& s) {
  return parse_enum("--level-weights", s, kWeights);
}
FirstAxis parse_first_axis(const std::string& s) { return parse_enum("--first-axis", s, kAxes); }
Luma parse_luma(const std::string& s) { return parse_enum("--luma", s, kLumas); }
LumaSpace parse_luma_space(const std::string& s) {
  return parse_enum("--luma-space", s, kLumaSpaces);
}
CompositeMode parse_composite_mode(const std::string& s) {
  return parse_enum("--composite-mode", s, kModes);
}
Prefilter parse_prefilter(const std::string& s) { return parse_enum("--prefilter", s, kPrefilters); }
KarisForm parse_karis_form(const std::string& s) {
  return parse_enum("--karis-form", s, kKarisForms);
}
TexelStep parse_texel_step(const std::string& s) {
  return parse_enum("--texel-step", s, kTexelSteps);
}
BloomUpscale parse_bloom_upscale(const std::string& s) {
  return parse_enum("--bloom-upscale", s, kUpscales);
}
Storage parse_chain_storage(const std::string& s) {
  return parse_enum("--chain-storage", s, kStorages);
}
CompositeOrder parse_composite_order(const std::string& s) {
  return parse_enum("--composite", s, kOrders);
}
Method parse_method(const std::string& s) { return parse_enum("--method", s, kMethods); }
KernelName parse_kernel(const std::string& s) { return parse_enum("--kernel", s, kKernels); }
Storage parse_storage(const std::string& s) { return parse_enum("--storage", s, kStorages); }
Precision parse_precision(const std::string& s) { return parse_enum("--precision", s, kPrecisions); }
NonFinite parse_nonfinite(const std::string& s) { return parse_enum("--nonfinite", s, kPolicies); }
PlanMode parse_plan_mode(const std::string& s) { return parse_enum("--plan", s, kPlans); }
BlurImpl parse_blur_impl(const std::string& s) { return parse_enum("--blur", s, kBlurs); }

}  // namespace bloomref
