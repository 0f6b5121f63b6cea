// bloomref — the mip-chain bloom (method `mip`, seed 003: Jimenez 2014, "Next generation post
// processing in Call of Duty: Advanced Warfare").
//
// Level sizes: level 0 is the image; level k is max(1, floor(n / 2)) of level k-1 per axis.
// `down.k` (level k) samples level k-1 with 13 GL_LINEAR lookups at offsets of 0, +-1, +-2
// source texels around the target texel's centre; `up.k` = down.k + tent(up.k+1) with the 3x3
// tent (1-2-1 / 16) at one texel of the smaller level; the bloom is the tent of up.1 at full
// resolution. Lookups follow sampler.h exactly, so odd sizes are sampled as GL samples them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "bloomref/half.h"
#include "bloomref/image.h"
#include "bloomref/params.h"
#include "bloomref/stages.h"

namespace bloomref {

struct LevelSize {
  int width = 0, height = 0;
};

/// Sizes of levels 1..K (level 0, the image, not included): at most `levels`, fewer when the
/// chain reaches 1x1 (no level repeats 1x1; a 1x1 image has one 1x1 level).
std::vector<LevelSize> mip_levels(int width, int height, int levels);

/// The chain's level sizes under `p`: mip_levels, or with p.first_level_height set, level 1
/// (round(width x r), round(height x r)) at least 1, r = first_level_height / height in f32 (Bevy's
/// prepare_bloom_textures), and each next level its size >> 1 (at least 1), at most p.levels, no
/// 1x1 repeated; with p.level_count unity, the number of levels Unity URP's SetupBloom draws
/// (at most p.levels), each floor(n / 2) of the one above; with p.level_count threejs, the high
/// pass's size (round(width / 2), round(height / 2)) and p.levels blurred mips, the first of
/// the same size, each next round(n / 2) (LevelCount::threejs).
std::vector<LevelSize> chain_levels(const BloomParams& p, int width, int height);

/// Bevy's soft_threshold (bloom.wesl) of one texel, in f32 as the shader computes it with the
/// host's precomputed (threshold, threshold - knee, 2 knee, 0.25 / (knee + 0.00001)): the factor
/// each channel is multiplied by. In [0, 1] for a threshold >= 0. KneeForm::unity: Unity URP's
/// FragPrefilter (Bloom.shader) in its order: softness = clamp(b - threshold + knee, 0, 2 knee),
/// softness^2 / (4 knee + 1e-4), max(b - threshold, softness) / max(b, 1e-4); also in [0, 1].
template <class T>
T soft_knee_factor(const T rgb[3], float threshold, float knee, KneeForm form = KneeForm::bevy);

/// How up.k adds the tent of the level below to down.k (LevelCombine), with its constant.
struct LevelBlend {
  LevelCombine combine = LevelCombine::add;
  float weight = 1.0f;
  /// add with weight 1: seed 002's order (down.k first, each tap added in turn).
  bool plain() const { return combine == LevelCombine::add && weight == 1.0f; }
  /// What up.k keeps of down.k: 1 - C under mix and lerp, 1 under add.
  float kept() const { return combine == LevelCombine::add ? 1.0f : 1.0f - weight; }
};

/// The blend of stage up.k of a chain of `levels` levels under `p` (LevelWeights).
LevelBlend level_blend(const BloomParams& p, int k, int levels);

/// One lookup of a chain stage: offset (ox, oy) in source texels, weight.
struct MipTap {
  int ox, oy;
  float weight;
};
/// Seed 003's 13 downsample taps (centre, inner four, outer eight) and their groups of four
/// for the Karis average (tap indices, group weights 0.5, 0.125 x 4).
const std::vector<MipTap>& downsample_taps();
/// The 4-tap box's taps (FirstDownsample::box4, DownsampleFilter::box4): (-1, -1), (1, -1),
/// (-1, 1), (1, 1), each 0.25, summed in that order.
const std::vector<MipTap>& box4_taps();
const std::vector<std::vector<int>>& karis_groups();
const std::vector<float>& karis_group_weights();
/// The 3x3 tent (1-2-1 / 16) in seed 003's order.
const std::vector<MipTap>& tent_taps();

/// The GL lookup of `src` for texel (x, y) of a tw x th target at offset (ox, oy) source texels,
/// computed in float as the shader does: uv = (x + 0.5) / size, uv + o / textureSize(src).
void mip_lookup(ConstImageView src, int x, int y, int tw, int th, int ox, int oy,
                int subtexel_bits, float out[3]);

struct DownsampleOptions {
  bool first = false;         ///< the first downsample thresholds each tap (L < threshold -> 0)
  float threshold = 1.0f;
  bool karis = false;         ///< first downsample only: the Karis average (karis_form)
  int subtexel_bits = 0;
  /// Optional dst-sized mask (adaptive plan): where 0 the texel is written (+0, +0, +0, 1), what
  /// it computes there: every texel it reads is +0 (mip_support), or, on the first level, no
  /// lookup reaches the threshold (mip_nothing_bright: all zero).
  const std::uint8_t* active = nullptr;
  /// Prefilter::bright: the first level reads a thresholded image and thresholds nothing.
  bool threshold_taps = true;
  KarisForm karis_form = KarisForm::per_tap;
  /// Prefilter::soft_knee: the first level's result scaled by the soft threshold
  /// (soft_threshold), with this knee (threshold x softness).
  bool soft_knee = false;
  float knee = 0.0f;
  KneeForm knee_form = KneeForm::bevy;
  /// The first level: its filter, and the clamp of its result before the soft threshold (0: none).
  FirstDownsample first_filter = FirstDownsample::taps13;
  float clamp_max = 0.0f;
  /// Levels after the first: seed 003's 13 taps or Unity's Gaussian pyramid, whose horizontal
  /// pass is stored as `intermediate` (rounded as `rounding`) before the vertical one reads it.
  DownsampleFilter filter = DownsampleFilter::taps13;
  Storage intermediate = Storage::f32;
  HalfRounding rounding = HalfRounding::nearest_even_saturate;
  /// Prefilter::none: the first level reads the scene and thresholds nothing.
  /// The size whose reciprocal is the texel step (TexelStep::halved_float: the host's float
  /// size); 0: the source texture's.
  float step_width = 0.0f, step_height = 0.0f;
  /// The tap threshold's luminance (its weights also the per-tap Karis weight's, on linear colour).
  LumaRule luma;
  /// Prefilter::smoothstep (the first level): its result times smoothstep(threshold, threshold +
  /// smooth_width, L), L its luminance under `luma`.
  bool smoothstep = false;
  float smooth_width = 0.01f;
  /// DownsampleFilter::separable: the level's kernel radius (taps i < radius either side) and
  /// sigma (0: radius / 3).
  int kernel_radius = 0;
  double kernel_sigma = 0.0;
  bool kernel_normalise = false;  ///< the coefficients divided by their sum (level_normalise)
};

/// three.js's separable blur coefficients for a kernel radius R (BloomNode.js,
/// _getSeparableBlurMaterial): c_i = 0.39894 exp(-0.5 i^2 / s^2) / s for i in [0, R), s = R / 3
/// (or `sigma` when it is > 0), in double as JavaScript computes them, rounded to float as the
/// uniform array holds them. `normalise`: each c_i divided by c_0 + 2 (c_1 + ... + c_R-1) in
/// double before that rounding (UnrealBloomPass.js divides the sum by the weights' float sum in
/// the shader, docs/design.md "Mip-chain variants" says what that difference is worth).
std::vector<float> separable_coefficients(int radius, double sigma = 0.0, bool normalise = false);

/// The sigma of stage down.k's separable blur under `p`: its --level-sigmas entry, else 0 (R / 3).
double level_sigma(const BloomParams& p, int k);

/// The first level's factor under Prefilter::smoothstep: smoothstep(threshold, threshold + width,
/// L) in the shader's f32 order (GLSL 4.60, 8.3: t = clamp((L - e0) / (e1 - e0), 0, 1), t t (3 -
/// 2 t)), e1 = threshold + width computed in f32.
template <class T>
T smoothstep_factor(T luminance, float threshold, float width);

/// The mip factor F_k of LevelCombine::sum for factor f (three.js's lerpBloomFactor): mix(f, 1.2
/// - f, radius) in f32 as the shader computes it, f (1 - radius) + (1.2 - f) radius.
float sum_factor(float f, float radius);

/// Stage up.1 under LevelCombine::sum: dst (the first level's size) = strength x (F_1
/// lookup(levels[0]) + F_2 lookup(levels[1]) + ...) in that order, each a GL_LINEAR lookup at the
/// texel's centre, F_i = sum_factor(factors[i], radius). Alpha 1.
template <class T>
void sum_levels(const std::vector<BasicView<const T>>& levels, BasicView<T> dst,
                const std::vector<float>& factors, float radius, float strength, int subtexel_bits,
                int threads);

/// The options of stage down.k of a w x h scene under `p` (its variant), sampling with
/// `subtexel_bits`.
DownsampleOptions downsample_options(const BloomParams& p, int k, int width, int height,
                                     int subtexel_bits);

/// The host's float size of level k (0: the image) under TexelStep::halved_float: the image's
/// size halved k times in float, as the article's bloomFBO::Init does (mipSize *= 0.5f).
float halved_size(int n, int k);

/// Stage `down.k`: dst (level k) from src (level k-1). f32 order (seed 003): q_i = lookup at
/// uv + o_i * texel (texel = 1 / source size), thresholded on the first level; without Karis
/// r = sum_i q_i * w_i in tap order; with Karis r = sum over groups of
/// sum_j ((g * w_j) / s) * q_j, w_j = 1 / (1 + L(q_j)), s = w_a + w_b + w_c + w_d. Alpha 1.
/// KarisForm::group_srgb (6.new_downsample.fs, mipLevel 0): G = (q_a + q_b + q_c + q_d) * (g / 4)
/// per group in the shader's order, G * (1 / (1 + dot(pow(G, 1 / 2.2), (0.299, 0.587, 0.114))
/// * 0.25)), r = G_0 + ... + G_4, then max(r, 0.0001). KarisForm::group_linear (Bevy's
/// downsample_first): G as for group_srgb, G * (1 / (1 + dot(G, Rec. 709) / 4)), r = G_0 + ... +
/// G_4, then clamp(r, 0.0001, 3.40282347e37).
/// FirstDownsample::bilinear (the first level): r = one lookup at the target texel's centre, then
/// min(r, clamp_max) when clamp_max > 0, then the soft threshold.
/// DownsampleFilter::gaussian (the other levels; Unity URP's FragBlurH and FragBlurV): h = sum_i
/// lookup(uv + (t i, 0)) w_i for i = -4..4 in order, t = (1 / source width) x 2, w = 0.01621622,
/// 0.05405405, 0.12162162, 0.19459459, 0.22702703 (symmetric), stored as `intermediate`; then
/// r = sum_j lookup_h(uv + (0, s o_j)) v_j, s = 1 / height, o = -3.23076923, -1.38461538, 0,
/// 1.38461538, 3.23076923, v = 0.07027027, 0.31621622, 0.22702703 (symmetric).
/// DownsampleFilter::separable (three.js's blurred mips): h = lookup(uv) c_0 + sum_i (lookup(uv +
/// (t i, 0)) + lookup(uv - (t i, 0))) c_i for i = 1 .. R-1 in order, t = 1 / the level's width,
/// stored as `intermediate`; then the same along y on h, t = 1 / the level's height.
/// Prefilter::smoothstep (FirstDownsample::bilinear): r = the lookup times smoothstep_factor.
template <class T>
void downsample(BasicView<const T> src, BasicView<T> dst, const DownsampleOptions& opt,
                int threads);

/// Stage `up.k` (current = down.k) and `bloom` (current empty: full resolution, no add):
/// r = current (or 0); r = r + lookup(small, uv + o_i * texel) * t_i over the 3x3 tent in seed
/// 003's order. Alpha 1.
/// `radius` > 0: the taps are `radius` apart in texture coordinates on both axes (the article's
/// filterRadius) instead of one texel of `small`.
/// A `blend` other than plain: t = the tent's sum in tap order, then r = t * C + current
/// (LevelCombine::add) or r = t * C + current * (1 - C) (mix), as the GPU's blend unit combines
/// the pass's output with the level it draws into.
/// `target_step` (TexelStep::target): the taps 2 / the target's size apart (one texel of a source
/// half its size) instead of one texel of `small`.
/// LevelCombine::lerp: r = current + (t - current) * C (HLSL's lerp).
/// UpsampleFilter::bilinear: t is one lookup of `small` at the texel's centre instead of the tent.
template <class T>
void upsample_tent(BasicView<const T> small, BasicView<const T> current, BasicView<T> dst,
                   int subtexel_bits, int threads, const std::uint8_t* active = nullptr,
                   float radius = 0.0f, LevelBlend blend = {}, bool target_step = false,
                   UpsampleFilter filter = UpsampleFilter::tent);

/// The Gaussian pyramid's offsets and weights (DownsampleFilter::gaussian), in tap order:
/// horizontal in units of the horizontal step t, vertical in texels of the level.
struct GaussianTap {
  float offset, weight;
};
const std::vector<GaussianTap>& gaussian_down_h_taps();
const std::vector<GaussianTap>& gaussian_down_v_taps();
/// The Gaussian pyramid's (or DownsampleFilter::separable's) horizontal pass alone into `h` (the
/// level's size), stored as opt.intermediate: what the vertical pass of downsample reads.
template <class T>
void downsample_gaussian_h(BasicView<const T> src, BasicView<T> h, const DownsampleOptions& opt,
                           int threads);

/// Stage `bloom` under BloomUpscale::bilinear: one GL_LINEAR lookup of `small` at each texel's
/// centre of `dst` (the article's final pass reads the half-resolution level so). Alpha 1.
template <class T>
void upscale_bilinear(BasicView<const T> small, BasicView<T> dst, int subtexel_bits, int threads);

/// Whether the first downsample is (+0, +0, +0, 1) everywhere because none of its lookups can
/// reach the threshold: threshold > 0 and every texel finite with L + 1e-4 (|R| + |G| + |B|)
/// below it (L in double). A lookup mixes texels with weights summing to 1 within a few ULPs,
/// so its luminance in float is at most the largest texel's plus a few ULPs of the channel
/// magnitudes: 1e-4 is a margin of ~1000x. Then every tap is zeroed by the threshold.
template <class T>
bool mip_nothing_bright(BasicView<const T> scene, double threshold, int threads,
                        const LumaRule& luma = {});

/// The adaptive plan's support of a chain stage: the texels of a tw x th target whose lookups
/// (offsets -reach..reach source texels: 2 for down.k, 1 for up.k and the bloom) read a texel
/// set in `src_mask` (sw x sh), or that are set in `also` (up.k: down.k's support; may be null).
/// Conservative: the lookups' bounding box. A texel outside it reads only +0 texels and computes
/// (+0, +0, +0): the sums start at +0 (up.k adds its own texel, +0 outside `also`) and add
/// products of +0. Not for the first downsample (it reads the whole scene). Returns the count.
template <class T>
std::size_t mip_support(const std::uint8_t* src_mask, int sw, int sh, const std::uint8_t* also,
                        int tw, int th, int reach, int subtexel_bits, std::uint8_t* out,
                        int threads);

}  // namespace bloomref
