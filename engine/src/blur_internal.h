// bloomref engine — the fast blur's shared parts: the per-pass tables built on the reference's
// taps (taps.h), the tile and row kernels' job descriptions, and their per-instruction-set
// dispatch.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <type_traits>
#include <utility>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/simd/isa_namespace.h"
#include "bloomref/exact/taps.h"

namespace bloomref::detail {

/// The small tiles of passes that visit only the tiles their support touches (blur_pass_fast's
/// listed tiles, the boxed blur's): texels along the blur, rows across a horizontal pass,
/// columns across a vertical one. blur_fast.cpp gives the measurements behind them.
constexpr int kTileAlongListed = 8;
constexpr int kTileAcrossHListed = 16;
constexpr int kTileAcrossVListed = 32;

/// How the tile kernel forms a tap's term, in blur_texel's form (p0 w0 [+ p1 w1]) wk: `one` when
/// w0 is exactly 1 and there is no second texel (x * 1 == x: no signalling NaN reaches the blur,
/// stages.h), `scaled` when there is no second texel (kept as the reference's case; the tap
/// tables give w1 = 0 only with w0 = 1 - 0 = 1), `two` otherwise.
enum class TapForm : unsigned char { one, scaled, two };
inline TapForm form_of(const AxisTap<float>& t) {
  return t.w1 != 0.0f ? TapForm::two : t.w0 == 1.0f ? TapForm::one : TapForm::scaled;
}

/// One pass of the fast blur, cut into tiles of `tile_along` x `tile_across` output texels.
/// Tile t covers along-block t % tiles_along and across-block t / tiles_along, so consecutive
/// tiles walk down the same across-block and reuse the rows in cache.
/// Rows are reached through tables of row pointers (image row y at src_rows[y]), so the same
/// kernel reads a whole image or the fused blur's ring buffers (blur_fused.cpp).
struct TileJob {
  const float* const* src_rows = nullptr;
  float* const* dst_rows = nullptr;
  bool horizontal = true;
  int n_along = 0, n_across = 0;
  int tile_along = 0, tile_across = 0, tiles_along = 0;
  /// Only output texels with a in [along_lo, along_hi) and b in [across_lo, across_hi).
  int along_lo = 0, along_hi = 1 << 30, across_lo = 0, across_hi = 1 << 30;
  const AxisTap<float>* taps = nullptr;  ///< n_along x taps_per_position, shader order
  int taps_per_position = 0;
  /// PassTables' per-tap forms and per-position reach and plainness (same layout as `taps`).
  const TapForm* forms = nullptr;
  const int* reach_lo = nullptr;
  const int* reach_hi = nullptr;
  const std::uint8_t* plain = nullptr;
  /// Kernel weights, centre first. Every line is computed as if its lookup across the blur sat
  /// exactly on it; the caller recomputes the lines where it does not.
  const float* weights = nullptr;
  const std::uint8_t* active = nullptr;  ///< optional width x height mask (stages.h)
  /// Optional: the tiles to compute, in order; tiles [t0, t1) of the kernel are then entries
  /// [t0, t1) of this list (the adaptive plan's touched tiles), the others left alone.
  const int* tile_ids = nullptr;
  bool dst_zero_outside = false;  ///< tiles without an active texel are left alone (fast_stages.h)
  /// Optional, with dst_zero_outside and listed tiles, the vertical pass with RGBA rows only: per
  /// output row, the support's spans (sorted, disjoint; row_span_counts of them). Only those
  /// texels of a tile's lines are computed: the others are +0 in the destination already.
  const Span* const* row_spans = nullptr;
  const int* row_span_counts = nullptr;
  int width = 0;
  /// Floats a texel of the source and destination rows: 4 (RGBA; the destination's alpha is
  /// written 1) or 3 (RGB: the fused blur's intermediate rows; a row of 3 is read 8 floats at a
  /// time, so it needs 8 floats of slack after it). 3 only from the fused blur, which gives no
  /// mask (`active`).
  int src_channels = 4, dst_channels = 4;
  /// Whether a vertical pass from rows of 3 to rows of 4 floats may store its output past the
  /// cache (x86 streaming stores, where the destination row is 32-byte aligned): the fused
  /// blur's last pass into an image larger than the last-level cache, which the next pass
  /// could not have found there anyway (the stores then skip reading each line in first).
  bool stream_dst = false;
};

/// Computes tiles [t0, t1) of `job`: every texel of a line whose lookup across the blur is
/// exact is bit-identical to blur_texel. Compiled once per instruction set; the same IEEE operations in every lane.
void blur_tiles_generic(const TileJob& job, int t0, int t1);
void blur_tiles_avx2(const TileJob& job, int t0, int t1);
void blur_tiles_avx512(const TileJob& job, int t0, int t1);  // 64-byte vectors

/// The tile kernel's scratch buffers, made, grown and freed by functions defined in a
/// baseline-ISA file, so that the per-ISA kernels instantiate no std::vector member of their
/// own: an inline function compiled with -mavx2 and not inlined (at -O0, say) is a weak symbol
/// the linker may pick for the whole program, AVX2 code then running on CPUs without it
/// (scripts/check-isa-symbols, a unit test, looks for such symbols).
class TileScratch {
 public:
  TileScratch();
  ~TileScratch();
  TileScratch(const TileScratch&) = delete;
  TileScratch& operator=(const TileScratch&) = delete;
  /// The horizontal pass's transposed input tile, resized to n floats.
  float* local(std::size_t n);
  /// The horizontal pass's output tile, or a converted line, resized to n floats.
  float* tile(std::size_t n);

 private:
  PixelBuffer<float> local_, tile_;
};

/// Whether `isa` means the AVX2 kernels here for the stages other than the blur's tiles (avx2
/// and avx512; best: where this CPU and build have them); throws ParamError for AVX2 or AVX-512
/// where they are not. Shared by every fast stage's dispatch.
bool uses_avx2_stages(BlurIsa isa);
/// `isa` as it runs here: best becomes the widest of avx512, avx2 and generic this CPU and build
/// have; throws ParamError for AVX2 or AVX-512 where they are not.
BlurIsa resolve_isa(BlurIsa isa);

using TileKernel = void (*)(const TileJob&, int, int);
/// The tile kernel for `isa` (best: the widest of AVX-512, AVX2 and generic this CPU and build
/// have); throws ParamError for AVX2 or AVX-512 where they are not.
TileKernel tile_kernel_for(BlurIsa isa);

/// n rounded up to a multiple of m.
constexpr std::size_t round_up(std::size_t n, std::size_t m) { return (n + m - 1) / m * m; }

struct RowTaps;

/// One f32 pass's tables, shared by blur_pass_fast and blur_passes_fused.
struct PassTables {
  bool horizontal = true;
  TapTable<float> along;        ///< the reference taps along the blur (blur_texel's)
  TapTable<float> kernel_taps;  ///< the tile kernel's one-texel form of `along`
  /// From kernel_taps: each tap's form (same layout), and per position along the blur the input
  /// lines its taps reach and whether every tap's form is `one` (the kernel's branch-free lines).
  std::vector<TapForm> forms;
  std::vector<int> reach_lo, reach_hi;
  std::vector<std::uint8_t> plain;
  /// The input lines [first, second] that the positions [a0, a1) along the blur reach.
  std::pair<int, int> reach(int a0, int a1) const {
    int lo = reach_lo[a0], hi = reach_hi[a0];
    for (int a = a0; a < a1; ++a) {
      lo = std::min(lo, reach_lo[a]);
      hi = std::max(hi, reach_hi[a]);
    }
    return {lo, hi};
  }
  std::vector<AxisTap<float>> across;  ///< the lookup across the blur, per line
  std::vector<int> inexact;  ///< lines whose lookup across the blur is not exactly on them
  /// The pass's work per image column, roughly, as prefix sums (column_terms[x1] -
  /// column_terms[x0]: columns [x0, x1)): the terms its texels add, a two-texel tap counted
  /// twice, and every tap of a column whose lookup across mixes two (a vertical pass's inexact
  /// column) twice. The fused blur orders its strips by it.
  std::vector<std::int64_t> column_terms;

  /// The horizontal pass's inexact rows' vector kernel (blur_inexact_group_*) computes
  /// kGroupLanes positions along the blur at once, one lane each: group g is positions
  /// [kGroupLanes g, kGroupLanes (g + 1)). Lane l's tap k reads texel kGroupLanes g + l + e (+ 1 where
  /// `sel`) of a row: its one-texel form (the sample mixed once across the blur) or, where `two`,
  /// that texel and the next at weights w0 and w1 (the 2-D bilinear mix). Built only for a
  /// horizontal pass with inexact rows (the vertical pass's columns: blur_inexact_columns_*).
  /// 16: one 64-byte vector, faster than 8 lanes.
  static constexpr int kGroupLanes = 16;
  struct GroupTap {
    float w0[kGroupLanes], w1[kGroupLanes];  ///< along weights where `two` (0 elsewhere)
    std::int32_t sel[kGroupLanes];           ///< -1: the lane's first texel is e + 1
    std::int32_t two[kGroupLanes];           ///< -1: two texels (TapForm::two), 0: one
    int e = 0;
    std::uint8_t kinds = 0;  ///< GroupKind bits: which lanes occur, so a group skips the rest
  };
  enum GroupKind : std::uint8_t { some_one = 1, some_two = 2, some_sel = 4 };
  std::vector<GroupTap> group_taps;  ///< (n_along / kGroupLanes) x per_position
  /// Whether group g's lanes all fit that form: every tap `one` or `two` with i1 = i0 + 1 and
  /// nonzero weights, each lane's first texel e or e + 1 after its position (not where
  /// clamp-to-edge repeats a texel). Other positions take blur_texel's per-texel path.
  std::vector<std::uint8_t> group_ok;
  /// The horizontal pass's taps for blur_rows_exact_* and blur_row_inexact_* (discrete9 only;
  /// empty otherwise).
  std::shared_ptr<const RowTaps> row_taps;
};
/// The exact horizontal pass along its rows (blur_rows_exact_*): lanes along a row of R, G, B
/// (3 floats a texel), one 16-float vector of it at a time, so that no tile is transposed. Lane
/// l of vector v is float 16 v + l of the row, channel (16 v + l) % 3 of texel (16 v + l) / 3 =
/// a. Its tap k, at offset o = 0, +1, -1, ..., +4, -4 in the shader's order, reads texel
/// a + o - 1 + s (s: bit l of `sel`) at weight w0 and, where bit l of `two` is set, the next
/// texel at weight w1: (p0 w0 + p1 w1) wk, blur_texel's sample_pair; elsewhere w0 is exactly 1
/// and the second product is left out (-0 is added, which changes no value: x 1 + -0 = x), so
/// the term is p0 wk, the tile kernel's `one`. Only vectors whose lanes all fit that form are
/// `ok` (not those whose taps clamp at an edge).
struct RowTaps {
  static constexpr int kLanes = 16;
  static constexpr int kTaps = 9;  ///< discrete9's (other kernels have no row taps)
  /// Tap k's offset in texels, in the shader's order (centre, +1, -1, ..., +4, -4).
  static constexpr int kOffset[kTaps] = {0, 1, -1, 2, -2, 3, -3, 4, -4};
  std::vector<std::uint8_t> ok;      ///< per vector
  PixelBuffer<float> w;  ///< per vector and tap: w0[16], then w1[16] (64-byte aligned)
  std::vector<std::uint32_t> masks;  ///< per vector and tap: sel | two << 16
  /// The least weight of a two-texel lane (1 where there is none): a lookup across the blur at
  /// weights at least m with m * min_weight > 0 makes every 2-D weight nonzero (rounding is
  /// monotonic), as the inexact rows' kernel assumes (blur_row_inexact_avx512).
  float min_weight = 1.0f;
};
RowTaps make_row_taps(const PassTables& t, int width);

inline namespace BLOOMREF_ISA_NAMESPACE {  // instantiated by each row kernel's file
/// f(K, O) for the row kernels' taps in the shader's order, K and O compile-time constants
/// (std::integral_constant): tap K at offset O = RowTaps::kOffset[K], kernel weight (K + 1) / 2.
template <class F, int... K>
inline void each_row_tap(F&& f, std::integer_sequence<int, K...>) {
  (f(std::integral_constant<int, K>{}, std::integral_constant<int, RowTaps::kOffset[K]>{}), ...);
}
template <class F>
inline void each_row_tap(F&& f) {
  each_row_tap(f, std::make_integer_sequence<int, RowTaps::kTaps>{});
}
}  // namespace BLOOMREF_ISA_NAMESPACE

struct RowsExactJob {
  /// Image row y at src_rows[y], texel x at 3 x (a ring) or, with src_channels 4, at 4 x (RGBA:
  /// the vectors of R, G, B are packed from it in registers; vector v reads the row's floats
  /// [16 (u + u / 3), 16 (w + w / 3 + 2)) with u = v - 1, w = v + 1, which the caller keeps
  /// inside the row).
  const float* const* src_rows = nullptr;
  int src_channels = 3;
  float* const* dst_rows = nullptr;
  const RowTaps* taps = nullptr;
  const float* weights = nullptr;  ///< the kernel's, centre first (5)
  int v0 = 0, v1 = 0;              ///< vectors [v0, v1), every one ok
  /// Only the floats [f0, f1) of a row are stored (the strip's columns). Lanes outside them are
  /// computed from whatever their loads find, which must be readable memory, and are not stored.
  /// (Whole vectors would also fit in the fused blur's ring rows, and no pass reads the columns
  /// outside a strip's; the mask keeps that from being a rule the caller must know.)
  int f0 = 0, f1 = 1 << 30;
};
void blur_rows_exact_avx512(const RowsExactJob& job, int r0, int r1);

/// One inexact row of the horizontal pass (its lookup across the blur mixes rows a and b at
/// weights wa, wb, both nonzero) along the row, like blur_rows_exact_avx512: per lane
/// blur_inexact_lines's sums. A one-texel lane's sample is the row mixed across, p_a wa + p_b wb
/// (bilinear_v4 of {i, i, 1, 0}: weights 1 wa and 1 wb); a two-texel lane's, bilinear_v4's four
/// terms in its order ((a0 w0 wa + a1 w1 wa) + b0 w0 wb) + b1 w1 wb. A one-texel lane takes the
/// two-texel form with w0 = 1 and its second texel's products replaced by -0, which changes no
/// value, so both take one sequence of operations. Vectors [v0, v1), every one ok; every 2-D
/// weight must be nonzero (RowTaps::min_weight).
struct RowInexactJob {
  const float* a = nullptr;  ///< row o.i0, texel x at 3 x (a row table's entry), or 4 x
  const float* b = nullptr;  ///< row o.i1
  int src_channels = 3;      ///< as RowsExactJob's
  float* dst = nullptr;
  float wa = 0, wb = 0;  ///< o.w0, o.w1
  const RowTaps* taps = nullptr;
  const float* weights = nullptr;  ///< the kernel's, centre first (5)
  int v0 = 0, v1 = 0;
  int f0 = 0, f1 = 1 << 30;  ///< as RowsExactJob's
};
void blur_row_inexact_avx512(const RowInexactJob& job);
/// The same with AVX2, 8 floats a vector, from rows of 3 floats a texel only (src_channels 3),
/// for the AVX2 build's fused blur (its other rows go through the tile kernel).
void blur_row_inexact_avx2(const RowInexactJob& job);

/// The row kernels for `isa` (as tile_kernel_for), null where it has none: the exact rows'
/// (AVX-512) and the inexact rows' (AVX-512; AVX2, whose other rows take the tile kernel).
/// `exact` and, where `exact` is set, `inexact` take rows of 3 or 4 floats a texel; AVX2's
/// `inexact` alone takes rows of 3 only.
struct RowKernels {
  void (*exact)(const RowsExactJob&, int, int) = nullptr;
  void (*inexact)(const RowInexactJob&) = nullptr;
};
RowKernels row_kernels_for(BlurIsa isa);

PassTables make_pass_tables(Axis axis, int width, int height, const Kernel& k, int bits);
/// make_pass_tables, kept for the last few (axis, size, kernel offsets, bits) asked: the
/// adaptive plan's passes ask for the same two, and building them would otherwise be a serial
/// part of every pass (docs/design.md, "A pass's tables are built once and kept").
std::shared_ptr<const PassTables> pass_tables(Axis axis, int width, int height, const Kernel& k,
                                              int bits);

/// What a pass's tables depend on: the axis, the image's size, the kernel's tap offsets (and
/// count) and the subtexel precision; `f64` for the exact taps. The key of the table memos.
struct TableKey {
  Axis axis;
  int width, height, bits;
  bool f64;
  std::vector<float> offsets_f32;
  std::vector<double> offsets_f64;
  std::size_t weights;
  TableKey(Axis a, int w, int h, const Kernel& k, int b, bool exact)
      : axis(a), width(w), height(h), bits(b), f64(exact), offsets_f32(k.offsets_f32),
        offsets_f64(k.offsets_f64), weights(k.weights_f32.size()) {}
  bool operator==(const TableKey& o) const {
    return axis == o.axis && width == o.width && height == o.height && bits == o.bits &&
           f64 == o.f64 && offsets_f32 == o.offsets_f32 && offsets_f64 == o.offsets_f64 &&
           weights == o.weights;
  }
};

/// A memo of the last kSize tables built, shared by all threads: `get` returns the table for
/// `key`, building it with `make` (outside the lock) when it is not kept.
template <class V>
class TableMemo {
 public:
  template <class Make>
  std::shared_ptr<const V> get(const TableKey& key, const Make& make) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& [k, v] : kept_)
        if (k == key) return v;
    }
    auto v = std::make_shared<const V>(make());
    std::lock_guard<std::mutex> lock(mutex_);
    if (kept_.size() == kSize) kept_.erase(kept_.begin());
    kept_.emplace_back(key, v);
    return v;
  }

 private:
  static constexpr std::size_t kSize = 8;
  std::mutex mutex_;
  std::vector<std::pair<TableKey, std::shared_ptr<const V>>> kept_;
};
/// Points `job`'s tap tables at `t`'s.
void set_tables(TileJob& job, const PassTables& t);

/// Recomputes with blur_texel's bits the texels (a, b) with a in [a0, a1) and
/// b an inexact line in [b0, b1), where the tile kernel's one-line form does not apply; texels
/// outside `active` (optional width x height mask) are (0, 0, 0, 1), written unless
/// `dst_zero_outside` says they already are. Rows are given by pointers (image row y at in[y],
/// `in_channels` floats a texel, 3 or 4; a texel's 16 bytes are read, so a row of 3 needs a
/// float after it); R, G, B are written, and alpha 1 when `out_channels` is 4.
/// `kernels` are the vector kernels (inexact_kernels_for; none: every texel the per-texel way):
/// the horizontal pass's lines take `group` for whole groups of positions, the vertical pass's
/// columns `columns` for all of [a0, a1) at once where it applies. `spans` (optional, with
/// dst_zero_outside; per image row y, span_counts[y] sorted spans: TileJob::row_spans): the
/// support; texels outside it are +0 in the destination already and the per-texel way leaves
/// them alone (the vector kernels compute their groups whole).
using InexactGroupKernel = void (*)(const PassTables& t, const float* const* in,
                                    float* const* out, const float* w, int b, int g0, int g1,
                                    const std::uint8_t* active, int width, bool dst_zero_outside,
                                    int in_channels, int out_channels, TileScratch& scratch);
using InexactColumnsKernel = bool (*)(const PassTables& t, const float* const* in,
                                      float* const* out, const float* w, int a0, int a1,
                                      const int* cols, int ncols, const std::uint8_t* active,
                                      int width, bool dst_zero_outside, int in_channels,
                                      int out_channels, TileScratch& scratch);
struct InexactKernels {
  InexactGroupKernel group = nullptr;
  InexactColumnsKernel columns = nullptr;
};
void blur_inexact_lines(const PassTables& t, const float* const* in, float* const* out,
                        const std::vector<float>& w, int a0, int a1, int b0, int b1,
                        const std::uint8_t* active, int width, bool dst_zero_outside = false,
                        int in_channels = 4, int out_channels = 4, InexactKernels kernels = {},
                        const Span* const* spans = nullptr, const int* span_counts = nullptr);

/// Inexact row b's positions (a horizontal pass) in the groups [g0, g1) whose group_ok is set,
/// blur_texel's bits
/// (the same operations on each lane as blur_inexact_lines's per-texel path), written as that
/// path writes them. Compiled once per instruction set (blur_tiles.inc).
void blur_inexact_group_generic(const PassTables& t, const float* const* in, float* const* out,
                                const float* w, int b, int g0, int g1,
                                const std::uint8_t* active, int width, bool dst_zero_outside,
                                int in_channels, int out_channels, TileScratch& scratch);
void blur_inexact_group_avx2(const PassTables& t, const float* const* in, float* const* out,
                             const float* w, int b, int g0, int g1, const std::uint8_t* active,
                             int width, bool dst_zero_outside, int in_channels, int out_channels,
                             TileScratch& scratch);
/// The vertical pass's inexact columns [cols, cols + ncols) (both across weights nonzero), rows
/// [a0, a1), blur_texel's bits, written as blur_inexact_lines's per-texel path writes them: the
/// columns side by side in vector lanes (R, G, B of each), so that every lane takes the row's
/// taps in the same form. Returns false, having written nothing, where a tap of those rows is
/// neither one texel nor two with nonzero weight products. Compiled once per instruction set.
bool blur_inexact_columns_generic(const PassTables& t, const float* const* in, float* const* out,
                                  const float* w, int a0, int a1, const int* cols, int ncols,
                                  const std::uint8_t* active, int width, bool dst_zero_outside,
                                  int in_channels, int out_channels, TileScratch& scratch);
bool blur_inexact_columns_avx2(const PassTables& t, const float* const* in, float* const* out,
                               const float* w, int a0, int a1, const int* cols, int ncols,
                               const std::uint8_t* active, int width, bool dst_zero_outside,
                               int in_channels, int out_channels, TileScratch& scratch);
void blur_inexact_group_avx512(const PassTables& t, const float* const* in, float* const* out,
                               const float* w, int b, int g0, int g1, const std::uint8_t* active,
                               int width, bool dst_zero_outside, int in_channels,
                               int out_channels, TileScratch& scratch);
bool blur_inexact_columns_avx512(const PassTables& t, const float* const* in, float* const* out,
                                 const float* w, int a0, int a1, const int* cols, int ncols,
                                 const std::uint8_t* active, int width, bool dst_zero_outside,
                                 int in_channels, int out_channels, TileScratch& scratch);
/// The inexact lines' kernels for `isa` (as tile_kernel_for).
InexactKernels inexact_kernels_for(BlurIsa isa);

}  // namespace bloomref::detail

namespace bloomref::detail {

/// One pass of the fast approximate blur (blur_approx.inc), rows [y0, y1) of the output.
struct ApproxJob {
  const float* src = nullptr;
  std::ptrdiff_t src_stride = 0;  ///< floats per row
  float* dst = nullptr;
  std::ptrdiff_t dst_stride = 0;
  int width = 0, height = 0;
  bool horizontal = true;
  const float* weights = nullptr;  ///< centre first, then pairs at +-1, +-2, ... texels (<= 7)
  int n_weights = 0;
  const std::uint8_t* active = nullptr;  ///< optional mask; rows without an active texel are 0
};

void blur_approx_generic(const ApproxJob& job, int y0, int y1);
void blur_approx_avx2_fma(const ApproxJob& job, int y0, int y1);
void blur_approx_avx512(const ApproxJob& job, int y0, int y1);

/// One pass of the fast approximate blur for the fused blur (blur_fused.cpp): output columns
/// [x0, x1) of rows [r0, r1), rows reached through tables (image row y at src_rows[y], texel x
/// at src_rows[y] + x * src_channels, as TileJob's). Every float is ApproxJob's stencil with its
/// operations (so blur_approx_*'s bits in R, G, B); alpha, where the destination has it, is 1.
struct ApproxRowsJob {
  const float* const* src_rows = nullptr;
  float* const* dst_rows = nullptr;
  int src_channels = 4, dst_channels = 4;  ///< 3 (the fused blur's rings) or 4 (RGBA)
  bool horizontal = true;
  int width = 0, height = 0;
  int x0 = 0, x1 = 0;
  const float* weights = nullptr;  ///< as ApproxJob's
  int n_weights = 0;
  /// At least (x1 - x0) * 4 floats: a row's output before it is converted, where the source
  /// and destination texels differ in size (or both are RGBA: alpha is then set to 1).
  float* scratch = nullptr;
  /// Whether the source and destination rows sit alike in 64-byte lines (column x at the same
  /// offset in a line of both), RGB both, each row's line holding column x0 and its line holding
  /// column x1 - 1 theirs to read and write whole: the vertical pass then computes whole lines
  /// (a few floats either side of the columns asked for, from whatever the source holds there,
  /// never read back), its loads and stores never straddling two lines.
  bool whole_lines = false;
  /// Whether a destination of RGBA rows may be stored past the cache (TileJob::stream_dst's
  /// case: the fused blur's last pass into an image larger than the last-level cache).
  bool stream_dst = false;
};
void blur_approx_rows_generic(const ApproxRowsJob& job, int r0, int r1);
void blur_approx_rows_avx2_fma(const ApproxRowsJob& job, int r0, int r1);
void blur_approx_rows_avx512(const ApproxRowsJob& job, int r0, int r1);
/// The approximate blur's kernels for `isa` (best: the widest this CPU and build have); throws
/// ParamError for AVX2 or AVX-512 where they are not.
struct ApproxKernels {
  void (*pass)(const ApproxJob&, int, int);      ///< blur_pass_approx's
  void (*rows)(const ApproxRowsJob&, int, int);  ///< the fused blur's
};
ApproxKernels approx_kernels_for(BlurIsa isa);
/// The approximate blur's weights: discrete9's exact ones rounded once to float, centre first.
const std::vector<float>& approx_weights();

}  // namespace bloomref::detail
