// bloomref — the parameters of one bloom run, and their validation.
// Defaults are the seeds' (LearnOpenGL "Bloom", ../shared/seeds/000): threshold 1, 10 passes,
// exposure 1, gamma 2.2. Validation refuses bad values with a ParamError naming the parameter;
// nothing is clamped silently.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace bloomref {

enum class Method { gaussian, mip };
enum class KernelName { discrete9, linear5 };
/// How a stage's output is stored, as the GL path stores it: RGBA32F, RGBA16F, r11g11b10
/// (GL_R11F_G11F_B10F: unsigned floats, 6-bit mantissas for R and G, 5 for B, no alpha) or rgba8
/// (GL_RGBA8: unsigned normalised, each channel clamped to [0, 1] and rounded to the nearest
/// 255th, NaN as 0). BloomParams::storage stores every stage but the mip chain's levels, which
/// BloomParams::chain_storage stores when it is set.
enum class Storage { f32, f16, r11g11b10, rgba8 };
/// f32 mirrors the shaders' operation order; f64 is the truth used to measure error.
enum class Precision { f32, f64 };
/// What happens to NaN and +-Inf in the input (docs/design.md, "Specification").
enum class NonFinite { zero, clamp, propagate, error };
/// `adaptive` leaves out work the scene does not need (same bits as `full`).
enum class PlanMode { adaptive, full };
/// How the f32 gaussian blur is computed: `fast` (tiled and vectorised, blur_pass_fast) and
/// `reference` (the straightforward per-texel loop, blur_pass) give the same bits; `approx`
/// (blur_pass_approx) is faster and not GL's sampling: its error is measured, not assumed.
/// f64 always uses the reference loop.
enum class BlurImpl { fast, reference, approx };
/// Where the bloom is added: to the HDR scene before the tone map (the classic, seed 000), or to
/// the tone-mapped image (seed 003: mapped + 0.02 * bloom with exposure 0.5).
enum class CompositeOrder { before_tonemap, after_tonemap };
/// How the bloom is combined with the image: `add` (image + strength * bloom, the seeds') or
/// `mix` (GLSL mix(image, bloom, strength) = image * (1 - strength) + bloom * strength, as
/// LearnOpenGL's "Physically Based Bloom" article, 6.bloom_final.fs, does).
enum class CompositeMode { add, mix };
/// The axis of the gaussian method's first blur pass; the passes then alternate. Seed 000's
/// host starts horizontal (`bool horizontal = true`); some engines start vertical.
enum class FirstAxis { horizontal, vertical };
/// The weights of the luminance the threshold (and seed 002's per-tap Karis weight) reads:
/// Rec. 709, (0.2126, 0.7152, 0.0722) as seed 000's shaders; or Rec. 601 luma, (0.299, 0.587,
/// 0.114), as many shipped blooms take it (ITU-R BT.601). The group forms of the Karis average
/// keep their own (KarisForm).
enum class Luma { rec709, rec601 };
/// The colour the threshold's luminance is taken of: linear (the seeds'), or max(c, 0) encoded
/// by IEC 61966-2-1's sRGB curve, or by pow(., 1 / gamma) with the run's gamma, as blooms
/// whose threshold is set in an encoded space do (Unity-Technologies/PostProcessing#629).
enum class LumaSpace { linear, srgb, gamma };

// The mip chain's variants (docs/design.md, "Mip-chain variants"). The defaults are seed 002's
// chain; preset learnopengl-pbb sets the article's (src/8.guest/2022/6.physically_based_bloom).
/// Where the threshold is: on each lookup of the first downsample (seed 002), or in a `bright`
/// stage before the chain (luminance > threshold, as the article's scene shader 6.bloom.fs
/// writes its second output), the chain then reading that image without a threshold; or none:
/// the chain reads the scene and thresholds nothing (Bevy's bloom with its default threshold 0,
/// bevyengine/bevy crates/bevy_post_process/src/bloom/bloom.wesl); or soft_knee: the chain reads
/// the scene and the first downsample's result is scaled by Bevy's soft_threshold (Unity's form,
/// catlikecoding.com/unity/tutorials/advanced-rendering/bloom, 3.4): with knee = threshold x
/// softness, contribution max(b - threshold, clamp(b - threshold + knee, 0, 2 knee)^2 / (4 knee +
/// 0.00004)) / max(b, 0.00001), b the largest channel; or smoothstep: three.js's luminosity high
/// pass (mrdoob/three.js examples/jsm/tsl/display/BloomNode.js, luminosityHighPass): the first
/// level's lookup c times smoothstep(threshold, threshold + smooth_width, L), L its luminance.
enum class Prefilter { per_lookup, bright, none, soft_knee, smoothstep };
/// The first downsample's Karis average: `per_tap` (seed 002: each tap weighted 1 / (1 + L),
/// normalised within its group) or `group_srgb` (the article's 6.new_downsample.fs: each group
/// of four scaled by 1 / (1 + luma / 4), luma = Rec. 601 weights of pow(group, 1 / 2.2), not
/// normalised; the sum then max(., 0.0001)); or `group_linear` (Bevy's bloom.wesl,
/// downsample_first: each group of four scaled by its weight, then by 1 / (1 + L / 4) with L its
/// Rec. 709 luminance in linear colour, not normalised; the sum clamped to [0.0001, 3.40282347e37]).
enum class KarisForm { per_tap, group_srgb, group_linear };
/// The downsample's texel step: 1 / the source texture's size, or 1 / the size the host passes
/// as a float that it halves per level (the article's srcResolution: 400.5 where the texture is
/// 400 wide), so that odd levels are sampled off their texel grid; or `target`: from the size of
/// the level drawn (seed 002's shader: 0.5 / size downsampling, 2 / size upsampling, size the
/// target's), one texel of its source only where that source is exactly twice (half) its size.
enum class TexelStep { texture, halved_float, target };
/// The bloom at full resolution: the 3x3 tent of up.1 (seed 002), or one bilinear lookup of it
/// (the article's final pass samples the half-resolution level directly).
enum class BloomUpscale { tent, bilinear };
/// How up.k combines down.k with the tent of the level below it: `add` (down.k + C_k tent, the
/// blend GL_ONE / GL_ONE when C_k is 1) or `mix` (tent C_k + down.k (1 - C_k): the blend
/// constant / one-minus-constant, Bevy's energy-conserving mode) or `lerp` (HLSL's
/// lerp(down.k, tent, C_k) = down.k + (tent - down.k) C_k in the shader, Unity URP's Upsample);
/// or sum: no chain of upsamples, one stage up.1 at the first level's size = level_strength x
/// (F_1 lookup(down.2) + ... + F_K lookup(down.K+1)), F_k = mix(f_k, 1.2 - f_k, level_radius)
/// with f_k the k-th --level-factors entry (three.js's composite pass, BloomNode.js
/// compositePass).
enum class LevelCombine { add, mix, lerp, sum };
/// The per-level constants C_k: `one` (every C_k 1), or `bevy` (bloom/mod.rs,
/// compute_blend_factor, in f32: (strength + boost) x high-pass, boost = (1 - (1 - k / K)^(1 / (1 -
/// curvature))) x low_frequency_boost, times 1 - strength under LevelCombine::mix; K the last
/// level's index, counted from 0 at down.1), or `constant` (every C_k --level-weight: Unity
/// URP's scatter, Mathf.Lerp(0.05, 0.95, scatter)).
enum class LevelWeights { one, bevy, constant };
/// The soft threshold's arithmetic (Prefilter::soft_knee): Bevy's (bloom.wesl, soft_threshold,
/// with the host's precomputed constants and 0.00001) or Unity URP's (Bloom.shader,
/// FragPrefilter: clamp(b - threshold + knee, 0, 2 knee)^2 / (4 knee + 1e-4), max(b, 1e-4)).
enum class KneeForm { bevy, unity };
/// The first level's filter: seed 003's 13 taps, or one bilinear lookup at the target texel's
/// centre (Unity URP's FragPrefilter), or the 4-tap box: four lookups at (+-1, +-1) texels of
/// the source, each the mean of a 2x2 block, summed and times 0.25 (the 4x4 box, Kawase's and
/// catlikecoding.com's Unity bloom tutorial's downsample).
enum class FirstDownsample { taps13, bilinear, box4 };
/// The other levels' filter: seed 003's 13 taps, or Unity URP's Gaussian pyramid (Bloom.shader,
/// FragBlurH then FragBlurV): nine lookups two source texels apart along x into the level's
/// size, stored as the level is, then five lookups at 0, +-1.38461538 and +-3.23076923 texels
/// along y; or separable: three.js's blurred mips (BloomNode.js, _getSeparableBlurMaterial): a
/// pass along x into the level's size, stored, then one along y, each sum_i c_i (lookup(uv + i d)
/// + lookup(uv - i d)) for i < R (the centre once, times c_0), d one texel of the level drawn,
/// c_i = 0.39894 exp(-0.5 i^2 / s^2) / s in double rounded to float, s = R / 3, not normalised
/// unless level_normalise; R the level's --level-kernels entry.
/// box4: the 4-tap box, as FirstDownsample::box4.
enum class DownsampleFilter { taps13, gaussian, separable, box4 };
/// What up.k reads of the level below: the 3x3 tent, or one bilinear lookup (Unity URP's
/// Upsample without _BLOOM_HQ).
enum class UpsampleFilter { tent, bilinear };
/// How many levels: `fixed` (--levels, fewer when the image ends) or `unity` (URP's
/// PostProcessPass.SetupBloom: clamp(floor(log2(max(w >> 1, h >> 1)) - 1), 1, --levels)), or
/// `threejs`: down.1 (the high pass) at (round(w / 2), round(h / 2)) as JavaScript's Math.round
/// rounds, then --levels blurred mips, the first at that size, each next round(n / 2) of the one
/// before (BloomNode.js, setSize; 1x1 repeats as it does there).
enum class LevelCount { fixed, unity, threejs };

struct BloomParams {
  Method method = Method::gaussian;
  float threshold = 1.0f;   ///< bright when luminance > threshold (strictly)
  float exposure = 1.0f;    ///< tone map: 1 - exp(-hdr * exposure)
  float gamma = 2.2f;       ///< output: pow(max(x, 0), 1 / gamma)
  float strength = 1.0f;    ///< composite: scene + strength * bloom
  int passes = 10;          ///< single-direction blur passes; pass k is horizontal when k is odd
  KernelName kernel = KernelName::discrete9;
  Storage storage = Storage::f32;
  Precision precision = Precision::f32;
  NonFinite nonfinite = NonFinite::zero;
  /// Sub-texel precision of bilinear weights: 0 = exact float weights (llvmpipe, measured),
  /// 8 = 8-bit fixed point (NVIDIA-like hardware). Only the f32 precision uses it.
  int subtexel_bits = 0;
  int threads = 0;  ///< 0 = all hardware threads
  PlanMode plan = PlanMode::adaptive;
  BlurImpl blur = BlurImpl::fast;
  // Method mip (seed 003):
  int levels = 6;           ///< downsample levels; fewer when the image reaches 1x1
  bool karis = false;       ///< Karis average on the first downsample
  CompositeOrder composite = CompositeOrder::before_tonemap;
  CompositeMode composite_mode = CompositeMode::add;
  FirstAxis first_axis = FirstAxis::horizontal;
  Luma luma = Luma::rec709;
  LumaSpace luma_space = LumaSpace::linear;
  /// The seeds' luminance: Rec. 709's weights on linear colour (what the vector fast paths test).
  bool seed_luma() const { return luma == Luma::rec709 && luma_space == LumaSpace::linear; }
  Prefilter prefilter = Prefilter::per_lookup;
  KarisForm karis_form = KarisForm::per_tap;
  TexelStep texel_step = TexelStep::texture;
  /// The upsample tent's tap distance in texture coordinates (the article's filterRadius,
  /// 0.005); 0: one texel of the level it reads (seed 002).
  float upsample_radius = 0.0f;
  BloomUpscale bloom_upscale = BloomUpscale::tent;
  /// How down.k and up.k are stored; f32 and f16 are `storage` itself.
  Storage chain_storage = Storage::f32;
  bool chain_storage_set = false;  ///< false: chain_storage follows `storage`
  /// The first level's height, its width in proportion (round(width x height' / height)), as
  /// Bevy sizes its bloom texture (max_mip_dimension); 0: half the image (floor(n / 2)).
  int first_level_height = 0;
  /// Prefilter::soft_knee: the knee's width as a fraction of the threshold (Bevy's
  /// threshold_softness), in [0, 1].
  float knee = 0.0f;
  LevelCombine level_combine = LevelCombine::add;
  LevelWeights level_weights = LevelWeights::one;
  float low_frequency_boost = 0.7f;            ///< LevelWeights::bevy (Bevy's defaults)
  float low_frequency_boost_curvature = 0.95f;  ///< in [0, 1)
  float high_pass_frequency = 1.0f;            ///< in (0, 1]
  float level_weight = 1.0f;                   ///< LevelWeights::constant: every C_k
  KneeForm knee_form = KneeForm::bevy;
  /// The first level's input clamped to at most this before the soft threshold (Unity URP's
  /// ClampMax, min(ClampMax, color)); 0: no clamp.
  float clamp_max = 0.0f;
  FirstDownsample first_downsample = FirstDownsample::taps13;
  DownsampleFilter downsample = DownsampleFilter::taps13;
  UpsampleFilter upsample = UpsampleFilter::tent;
  LevelCount level_count = LevelCount::fixed;
  /// Prefilter::smoothstep: the width of the smoothstep above the threshold (three.js's
  /// smoothWidth).
  float smooth_width = 0.01f;
  /// DownsampleFilter::separable: each blurred mip's kernel radius R (taps i < R either side).
  std::vector<int> level_kernels = {6, 10, 14, 18, 22};
  /// Each blurred mip's sigma; empty (or a mip beyond its length): R / 3, three.js's.
  std::vector<float> level_sigmas;
  /// Each blurred mip's coefficients divided by their sum c_0 + 2 (c_1 + ... + c_R-1), as
  /// UnrealBloomPass's weightSum does (three.js's WebGL bloom); false: as they are (BloomNode's).
  bool level_normalise = false;
  /// LevelCombine::sum: each blurred mip's factor, the radius that mirrors them about 0.6, and
  /// the sum's multiplier (three.js's bloomFactors, radius and strength).
  std::vector<float> level_factors = {1.0f, 0.8f, 0.6f, 0.4f, 0.2f};
  float level_radius = 0.0f;
  float level_strength = 1.0f;
  /// The storage of the chain's levels (chain_storage when set, else storage).
  Storage level_storage() const { return chain_storage_set ? chain_storage : storage; }
  /// Whether any mip-chain choice differs from seed 002's chain.
  bool mip_variant() const {
    return prefilter != Prefilter::per_lookup || karis_form != KarisForm::per_tap ||
           texel_step != TexelStep::texture || upsample_radius != 0.0f ||
           bloom_upscale != BloomUpscale::tent || chain_storage_set || first_level_height != 0 ||
           level_combine != LevelCombine::add || level_weights != LevelWeights::one ||
           knee_form != KneeForm::bevy || clamp_max != 0.0f ||
           first_downsample != FirstDownsample::taps13 || downsample != DownsampleFilter::taps13 ||
           upsample != UpsampleFilter::tent || level_count != LevelCount::fixed;
  }
};

/// Whether the user gave an option ("--knee"); validate's caller knows (the command line, a
/// manifest's keys); a preset's values are not given.
using OptionGiven = std::function<bool(const std::string& option)>;
/// Throws ParamError for the first value out of its domain.
void validate(const BloomParams& p);
/// Throws ParamError for an option that only a mode reads, given without that mode (`given`;
/// without one: set to other than its default), rather than ignoring it. A preset's values
/// under a mode the user overrode are not given.
void refuse_ignored_options(const BloomParams& p, const OptionGiven& given = nullptr);

// Names used by the CLI, JSON and files. parse_* throw ParamError listing the accepted names.
std::string to_string(Method m);
std::string to_string(KernelName k);
std::string to_string(Storage s);
std::string to_string(Precision p);
std::string to_string(NonFinite n);
std::string to_string(PlanMode m);
std::string to_string(BlurImpl b);
std::string to_string(CompositeOrder c);
std::string to_string(CompositeMode c);
std::string to_string(FirstAxis a);
std::string to_string(Luma l);
std::string to_string(LumaSpace s);
std::string to_string(Prefilter p);
std::string to_string(KarisForm k);
std::string to_string(TexelStep t);
std::string to_string(BloomUpscale b);
std::string to_string(LevelCombine c);
std::string to_string(LevelWeights w);
std::string to_string(KneeForm k);
std::string to_string(FirstDownsample f);
std::string to_string(DownsampleFilter f);
std::string to_string(UpsampleFilter f);
std::string to_string(LevelCount c);
Method parse_method(const std::string& s);
KernelName parse_kernel(const std::string& s);
Storage parse_storage(const std::string& s);
Precision parse_precision(const std::string& s);
NonFinite parse_nonfinite(const std::string& s);
PlanMode parse_plan_mode(const std::string& s);
BlurImpl parse_blur_impl(const std::string& s);
CompositeOrder parse_composite_order(const std::string& s);
CompositeMode parse_composite_mode(const std::string& s);
FirstAxis parse_first_axis(const std::string& s);
Luma parse_luma(const std::string& s);
LumaSpace parse_luma_space(const std::string& s);
Prefilter parse_prefilter(const std::string& s);
KarisForm parse_karis_form(const std::string& s);
TexelStep parse_texel_step(const std::string& s);
BloomUpscale parse_bloom_upscale(const std::string& s);
LevelCombine parse_level_combine(const std::string& s);
LevelWeights parse_level_weights(const std::string& s);
KneeForm parse_knee_form(const std::string& s);
FirstDownsample parse_first_downsample(const std::string& s);
DownsampleFilter parse_downsample_filter(const std::string& s);
UpsampleFilter parse_upsample_filter(const std::string& s);
LevelCount parse_level_count(const std::string& s);
/// --chain-storage: f32, f16, r11g11b10 or rgba8 (as --storage).
Storage parse_chain_storage(const std::string& s);

}  // namespace bloomref
