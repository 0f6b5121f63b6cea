// bloomref — the pipeline stages (docs/design.md, "Specification"), one function each.
//
// Every stage reads const views and writes one image of the same size; `T` is the precision
// (float mirrors the shaders' operation order, double is the truth). The f32 operation order is
// written out in each comment and compiled with -ffp-contract=off, so it is what runs. Stages
// do not round to the storage format: the executor calls `store` after each one, exactly where
// the GL path writes a render target.
//
// `bright` is computed from the sanitised scene before it is stored (the seeds write both in one
// MRT draw), so with f16 storage the threshold sees the unrounded value.
//
// Alpha: `bright` and `blur.k` write alpha 1 (as the seeds' shaders do); `composite`, `tonemap`
// and `output` carry the scene's alpha through unchanged.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "bloomref/half.h"
#include "bloomref/image.h"
#include "bloomref/kernel.h"
#include "bloomref/params.h"

namespace bloomref {

struct NonFiniteCounts {
  std::uint64_t nan = 0, pos_inf = 0, neg_inf = 0;
  std::uint64_t out_of_range = 0;  ///< finite values beyond kRangeGuard (clamped to it)
  std::uint64_t total() const { return nan + pos_inf + neg_inf; }
  /// Whether the input stage has anything to change.
  bool any() const { return total() + out_of_range > 0; }
  NonFiniteCounts& operator+=(const NonFiniteCounts& o) {
    nan += o.nan; pos_inf += o.pos_inf; neg_inf += o.neg_inf; out_of_range += o.out_of_range;
    return *this;
  }
};

/// The largest magnitude the pipeline carries: 2^120. Finite input beyond it is clamped to it
/// (and counted), under every policy. Reason (docs/design.md, "Range guard"):
/// values near FLT_MAX (scale.hdr, WideFloatRange.exr: 1.7e38) overflow to Inf inside GL's
/// bilinear filter and in the mip chain's sums, and llvmpipe's filter turns Inf texels into
/// NaN. 2^8 of headroom covers every sum the stages form (four bilinear texels, up to 17
/// pyramid levels, the composite); any tone map has long saturated at 2^120.
constexpr double kRangeGuard = 1329227995784915872903807060280344576.0;  // 2^120

/// Rec. 709 luminance, dot(rgb, (0.2126, 0.7152, 0.0722)) summed left to right (seed 000).
/// S is the scalar type of the weights: T itself, or T's lane type when T is a vector of values
/// (the same operations in every lane).
template <class T, class S = T>
inline T luminance(T r, T g, T b) {
  return r * S(0.2126) + g * S(0.7152) + b * S(0.0722);
}

/// A luminance's three weights in the scalar type S: S(0.2126) ... for Rec. 709, S(0.299) ...
/// for Rec. 601 (BloomParams::luma).
template <class S>
struct LumaWeights {
  S r, g, b;
};
template <class S>
LumaWeights<S> luma_weights(Luma l) {
  return l == Luma::rec601 ? LumaWeights<S>{S(0.299), S(0.587), S(0.114)}
                           : LumaWeights<S>{S(0.2126), S(0.7152), S(0.0722)};
}

/// The luminance with weights w, summed left to right: with Rec. 709's, luminance(r, g, b)'s
/// bits.
template <class T, class S = T>
inline T luminance(T r, T g, T b, const LumaWeights<S>& w) {
  return r * w.r + g * w.g + b * w.b;
}

/// How the threshold's luminance is formed: its weights and the space of the colour it is
/// taken of (BloomParams::luma, luma_space; gamma for LumaSpace::gamma).
struct LumaRule {
  Luma weights = Luma::rec709;
  LumaSpace space = LumaSpace::linear;
  float gamma = 2.2f;
  bool seed() const { return weights == Luma::rec709 && space == LumaSpace::linear; }
};
inline LumaRule luma_rule(const BloomParams& p) { return {p.luma, p.luma_space, p.gamma}; }

float oracle_pow(float x, float y);  // below

/// One channel encoded as `rule.space` says, as common.glsl's luma_encode: max(x, 0) (maxNum,
/// as the devices' max), then pow(x, 1 / gamma), or IEC 61966-2-1's curve (12.92 x up to
/// 0.0031308, else 1.055 x^(1 / 2.4) - 0.055). f32: the shader's float operations with the
/// oracle's pow; f64: exact.
template <class T>
inline T luma_encode(T x, const LumaRule& rule) {
  x = std::fmax(x, T(0));
  const T inv = rule.space == LumaSpace::gamma ? T(1) / T(rule.gamma) : T(1) / T(2.4);
  T p;
  if constexpr (std::is_same_v<T, float>) p = oracle_pow(x, inv);
  else p = std::pow(x, inv);
  if (rule.space == LumaSpace::gamma) return p;
  return x <= T(0.0031308) ? T(12.92) * x : T(1.055) * p - T(0.055);
}

/// The luminance the threshold compares: of (r, g, b) encoded as rule.space says, weighted as
/// rule.weights says; linear with Rec. 709's weights, luminance(r, g, b)'s bits.
template <class T>
inline T threshold_luminance(T r, T g, T b, const LumaRule& rule) {
  const LumaWeights<T> w = luma_weights<T>(rule.weights);
  if (rule.space == LumaSpace::linear) return luminance(r, g, b, w);
  return luminance(luma_encode(r, rule), luma_encode(g, rule), luma_encode(b, rule), w);
}

/// The largest value a stage stores: 65504 for f16, 65024 for r11g11b10, 1 for rgba8,
/// kRangeGuard (2^120) for f32; what `clamp` maps +Inf to.
double storage_max(Storage s);
/// The non-finite policy as the stage shaders' sanitize_value takes it (gpu/shaders/common.glsl):
/// 0 zero, 1 clamp, 2 propagate, 3 error.
int nonfinite_code(NonFinite n);

/// One value under a non-finite policy. `error` leaves the value alone (the plan refuses the
/// image before any stage runs).
template <class T>
inline T sanitize_value(T v, NonFinite policy, Storage storage) {
  if (std::isfinite(v)) return std::fabs(v) > T(kRangeGuard) ? std::copysign(T(kRangeGuard), v) : v;
  if (policy == NonFinite::propagate || policy == NonFinite::error) return v;
  if (policy == NonFinite::zero || std::isnan(v)) return T(0);
  const T m = static_cast<T>(storage_max(storage));
  return v > 0 ? m : -m;
}

/// Adds to `c` the NaN, +Inf, -Inf and finite values beyond kRangeGuard among p[0..n); returns
/// whether there was any. Most rows hold none: one branch-free test per value first (NaN fails
/// it too), which the compiler vectorises; the counting loop only for the rows that fail it.
template <class T>
inline bool count_nonfinite_values(const T* p, int n, NonFiniteCounts& c) {
  int outside = 0;
  for (int i = 0; i < n; ++i) outside |= !(std::fabs(p[i]) <= T(kRangeGuard));
  if (!outside) return false;
  for (int i = 0; i < n; ++i) {
    if (std::isnan(p[i])) ++c.nan;
    else if (std::isinf(p[i])) ++(p[i] > 0 ? c.pos_inf : c.neg_inf);
    else if (std::fabs(p[i]) > T(kRangeGuard)) ++c.out_of_range;
  }
  return true;
}


/// Stage `input`: applies the non-finite policy to every channel; returns what it found.
template <class T>
NonFiniteCounts sanitize(BasicView<const T> src, BasicView<T> dst, NonFinite policy,
                         Storage storage, int threads);

/// Stage `bright`: (rgb, 1) where luminance(rgb) > threshold (strictly; a tie is not bright),
/// else (0, 0, 0, 1). NaN luminance is not bright. With dst_zeroed (dst holds +0 everywhere, as
/// BasicImage::zeroed gives) only the bright pixels are written: the others keep (0, 0, 0, 0),
/// for a caller that reads no alpha of the bright image (the executor when no stage is kept).
/// With `nonzero` (width x height), also what nonzero_support(dst) would give, without reading
/// dst again. With dst_zeroed and `bright_rows` (one entry a row, SceneFacts::bright_rows), a
/// row whose entry is 0 holds no bright pixel and is not read: its `nonzero` row must then be 0
/// already. The luminance has `luma`'s weights.
template <class T>
void extract_bright(BasicView<const T> src, BasicView<T> dst, T threshold, int threads,
                    bool dst_zeroed = false, std::uint8_t* nonzero = nullptr,
                    const std::uint8_t* bright_rows = nullptr, const LumaRule& luma = {});

namespace detail {
/// Stage bright's RGB of n RGBA texels of one row, packed as RGB (extract_bright's test and
/// values: its bits): what blur_bright_fused's first pass stores.
void bright_rgb_row(const float* rgba, float* rgb, int n, float threshold,
                    const LumaRule& luma = {});
}  // namespace detail

enum class Axis { horizontal, vertical };

struct BlurPassOptions {
  Axis axis = Axis::horizontal;
  const Kernel* kernel = nullptr;
  int subtexel_bits = 0;  ///< f32 only; see sampler.h
  /// Optional width x height mask, row-major: where 0, the pixel is not computed and is written
  /// (+0, +0, +0, 1) -- exactly what the blur gives when every texel it reads is +0, which is what
  /// blur_support guarantees for its zeros (the adaptive plan's tiles, at texel resolution).
  const std::uint8_t* active = nullptr;
};

/// Stage `blur.k`: one single-direction pass of a separable kernel, through GL_LINEAR /
/// GL_CLAMP_TO_EDGE lookups. f32: uv = (x + 0.5f) / n, d = 1.0f / n, tap coordinate
/// uv + d * o_i (resp. uv - d * o_i); r = T(uv) * w0, then r = r + T(+) * w_i, r = r + T(-) * w_i.
/// f64: taps at x + o_i texels exactly, exact rational weights. Alpha out is 1.
template <class T>
void blur_pass(BasicView<const T> src, BasicView<T> dst, const BlurPassOptions& opt, int threads);

/// Whether a texel's RGB is not +0 in every channel (bit-exact: -0, NaN and Inf count): what
/// the adaptive plan tracks (nonzero_support, extract_bright's `nonzero`).
template <class T>
inline bool rgb_not_plus_zero(const T* p) {
  bool nz = false;
  for (int c = 0; c < 3; ++c) nz |= !(p[c] == T(0) && !std::signbit(p[c]));
  return nz;
}

/// Stage `composite`: scene + strength * bloom (f32: t = strength * bloom; scene + t).
template <class T>
void composite(BasicView<const T> scene, BasicView<const T> bloom, BasicView<T> dst, T strength,
               int threads);

/// Stage `composite` under CompositeMode::mix: GLSL mix(scene, bloom, a), defined (GLSL 4.60,
/// 8.3) as scene * (1 - a) + bloom * a: f32 u = scene * (1 - a); v = bloom * a; u + v.
/// `dst` may be `scene`.
template <class T>
void composite_mix(BasicView<const T> scene, BasicView<const T> bloom, BasicView<T> dst, T a,
                   int threads);

/// The f32 oracle's exp: IEEE basic operations only, evaluated in double and rounded once, so
/// its bits are the same on every machine and in every vector lane (the C library's expf is
/// not correctly rounded and differs between libraries). Within 1e-15 relative of e^x before
/// the rounding, so it returns the correctly rounded float except where e^x lies that close to
/// a rounding boundary (docs/design.md, "Specification"; tested in
/// tests/reference/test_oracle_math.cpp). Method: reference/exact/bloomref/exact/oracle_math.h.
float oracle_exp(float x);
/// The f32 oracle's pow for x >= 0 (or NaN), the same way; IEEE pow's special cases for those x
/// (including pow(-0, odd integer y) = -0), NaN for x < 0.
float oracle_pow(float x, float y);

/// Stage `tonemap`: 1 - exp(-hdr * exposure). f64 computes -expm1(-hdr * exposure); f32 (and
/// the shader) evaluate 1 - exp(x) for |x| >= 0.5 (exp: oracle_exp) and a Horner-form Taylor
/// series below, which keeps full relative precision where hdr * exposure is tiny (1 - exp
/// cancels there).
template <class T>
void tonemap(BasicView<const T> hdr, BasicView<T> dst, T exposure, int threads);

/// Stage `output`: pow(max(x, 0), 1 / gamma), with 1 / gamma computed in T (f32: oracle_pow).
/// Display-referred.
template <class T>
void encode_output(BasicView<const T> mapped, BasicView<T> dst, T gamma, int threads);

/// Rounds every channel to the storage format in place. f32 storage is a no-op in either
/// precision (the f64 truth is not narrowed to float); f16 storage rounds to binary16.
template <class T>
void store(BasicView<T> img, Storage storage, HalfRounding rounding, int threads);

/// PNG code of a display value: round(clamp(x, 0, 1) * 255); NaN -> 0.
std::uint8_t quantize_8bit(float x);

}  // namespace bloomref
