// bloomref engine — the fast CPU path: the stages of stages.h in f32 with the same bits
// (tested), vectorised per instruction set and fused where that saves memory traffic. The
// executor (runtime/) chooses between these and the reference functions; conventions as in
// bloomref/image.h.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "bloomref/stages.h"

namespace bloomref {

/// Instruction sets of the fast blur's kernel. Every one gives blur_pass's bits. avx512: the
/// blur's tile kernels with 64-byte vectors (AVX-512F), the other fast stages' AVX2 kernels.
enum class BlurIsa { best, generic, avx2, avx512 };
/// Whether this CPU (and this build) can run `isa`; `best` and `generic` always can.
bool blur_isa_available(BlurIsa isa);
/// The instruction set `best` resolves to here ("avx512", "avx2" or "generic").
std::string blur_isa_name(BlurIsa isa = BlurIsa::best);

/// A run of set texels on one row: x in [x0, x1).
struct Span {
  int x0 = 0, x1 = 0;
};
inline bool operator==(const Span& a, const Span& b) { return a.x0 == b.x0 && a.x1 == b.x1; }
inline bool operator!=(const Span& a, const Span& b) { return !(a == b); }
/// A set of texels as spans per row (rows[y] for image row y): sorted, disjoint and not
/// touching (x1 of one < x0 of the next). The adaptive plan's supports in this form cost time in
/// proportion to their spans, not to the image (a mask costs a sweep of every byte per pass).
using RowSpans = std::vector<std::vector<Span>>;

namespace detail {
class PageLedger;  // bloomref/engine/page_ledger.h
}  // namespace detail

/// What the adaptive plan tells blur_pass_fast beyond BlurPassOptions (whose mask `active`
/// every blur honours): the engine's own facts about its buffers.
struct FastPassOptions {
  /// With `active`: dst already holds +0 in R, G and B wherever active is 0, so the pass does
  /// not write its tiles without an active texel (texels of the other tiles are computed, the
  /// inactive ones (+0, +0, +0, 1)); the tiles left alone keep dst's alpha. The adaptive plan
  /// sets it from pass 2 on (its supports only grow, and pass k writes the buffer pass k - 2
  /// wrote; pass 2: the bright image, (+0, +0, +0, 1) outside its nonzero support), and on pass
  /// 1 when it writes into a zeroed image (alpha 0 where left alone: no stage after the blur
  /// reads the bloom's alpha). The other passes write them anyway.
  bool dst_zero_outside = false;
  /// Optional, with `active` and dst_zero_outside: the same set as `active`, as spans per row.
  /// The pass then visits only the tiles these spans touch (found without reading the mask),
  /// shared out between threads by count, not by position in the image.
  const RowSpans* active_spans = nullptr;
  /// Optional: ledgers of src's and dst's pages (page_ledger.h). Where the pass lists its tiles
  /// (active, active_spans and dst_zero_outside all set) it marks what they read and write
  /// there and faults the new pages in writable before the pass, so that no page of a zeroed
  /// buffer is read before it exists.
  detail::PageLedger* src_pages = nullptr;
  detail::PageLedger* dst_pages = nullptr;
  /// Threads that fault the ledgers' new pages in (0: the pass's own). The adaptive plan runs a
  /// small support's pass on one thread but faults its pages in on all of them.
  int page_threads = 0;
};

/// Stage `blur.k` in f32, fast and bit-identical to blur_pass (same IEEE operations in the same
/// order per channel, tested on every scene and corpus image): tiled, one whole output line at
/// a time from whole input lines, vectorised across the blur (blur_fast.cpp). Two provisos:
/// where two NaNs meet, which one comes out (sign, payload) is not specified (IEEE 754 leaves it
/// open and the compiler may commute an addition); and x * 1 is taken as x, which differs only
/// for a signalling NaN -- the bright stage passes no NaN and arithmetic makes only quiet ones,
/// so none reaches a blur. `dst` must not overlap `src`. Throws ParamError for an instruction
/// set this CPU lacks.
void blur_pass_fast(BasicView<const float> src, BasicView<float> dst, const BlurPassOptions& opt,
                    int threads, BlurIsa isa = BlurIsa::best, const FastPassOptions& fast = {});

/// Stages `blur.1` ... `blur.n` of the dense plan in f32 at once (pass k along axes[k - 1]),
/// with blur_pass_fast's bits in every texel (tested), but fused: the image is cut into
/// column strips, and each strip streams through all n passes keeping per pass only the rows
/// the next pass still reads (a ring of about 2 x (16 + 5) rows of the strip), so the image is
/// read and written once instead of n times (blur_fused.cpp). Beyond 16 passes (stage bright
/// counted) they are fused 16 at a time, each group written into one of two images the next
/// reads: memory is bounded by the image's size, not the pass count. Nothing is rounded
/// between passes (f32 storage). With `impl` approx, every pass is blur_pass_approx's instead,
/// with its bits (tested; `kernel` and `subtexel_bits` then only shape the strips);
/// `reference` is `fast` (the same bits).
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

/// One part of a row for finish_fast_parts: `width` RGBA pixels of the scene, the bloom's
/// (texel 0 first; its R, G and B +0 outside `spans`, where it is not read; null: +0
/// throughout), the support's spans relative to the part's first texel (sorted, disjoint), and
/// where the result goes (may be the scene).
struct FinishPart {
  const float* scene = nullptr;
  const float* bloom = nullptr;
  const Span* spans = nullptr;
  std::size_t span_count = 0;
  float* dst = nullptr;
  int width = 0;
};
/// finish_fast over parts of rows that the caller cuts out itself (the boxed blur's boxes, and
/// what lies outside them), on the calling thread, with finish_fast's bits (every value is
/// finished on its own). `table`: finish_fast_table's, or null. Returns the pixels finished
/// from the table.
std::size_t finish_fast_parts(const FinishPart* parts, std::size_t n, float strength,
                              float exposure, float gamma, const float* table,
                              BlurIsa isa = BlurIsa::best);
/// The table of finished binary16 values finish_fast uses for this scene when `outside` of its
/// pixels lie outside the bloom's support (built once, kept between runs), or null where it
/// does not pay.
std::shared_ptr<const std::vector<float>> finish_fast_table(BasicView<const float> scene,
                                                            std::size_t outside, float strength,
                                                            float exposure, float gamma,
                                                            int threads,
                                                            BlurIsa isa = BlurIsa::best);

/// finish_fast's composite, tone map and output over `rows` row segments of `width` RGBA
/// pixels (scene_rows[i], bloom_rows[i], dst_rows[i]; dst may be the scene), on the calling
/// thread, with finish_fast's bits: every value is finished on its own, so a row cut into
/// segments gives what the whole row gives. For the fused blur's sink.
void finish_fast_rows(const float* const* scene_rows, const float* const* bloom_rows,
                      float* const* dst_rows, int rows, int width, float strength,
                      float exposure, float gamma, BlurIsa isa = BlurIsa::best);

}  // namespace bloomref
