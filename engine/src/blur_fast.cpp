// Stage blur.k, the fast way (stages.h: blur_pass_fast). Builds the pass's tap tables exactly as
// blur_pass does, hands tiles to the instruction-set kernel (blur_tiles.inc), and recomputes with
// blur_texel's bits (blur_inexact_lines, blur.cpp) the few lines whose lookup across the blur is
// not exactly on one texel line (with GL float coordinates, e.g. 85 of 2160 rows and 102 of 3840
// columns), where the sample is a 2-D bilinear mix of two lines and the kernel's one-line form
// does not apply.
#include <algorithm>
#if defined(__x86_64__)
#include <cpuid.h>
#endif
#include <cstdint>
#include <optional>
#include <vector>

#include "blur_internal.h"
#include "bloomref/engine/scan.h"
#include "bloomref/simd/simd_lanes.h"
#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "bloomref/engine/page_ledger.h"

namespace bloomref {
namespace {

// Tile shape (texels): long along the blur so the tap window's overlap is re-read rarely, narrow
// across so a tile's input lines stay in L1/L2 (the horizontal pass's transposed copy: about
// (64 + 8) x 32 texels x 16 bytes = 36 KiB).
constexpr int kTileAlong = 64;
constexpr int kTileAcrossH = 32;
constexpr int kTileAcrossV = 1024;
constexpr int kTileAcrossVMasked = 128;
// The tiles of passes that visit only the tiles their support's spans touch (the adaptive
// plan's sparse passes), where the support is small: 8 along the blur, 16 rows (horizontal) or
// 32 columns (vertical) across. A small support leaves most of a 64 x 32 / 64 x 128 tile
// empty, so smaller tiles leave more of the empty texels out (docs/design.md, "The support is
// tracked as spans per row").
using detail::kTileAlongListed;
using detail::kTileAcrossHListed;
using detail::kTileAcrossVListed;
// ... while the support is under 1/8 of the image: on larger ones (WideColorGamut.exr, 10-25%
// bright) the small tiles' per-tile work costs more than they leave out.
constexpr std::size_t kSmallTilesBelow = 8;

bool cpu_has_avx2() {
#if defined(__x86_64__) && defined(BLOOMREF_HAVE_AVX2_KERNEL)
  __builtin_cpu_init();
  // F16C from CPUID leaf 1 (ECX bit 29): Clang 14's __builtin_cpu_supports has no "f16c".
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  const bool f16c = __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & bit_F16C);
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && f16c;
#else
  return false;
#endif
}

// AVX-512F for the blur's tile kernels, and AVX2 (+FMA, F16C) for the other fast stages'.
bool cpu_has_avx512() {
#if defined(__x86_64__) && defined(BLOOMREF_HAVE_AVX2_KERNEL)
  return cpu_has_avx2() && __builtin_cpu_supports("avx512f");
#else
  return false;
#endif
}

bool available(BlurIsa isa) {
  if (isa == BlurIsa::avx2) return cpu_has_avx2();
  if (isa == BlurIsa::avx512) return cpu_has_avx512();
  return true;
}

BlurIsa resolve(BlurIsa isa) {
  if (isa == BlurIsa::best) {
    if (cpu_has_avx512()) return BlurIsa::avx512;
    return cpu_has_avx2() ? BlurIsa::avx2 : BlurIsa::generic;
  }
  if (!available(isa))
    throw ParamError(isa == BlurIsa::avx512
                         ? "the AVX-512F kernels are not available on this CPU or build"
                         : "the AVX2 (+FMA, F16C) kernels are not available on this CPU or build");
  return isa;
}

}  // namespace

bool blur_isa_available(BlurIsa isa) { return available(isa); }

std::string blur_isa_name(BlurIsa isa) {
  switch (resolve(isa)) {
    case BlurIsa::avx512: return "avx512";
    case BlurIsa::avx2: return "avx2";
    default: return "generic";
  }
}

namespace detail {

BlurIsa resolve_isa(BlurIsa isa) { return resolve(isa); }

bool uses_avx2_stages(BlurIsa isa) { return resolve(isa) != BlurIsa::generic; }

TileScratch::TileScratch() = default;
TileScratch::~TileScratch() = default;
float* TileScratch::local(std::size_t n) {
  local_.resize(n);
  return local_.data();
}

ScanKernel scan_kernel_for(BlurIsa isa) {
  switch (resolve_isa(isa)) {  // throws for avx2 and avx512 where they are not
#ifdef BLOOMREF_HAVE_AVX2_KERNEL
    case BlurIsa::avx512: return scan_row_avx512;
    case BlurIsa::avx2: return scan_row_avx2;
#endif
    default: return scan_row_generic;
  }
}

float* TileScratch::tile(std::size_t n) {
  tile_.resize(n);
  return tile_.data();
}

TileKernel tile_kernel_for(BlurIsa isa) {
  switch (resolve(isa)) {
    case BlurIsa::avx512: return blur_tiles_avx512;
    case BlurIsa::avx2: return blur_tiles_avx2;
    default: return blur_tiles_generic;
  }
}

RowKernels row_kernels_for(BlurIsa isa) {
  const BlurIsa r = resolve(isa);
  if (r == BlurIsa::avx512) return {blur_rows_exact_avx512, blur_row_inexact_avx512};
  if (r == BlurIsa::avx2) return {nullptr, blur_row_inexact_avx2};
  return {};
}

InexactKernels inexact_kernels_for(BlurIsa isa) {
  const BlurIsa r = resolve(isa);
  if (r == BlurIsa::avx512) return {blur_inexact_group_avx512, blur_inexact_columns_avx512};
  if (r == BlurIsa::avx2) return {blur_inexact_group_avx2, blur_inexact_columns_avx2};
  return {blur_inexact_group_generic, blur_inexact_columns_generic};
}

namespace {

// Tap k of position a as one lane of the kernels that take a position a lane (the inexact rows'
// group kernel, the row kernel): one texel (i0, kernel form `one`), or two, i0 and i0 + 1, at
// nonzero weights w0, w1; nothing where it is neither (`scaled`, or two texels clamped into one).
struct LaneTap {
  int i0;
  bool two;
  float w0, w1;
};
std::optional<LaneTap> lane_tap(const PassTables& t, int a, int k) {
  const std::size_t at = std::size_t(a) * t.kernel_taps.per_position + k;
  if (t.forms[at] == TapForm::one) return LaneTap{t.kernel_taps.taps[at].i0, false, 1.0f, 0.0f};
  const AxisTap<float>& rt = t.along.taps[at];
  if (t.forms[at] == TapForm::two && rt.i1 == rt.i0 + 1 && rt.w0 != 0.0f && rt.w1 != 0.0f)
    return LaneTap{rt.i0, true, rt.w0, rt.w1};
  return std::nullopt;
}

// PassTables::group_taps and group_ok from the kernel's taps (one-texel form) and the reference
// taps (two texels).
void make_group_taps(PassTables& t) {
  constexpr int L = PassTables::kGroupLanes;
  const int per = t.kernel_taps.per_position;
  const int groups = int(t.reach_lo.size()) / L;
  t.group_taps.assign(std::size_t(groups) * per, {});
  t.group_ok.assign(groups, 1);
  for (int g = 0; g < groups; ++g) {
    for (int k = 0; k < per; ++k) {
      PassTables::GroupTap& q = t.group_taps[std::size_t(g) * per + k];
      int d[L];
      for (int l = 0; l < L; ++l) {
        const int a = g * L + l;
        const std::optional<LaneTap> lt = lane_tap(t, a, k);
        q.w0[l] = q.w1[l] = 0.0f;
        q.two[l] = 0;
        d[l] = lt ? lt->i0 - a : 0;
        if (!lt) {
          t.group_ok[g] = 0;
        } else if (!lt->two) {
          q.kinds |= PassTables::some_one;
        } else {
          q.w0[l] = lt->w0;
          q.w1[l] = lt->w1;
          q.two[l] = -1;
          q.kinds |= PassTables::some_two;
        }
      }
      q.e = *std::min_element(d, d + L);
      for (int l = 0; l < L; ++l) {
        if (d[l] - q.e > 1) t.group_ok[g] = 0;  // clamp-to-edge repeats texels
        q.sel[l] = d[l] == q.e ? 0 : -1;
        if (q.sel[l]) q.kinds |= PassTables::some_sel;
      }
    }
  }
}

// Whether lane l of vector v fits the row kernel (RowTaps), its weights and mask bits set.
bool fill_row_lane(const PassTables& t, int width, int v, int l, RowTaps& r) {
  constexpr int L = RowTaps::kLanes, K = RowTaps::kTaps;
  const int a = (v * L + l) / 3;
  if (a < 5 || a > width - 6) return false;  // a tap reads a texel past an edge
  for (int k = 0; k < K; ++k) {
    const std::optional<LaneTap> lt = lane_tap(t, a, k);
    const int d = lt ? lt->i0 - (a + RowTaps::kOffset[k]) : 1;
    if (d != 0 && d != -1) return false;
    float* w = r.w.data() + (std::size_t(v) * K + k) * 2 * L;
    std::uint32_t& m = r.masks[std::size_t(v) * K + k];
    w[l] = lt->w0;
    w[L + l] = lt->w1;
    if (lt->two) {
      m |= std::uint32_t(1) << (16 + l);
      r.min_weight = std::min({r.min_weight, lt->w0, lt->w1});
    }
    if (d == 0) m |= std::uint32_t(1) << l;
  }
  return true;
}

}  // namespace

RowTaps make_row_taps(const PassTables& t, int width) {
  constexpr int L = RowTaps::kLanes, K = RowTaps::kTaps;
  const std::size_t vectors = (std::size_t(width) * 3 + L - 1) / L;
  RowTaps r;
  r.ok.assign(vectors, 0);
  r.w.assign(vectors * K * 2 * L, 0.0f);
  r.masks.assign(vectors * K, 0);
  for (int v = 0; v < int(vectors); ++v) {
    bool ok = true;
    for (int l = 0; l < L && ok; ++l) ok = fill_row_lane(t, width, v, l, r);
    r.ok[v] = ok;
  }
  return r;
}

PassTables make_pass_tables(Axis axis, int width, int height, const Kernel& k, int bits) {
  PassTables t;
  t.horizontal = axis == Axis::horizontal;
  const int n_along = t.horizontal ? width : height;
  const int n_across = t.horizontal ? height : width;
  t.along = make_taps(n_along, k, bits, float());
  // The kernel's one-texel form is texel i0 times w0. A tap a hair left of texel 0's centre
  // (u = -2.98e-8 at x = 1, offset 1 of 1920 columns) has a = u - floor(u) rounded up to 1, so
  // w0 = 0 and the reference takes texel i1 times w1 alone: say that in the one-texel form.
  t.kernel_taps = t.along;
  for (AxisTap<float>& tap : t.kernel_taps.taps)
    if (tap.w0 == 0.0f) tap = {tap.i1, tap.i1, tap.w1, 0.0f};
  const int per = t.kernel_taps.per_position;
  t.forms.resize(t.kernel_taps.taps.size());
  t.reach_lo.assign(n_along, 0);
  t.reach_hi.assign(n_along, 0);
  t.plain.assign(n_along, 1);
  for (int a = 0; a < n_along; ++a) {
    const AxisTap<float>* at = t.kernel_taps.at(a);
    int lo = at[0].i0, hi = at[0].i1;
    for (int i = 0; i < per; ++i) {
      lo = std::min(lo, at[i].i0);
      hi = std::max(hi, at[i].i1);
      const TapForm f = form_of(at[i]);
      t.forms[std::size_t(a) * per + i] = f;
      if (f != TapForm::one) t.plain[a] = 0;
    }
    t.reach_lo[a] = lo;
    t.reach_hi[a] = hi;
  }
  // Lines whose lookup across the blur is not exactly line b (weight 1).
  t.across.resize(n_across);
  for (int b = 0; b < n_across; ++b) {
    t.across[b] = centre_tap(b, n_across, bits, float());
    if (t.across[b].w1 != 0.0f || t.across[b].i0 != b) t.inexact.push_back(b);
  }
  if (t.horizontal && !t.inexact.empty()) make_group_taps(t);  // the vertical pass: columns
  if (t.horizontal && per == RowTaps::kTaps)
    t.row_taps = std::make_shared<const RowTaps>(make_row_taps(t, width));
  t.column_terms.assign(std::size_t(width) + 1, 0);
  for (int x = 0; x < width; ++x) {
    std::int64_t terms = 0;
    if (t.horizontal) {
      for (int i = 0; i < per; ++i)
        terms += t.forms[std::size_t(x) * per + i] == TapForm::two ? 2 : 1;
    } else {
      terms = t.across[x].w1 != 0.0f ? 2 * per : per;
    }
    t.column_terms[x + 1] = t.column_terms[x] + terms;
  }
  return t;
}

std::shared_ptr<const PassTables> pass_tables(Axis axis, int width, int height, const Kernel& k,
                                              int bits) {
  static TableMemo<PassTables> memo;
  return memo.get(TableKey(axis, width, height, k, bits, false),
                  [&] { return make_pass_tables(axis, width, height, k, bits); });
}

void set_tables(TileJob& job, const PassTables& t) {
  job.taps = t.kernel_taps.taps.data();
  job.taps_per_position = t.kernel_taps.per_position;
  job.forms = t.forms.data();
  job.reach_lo = t.reach_lo.data();
  job.reach_hi = t.reach_hi.data();
  job.plain = t.plain.data();
}

}  // namespace detail

namespace {

// Marks in the ledgers what the listed tiles read of src (along: the taps' reach; across: the
// tile's lines and the other lines the inexact lines' lookups weight) and write of dst, and
// faults the pages marked for the first time in. A sparse adaptive blur into zeroed
// buffers otherwise reads pages no pass wrote yet (the zero page) and writes them a pass later
// (a copy-on-write fault and a TLB flush on every CPU), which a process's first run pays for
// (docs/design.md, "Nothing is written where nothing is").
void populate_tile_pages(const detail::TileJob& job,
                         const std::shared_ptr<const detail::PassTables>& tables,
                         const std::vector<int>& listed, std::size_t grid,
                         BasicView<const float> src, BasicView<float> dst,
                         const FastPassOptions& opt, int threads) {
  using detail::PageLedger;
  const detail::PassTables& t = *tables;
  // Texels [x0, x1) of rows [y0, y1).
  auto mark = [](PageLedger* ledger, const float* row0, std::size_t stride, int x0, int x1,
                 int y0, int y1) {
    if (!ledger || x0 >= x1) return;
    for (int y = y0; y < y1; ++y)
      ledger->mark(row0 + std::size_t(y) * stride + std::size_t(x0) * kChannels,
                   std::size_t(x1 - x0) * kChannels * sizeof(float));
  };
  const std::size_t ss = std::size_t(src.stride) * kChannels,
                    ds = std::size_t(dst.stride) * kChannels;
  // A tile's reads and writes depend on the pass tables and the tile grid only: each ledger
  // marks them once per tile, so later runs of the same scene mark nothing instead of walking
  // every tile again. A family is the tables (held by the ledger, so their address is not
  // reused), read or written, and the grid's tile size (small or not); `grid` tiles in all.
  const int small = job.tile_along == kTileAlongListed;
  for (int id : listed) {
    PageLedger* read = opt.src_pages && opt.src_pages->first_visit(tables, small, id, grid)
                           ? opt.src_pages : nullptr;
    PageLedger* written = opt.dst_pages && opt.dst_pages->first_visit(tables, 2 + small, id, grid)
                              ? opt.dst_pages : nullptr;
    if (!read && !written) continue;
    const int a0 = (id % job.tiles_along) * job.tile_along;
    const int a1 = std::min(a0 + job.tile_along, job.n_along);
    const int b0 = (id / job.tiles_along) * job.tile_across;
    const int b1 = std::min(b0 + job.tile_across, job.n_across);
    const auto [lo, hi] = t.reach(a0, a1);
    int across_lo = b0, across_hi = b1 - 1;
    for (int b = b0; b < b1; ++b) {
      const AxisTap<float>& o = t.across[b];
      if (o.w0 != 0.0f) across_lo = std::min(across_lo, o.i0);
      if (o.w1 != 0.0f) across_hi = std::max(across_hi, o.i1);
    }
    if (job.horizontal) {
      mark(read, src.data, ss, lo, hi + 1, across_lo, across_hi + 1);
      mark(written, dst.data, ds, a0, a1, b0, b1);
    } else {
      mark(read, src.data, ss, across_lo, across_hi + 1, lo, hi + 1);
      mark(written, dst.data, ds, b0, b1, a0, a1);
    }
  }
  const int page_threads = opt.page_threads ? opt.page_threads : threads;
  if (opt.src_pages) opt.src_pages->populate(page_threads);
  if (opt.dst_pages) opt.dst_pages->populate(page_threads);
}

}  // namespace

void blur_pass_fast(BasicView<const float> src, BasicView<float> dst, const BlurPassOptions& opt,
                    int threads, BlurIsa isa, const FastPassOptions& fast) {
  const detail::TileKernel kernel = detail::tile_kernel_for(isa);
  const detail::InexactKernels inexact_kernels = detail::inexact_kernels_for(isa);
  const std::shared_ptr<const detail::PassTables> kept =
      detail::pass_tables(opt.axis, src.width, src.height, *opt.kernel, opt.subtexel_bits);
  const detail::PassTables& tables = *kept;
  const bool horizontal = tables.horizontal;
  const int n_along = horizontal ? src.width : src.height;
  const int n_across = horizontal ? src.height : src.width;

  std::vector<const float*> src_rows(src.height);
  std::vector<float*> dst_rows(dst.height);
  for (int y = 0; y < src.height; ++y) src_rows[y] = src.row(y);
  for (int y = 0; y < dst.height; ++y) dst_rows[y] = dst.row(y);
  detail::TileJob job;
  job.src_rows = src_rows.data();
  job.dst_rows = dst_rows.data();
  job.horizontal = horizontal;
  job.n_along = n_along;
  job.n_across = n_across;
  // With the support's spans and nothing to write outside it, only the tiles the spans touch are
  // visited (below), and small tiles follow a sparse support more closely.
  const bool listing = opt.active && fast.active_spans && fast.dst_zero_outside;
  std::size_t support = 0;
  if (listing)
    for (const std::vector<Span>& row : *fast.active_spans)
      for (const Span& sp : row) support += std::size_t(sp.x1 - sp.x0);
  const bool small_tiles =
      listing && support * kSmallTilesBelow < std::size_t(src.width) * std::size_t(src.height);
  job.tile_along = small_tiles ? kTileAlongListed : kTileAlong;
  // With a mask, narrower vertical tiles: more of them can be left out whole.
  job.tile_across = horizontal   ? (small_tiles ? kTileAcrossHListed : kTileAcrossH)
                    : small_tiles ? kTileAcrossVListed
                    : opt.active  ? kTileAcrossVMasked
                                  : kTileAcrossV;
  job.tiles_along = (n_along + job.tile_along - 1) / job.tile_along;
  detail::set_tables(job, tables);
  const std::vector<float>& w = opt.kernel->weights_f32;
  job.weights = w.data();
  job.active = opt.active;
  job.dst_zero_outside = opt.active && fast.dst_zero_outside;
  job.width = src.width;
  const int tiles_across = (n_across + job.tile_across - 1) / job.tile_across;

  // With the support's spans, and nothing to write outside it: only the tiles the spans touch,
  // listed in tile order, without reading the mask (the demo scene at 3840x2160 touches a few
  // percent of them), and shared out between the threads by count.
  std::vector<int> listed;
  std::vector<const Span*> span_rows;
  std::vector<int> span_counts;
  if (listing) {
    std::vector<std::uint8_t> touched(std::size_t(job.tiles_along) * tiles_across);
    for (int y = 0; y < src.height; ++y) {
      for (const Span& s : (*fast.active_spans)[y]) {
        // Horizontal: x runs along (blocks of tile_along), y across; vertical the other way.
        const int block = horizontal ? s.x0 / job.tile_along : s.x0 / job.tile_across;
        const int last = horizontal ? (s.x1 - 1) / job.tile_along : (s.x1 - 1) / job.tile_across;
        for (int b = block; b <= last; ++b) {
          const std::size_t t = horizontal
                                    ? std::size_t(y / job.tile_across) * job.tiles_along + b
                                    : std::size_t(b) * job.tiles_along + y / job.tile_along;
          touched[t] = 1;
        }
      }
    }
    for (std::size_t t = 0; t < touched.size(); ++t)
      if (touched[t]) listed.push_back(int(t));
    job.tile_ids = listed.data();
    if (!horizontal) {
      // The vertical pass's lines are image rows: each computes only its spans.
      span_rows.resize(std::size_t(src.height));
      span_counts.resize(std::size_t(src.height));
      for (int y = 0; y < src.height; ++y) {
        span_rows[std::size_t(y)] = (*fast.active_spans)[std::size_t(y)].data();
        span_counts[std::size_t(y)] = int((*fast.active_spans)[std::size_t(y)].size());
      }
      job.row_spans = span_rows.data();
      job.row_span_counts = span_counts.data();
    }
    if (fast.src_pages || fast.dst_pages)
      populate_tile_pages(job, kept, listed, touched.size(), src, dst, fast, threads);
  }
  const int n_tiles = job.tile_ids ? int(listed.size()) : job.tiles_along * tiles_across;

  parallel_rows(n_tiles, threads, [&](int i0, int i1) {
    kernel(job, i0, i1);
    // The inexact lines inside these tiles, the reference way.
    for (int i = i0; i < i1; ++i) {
      const int t = job.tile_ids ? job.tile_ids[i] : i;
      const int a0 = (t % job.tiles_along) * job.tile_along;
      const int b0 = (t / job.tiles_along) * job.tile_across;
      detail::blur_inexact_lines(tables, src_rows.data(), dst_rows.data(), w, a0,
                                 std::min(a0 + job.tile_along, n_along), b0,
                                 std::min(b0 + job.tile_across, n_across), opt.active, src.width,
                                 job.dst_zero_outside, 4, 4, inexact_kernels);
    }
  });
}

namespace detail {

const std::vector<float>& approx_weights() {
  // Both kernels' exact sampling is this stencil (tests: "linear5 equals discrete9 with exact
  // sampling"); the exact rational weights rounded once to float.
  static const std::vector<float> w(kernel_discrete9().weights_f64.begin(),
                                    kernel_discrete9().weights_f64.end());
  return w;
}

ApproxKernels approx_kernels_for(BlurIsa isa) {
  switch (resolve(isa)) {
    case BlurIsa::avx512: return {blur_approx_avx512, blur_approx_rows_avx512};
    case BlurIsa::avx2: return {blur_approx_avx2_fma, blur_approx_rows_avx2_fma};
    default: return {blur_approx_generic, blur_approx_rows_generic};
  }
}

}  // namespace detail

void blur_pass_approx(BasicView<const float> src, BasicView<float> dst,
                      const BlurPassOptions& opt, int threads, BlurIsa isa) {
  const auto kernel = detail::approx_kernels_for(isa).pass;
  const std::vector<float>& w = detail::approx_weights();
  detail::ApproxJob job;
  job.src = src.data;
  job.src_stride = src.stride * kChannels;
  job.dst = dst.data;
  job.dst_stride = dst.stride * kChannels;
  job.width = src.width;
  job.height = src.height;
  job.horizontal = opt.axis == Axis::horizontal;
  job.weights = w.data();
  job.n_weights = static_cast<int>(w.size());
  job.active = opt.active;
  parallel_rows(src.height, threads, [&](int y0, int y1) { kernel(job, y0, y1); });
}

}  // namespace bloomref
