// bloomref — the pipeline stages (DESIGN.md, "The pipeline"), one function each.
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
/// (and counted), under every policy. Measured reason (README, "Stiff and extreme inputs"):
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

/// The largest value a stage stores: 65504 for f16, kRangeGuard (2^120) for f32; what
/// `clamp` maps +Inf to.
double storage_max(Storage s);

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
/// already.
template <class T>
void extract_bright(BasicView<const T> src, BasicView<T> dst, T threshold, int threads,
                    bool dst_zeroed = false, std::uint8_t* nonzero = nullptr,
                    const std::uint8_t* bright_rows = nullptr);

namespace detail {
/// Stage bright's RGB of n RGBA texels of one row, packed as RGB (extract_bright's test and
/// values: its bits): what blur_bright_fused's first pass stores.
void bright_rgb_row(const float* rgba, float* rgb, int n, float threshold);
}  // namespace detail

enum class Axis { horizontal, vertical };

/// A run of set texels on one row: x in [x0, x1).
struct Span {
  int x0 = 0, x1 = 0;
};
/// A set of texels as spans per row (rows[y] for image row y): sorted, disjoint and not
/// touching (x1 of one < x0 of the next). The adaptive plan's supports in this form cost time in
/// proportion to their spans, not to the image (a mask costs a sweep of every byte per pass).
using RowSpans = std::vector<std::vector<Span>>;

struct BlurPassOptions {
  Axis axis = Axis::horizontal;
  const Kernel* kernel = nullptr;
  int subtexel_bits = 0;  ///< f32 only; see sampler.h
  /// Optional width x height mask, row-major: where 0, the pixel is not computed and is written
  /// (+0, +0, +0, 1) -- exactly what the blur gives when every texel it reads is +0, which is what
  /// blur_support guarantees for its zeros (the adaptive plan's tiles, at texel resolution).
  const std::uint8_t* active = nullptr;
  /// With `active`: dst already holds +0 in R, G and B wherever active is 0, so the fast pass
  /// (blur_pass_fast) does not write its tiles without an active texel (texels of the other
  /// tiles are computed, the inactive ones (+0, +0, +0, 1)); the tiles left alone keep dst's
  /// alpha. The adaptive plan sets it from pass 2 on (its supports only grow, and pass k writes
  /// the buffer pass k - 2 wrote; pass 2: the bright image, (+0, +0, +0, 1) outside its nonzero
  /// support), and on pass 1 when it writes into a zeroed image (alpha 0 where left alone: no
  /// stage after the blur reads the bloom's alpha). The other passes write them anyway.
  bool dst_zero_outside = false;
  /// Optional, with `active` and dst_zero_outside: the same set as `active`, as spans per row.
  /// blur_pass_fast then visits only the tiles these spans touch (found without reading the
  /// mask), shared out between threads by count, not by position in the image.
  const RowSpans* active_spans = nullptr;
  /// Optional: ledgers of src's and dst's pages (image.h). Where blur_pass_fast lists its tiles
  /// (active, active_spans and dst_zero_outside all set) it marks what they read and write there
  /// and faults the new pages in writable before the pass, so that no page of a zeroed buffer
  /// is read before it exists. The other passes and blur_pass / blur_pass_approx ignore them.
  detail::PageLedger* src_pages = nullptr;
  detail::PageLedger* dst_pages = nullptr;
  /// Threads that fault the ledgers' new pages in (0: the pass's own). The adaptive plan runs a
  /// small support's pass on one thread but faults its pages in on all of them.
  int page_threads = 0;
};

/// Stage `blur.k`: one single-direction pass of a separable kernel, through GL_LINEAR /
/// GL_CLAMP_TO_EDGE lookups. f32: uv = (x + 0.5f) / n, d = 1.0f / n, tap coordinate
/// uv + d * o_i (resp. uv - d * o_i); r = T(uv) * w0, then r = r + T(+) * w_i, r = r + T(-) * w_i.
/// f64: taps at x + o_i texels exactly, exact rational weights. Alpha out is 1.
template <class T>
void blur_pass(BasicView<const T> src, BasicView<T> dst, const BlurPassOptions& opt, int threads);

/// Instruction sets of the fast blur's kernel. Every one gives blur_pass's bits. avx512: the
/// blur's tile kernels with 64-byte vectors (AVX-512F), the other fast stages' AVX2 kernels.
enum class BlurIsa { best, generic, avx2, avx512 };
/// Whether this CPU (and this build) can run `isa`; `best` and `generic` always can.
bool blur_isa_available(BlurIsa isa);
/// The instruction set `best` resolves to here ("avx512", "avx2" or "generic").
std::string blur_isa_name(BlurIsa isa = BlurIsa::best);

/// Stage `blur.k` in f32, fast and bit-identical to blur_pass (same IEEE operations in the same
/// order per channel, tested on every scene and corpus image): tiled, one whole output line at
/// a time from whole input lines, vectorised across the blur (blur_fast.cpp). Two provisos:
/// where two NaNs meet, which one comes out (sign, payload) is not specified (IEEE 754 leaves it
/// open and the compiler may commute an addition); and x * 1 is taken as x, which differs only
/// for a signalling NaN -- the bright stage passes no NaN and arithmetic makes only quiet ones,
/// so none reaches a blur. `dst` must not overlap `src`. Throws ParamError for an instruction
/// set this CPU lacks.
void blur_pass_fast(BasicView<const float> src, BasicView<float> dst, const BlurPassOptions& opt,
                    int threads, BlurIsa isa = BlurIsa::best);

/// Stages `blur.1` ... `blur.n` of the dense plan in f32 at once (pass k along axes[k - 1]),
/// with blur_pass_fast's bits in every texel (tested), but fused: the image is cut into
/// column strips, and each strip streams through all n passes keeping per pass only the rows
/// the next pass still reads (a ring of about 2 x (16 + 5) rows of the strip), so the image is
/// read and written once instead of n times (blur_fused.cpp). Nothing is rounded between passes
/// (f32 storage). With `impl` approx, every pass is blur_pass_approx's instead, with its bits
/// (tested; `kernel` and `subtexel_bits` then only shape the strips); `reference` is `fast`
/// (the same bits).
void blur_passes_fused(BasicView<const float> src, BasicView<float> dst,
                       const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                       int threads, BlurIsa isa = BlurIsa::best,
                       BlurImpl impl = BlurImpl::fast);

/// What blur_passes_fused can hand its output to instead of an image: rows [y0, y1) of columns
/// [x0, x1) of the last pass (RGBA, alpha 1), row y0 + i at rows[i], texel x0 first. Called
/// from the thread of the strip [x0, x1) as each block of rows is done (rows in order within a
/// strip, strips in any order, two strips at once on two threads); every texel of the image is
/// handed over exactly once. The rows are scratch, valid during the call.
using FusedBlurSink =
    std::function<void(int x0, int x1, int y0, int y1, const float* const* rows)>;
/// blur_passes_fused with its output handed to `sink` block by block while it is still in
/// cache (the same bits), instead of written into an image: the executor finishes it there
/// (finish_fast_rows), so the dense plan neither allocates the bloom image nor reads it back.
void blur_passes_fused(BasicView<const float> src, const FusedBlurSink& sink,
                       const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                       int threads, BlurIsa isa = BlurIsa::best,
                       BlurImpl impl = BlurImpl::fast);

/// Stages bright and blur.1 ... blur.n at once, for the dense plan: blur_passes_fused of
/// extract_bright(scene) (the same bits), the bright image never made whole (each strip makes
/// its rows as its first pass reads them). The sink may write the texels it is handed into
/// `scene` itself (in place: the executor's finishing stages do); nothing else may change the
/// scene during the call.
void blur_bright_fused(BasicView<const float> scene, float threshold, const FusedBlurSink& sink,
                       const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                       int threads, BlurIsa isa = BlurIsa::best,
                       BlurImpl impl = BlurImpl::fast);

/// Stage `blur.k`, fast and approximate: not GL's sampling but the 9-tap stencil both kernels
/// sample exactly (taps on texels x +- i, clamped to the edge, the discrete9 weights rounded to
/// float), pairs summed first, multiply-adds fused with AVX2+FMA. Its error against the f64
/// truth is measured (docs/tradeoff.md). Honours opt.active row by row (a row without an active
/// texel is written (0, 0, 0, 1)); ignores subtexel_bits.
void blur_pass_approx(BasicView<const float> src, BasicView<float> dst,
                      const BlurPassOptions& opt, int threads, BlurIsa isa = BlurIsa::best);

/// Whether a texel's RGB is not +0 in every channel (bit-exact: -0, NaN and Inf count): what
/// the adaptive plan tracks (nonzero_support, extract_bright's `nonzero`).
template <class T>
inline bool rgb_not_plus_zero(const T* p) {
  bool nz = false;
  for (int c = 0; c < 3; ++c) nz |= !(p[c] == T(0) && !std::signbit(p[c]));
  return nz;
}

/// The texels whose RGB is not +0 in every channel (bit-exact: -0, NaN and Inf count), as a
/// width x height mask. Returns how many.
template <class T>
std::size_t nonzero_support(BasicView<const T> img, std::uint8_t* mask, int threads);

/// The support of a blur pass's output given its input's: a texel is set when any texel one of
/// its lookups may read (both texels of every tap, both rows across) is set in `in`. Uses the
/// pass's own tap tables, so it is exact for this pass's coordinates. Returns how many are set.
template <class T>
std::size_t blur_support(const std::uint8_t* in, std::uint8_t* out, int width, int height,
                         const BlurPassOptions& opt, int threads);

/// The set texels of a width x height mask (0 or 1 per texel) as spans per row. Returns how many.
/// With `rows` (one entry a row), a row whose entry is 0 is taken as empty without reading it.
std::size_t mask_spans(const std::uint8_t* mask, int width, int height, RowSpans& out,
                       int threads, const std::uint8_t* rows = nullptr);

/// blur_support on spans: the same set (tested), in time proportional to the spans. Each pass's
/// lookups read a contiguous range of positions along the blur whose ends never decrease with
/// the position, and one or two adjacent lines across it: an input span maps to an output span
/// found by two binary searches. Returns how many are set, or nothing when a pass's tables lack
/// that shape (then use blur_support).
template <class T>
std::optional<std::size_t> blur_support_spans(const RowSpans& in, RowSpans& out, int width,
                                              int height, const BlurPassOptions& opt,
                                              int threads);

/// The adaptive plan's support through the blur passes, one tracker for the CPU and the GL
/// executors: the bright image's nonzero texels, then each pass's blur_support_spans (as spans,
/// with a mask kept equal to them for the consumers that read texels). The support only
/// grows; once it covers more than `dense_fraction` of the image, tracking it costs more than it
/// saves (scripts/adaptive-table), so the tracker stops and says so: whole passes from there.
class BlurSupportTracker {
 public:
  BlurSupportTracker(int width, int height, double dense_fraction)
      : width_(width), height_(height), dense_fraction_(dense_fraction) {}
  /// Pass 1's input, the bright image (read once, on the first advance).
  template <class T>
  void start(BasicView<const T> bright, int threads);
  /// Pass 1's input support given directly as a mask (extract_bright's `nonzero`); rows whose
  /// entry in `rows` (optional) is 0 are empty.
  void start(std::vector<std::uint8_t>&& support, int threads,
             const std::uint8_t* rows = nullptr);
  bool started() const { return !mask_.empty(); }
  /// This pass's output support, width x height, row-major; nullptr once dense. T chooses the
  /// tap tables (f32: the shader's coordinates; f64: exact taps).
  template <class T>
  const std::uint8_t* advance(const BlurPassOptions& opt, int threads);
  bool dense() const { return dense_; }
  /// Set texels of the last pass's support (the whole image once dense).
  std::size_t count() const { return count_; }
  /// The last pass's support as spans per row (the same set as advance's mask); nullptr once
  /// dense.
  const RowSpans* spans() const { return dense_ ? nullptr : &spans_; }

 private:
  int width_, height_;
  double dense_fraction_;
  bool dense_ = false;
  std::size_t count_ = 0;
  // The support is tracked as spans; the mask is kept equal to them by clearing the old spans
  // and setting the new ones (both in proportion to the support, not to the image).
  std::vector<std::uint8_t> mask_;
  RowSpans spans_, next_;
};

/// Stage `composite`: scene + strength * bloom (f32: t = strength * bloom; scene + t).
template <class T>
void composite(BasicView<const T> scene, BasicView<const T> bloom, BasicView<T> dst, T strength,
               int threads);

/// The f32 oracle's exp: IEEE basic operations only, evaluated in double and rounded once, so
/// its bits are the same on every machine and in every vector lane (the C library's expf is
/// not correctly rounded and differs between libraries). Within 1e-15 relative of e^x before
/// the rounding, so it returns the correctly rounded float except where e^x lies that close to
/// a rounding boundary (measured: README, "The f32 oracle's exp and pow are its own"; tested in
/// tests/test_oracle_math.cpp). Method: reference/src/oracle_math.h.
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

/// Stages `tonemap` and `output` in f32, fast and bit-identical to tonemap<float> and
/// encode_output<float> (tested): each row's RGB values packed into a line and run through
/// oracle_exp / oracle_pow four double lanes at a time (finish_kernels.inc). `dst` may be
/// `src`. Throws ParamError for an instruction set this CPU lacks.
void tonemap_fast(BasicView<const float> hdr, BasicView<float> dst, float exposure, int threads,
                  BlurIsa isa = BlurIsa::best);
void encode_output_fast(BasicView<const float> mapped, BasicView<float> dst, float gamma,
                        int threads, BlurIsa isa = BlurIsa::best);
/// Stages `composite`, `tonemap` and `output` in f32 at once, row by row (the image is read
/// and written once instead of three times), with the three stages' bits (tested); `bloom`
/// empty means no composite. `dst` may be `scene`. Nothing is rounded between the stages (f32
/// storage). `bloom_support`, where given (one span list per row), says where the bloom's R, G
/// and B may differ from +0 (the adaptive plan's last blur support): elsewhere the composite
/// adds strength * +0 without reading the bloom, the same bits, and the bloom's pages that no
/// pass wrote are not touched. There, where 2^17 or more pixels lie outside the support and at
/// least half of 1024 pixels sampled over the scene have binary16 values (a half-float file),
/// the finished value of every binary16 value is computed once (65536 values, by the same
/// kernel) and a pixel outside the support whose values s + strength * +0 are binary16 values
/// takes them from that table: the same function of the same floats, so the same bits.
/// Returns the pixels finished from the table (0 without one).
std::size_t finish_fast(BasicView<const float> scene, BasicView<const float> bloom,
                        BasicView<float> dst, float strength, float exposure, float gamma,
                        int threads, BlurIsa isa = BlurIsa::best,
                        const RowSpans* bloom_support = nullptr);

/// finish_fast's composite, tone map and output over `rows` row segments of `width` RGBA
/// pixels (scene_rows[i], bloom_rows[i], dst_rows[i]; dst may be the scene), on the calling
/// thread, with finish_fast's bits: every value is finished on its own, so a row cut into
/// segments gives what the whole row gives. For the fused blur's sink.
void finish_fast_rows(const float* const* scene_rows, const float* const* bloom_rows,
                      float* const* dst_rows, int rows, int width, float strength,
                      float exposure, float gamma, BlurIsa isa = BlurIsa::best);

/// Rounds every channel to the storage format in place. f32 storage is a no-op in either
/// precision (the f64 truth is not narrowed to float); f16 storage rounds to binary16.
template <class T>
void store(BasicView<T> img, Storage storage, HalfRounding rounding, int threads);

/// PNG code of a display value: round(clamp(x, 0, 1) * 255); NaN -> 0.
std::uint8_t quantize_8bit(float x);

}  // namespace bloomref
