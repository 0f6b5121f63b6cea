// Stages blur.1 ... blur.n at once, the fused way (stages.h: blur_passes_fused).
//
// Pass by pass, the blur reads and writes the whole image n times (3840x2160 RGBA float: 133 MB
// each way, ten times). Here the image is cut into column strips (of equal width, at most 512
// texels), and each strip
// streams through all n passes: pass k keeps only the rows the next pass still reads, in a ring
// of about 2 x (16 + 5) rows of the strip (~0.3 MB), and computes them 16 rows at a time when
// the next pass asks for them. The image is read once and written once; the strips run in
// parallel. The rings hold R, G, B only (every blur writes alpha 1): a quarter less to compute,
// load and store than RGBA in every pass between the first and the last.
//
// Every texel of every pass is computed by the same tile kernel and the same reference texel
// as blur_pass_fast (blur_tiles.inc, blur_inexact_lines), from the same tap tables, so the bits are
// blur_pass_fast's (tests/engine/test_blur_fast.cpp). A strip also computes, in its earlier passes, the
// columns beside it that its later passes read (the horizontal taps' reach, 5 texels per pass),
// a few percent of the work.
//
// blur_bright_fused puts stage bright in front, as pass 0 of every strip: its ring holds
// extract_bright's RGB of the scene (bright_rgb_row, the same sweep), so the dense plan writes
// no bright image at all (it was a 133 MB image faulted in and written by every run at
// 3840x2160, then read once by the blur). Its sink writes the output into the scene in place,
// over the strip's own columns; the columns beside a strip that its bright pass reads belong to
// its neighbours, whose sinks may have overwritten them already, so their bright values are
// taken from the scene before any strip starts (a few percent of the image).
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <numeric>
#include <optional>
#include <vector>

#include "blur_internal.h"
#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"

namespace bloomref {
namespace {

// Rows per chunk: the horizontal kernel's lanes run across rows (its widest group is 16
// texels, AVX2: 8 vectors of 2 texels), so a chunk's height is the length of the horizontal
// passes' lines, over which each line's tap setup is spread: 32 rows spread it enough, where
// 16 are slower and 64 no faster.
constexpr int kChunk = 32;
constexpr int kTileAlongH = 64;     // as blur_pass_fast
constexpr int kTileAcrossV = 1024;  // as blur_pass_fast
// Columns per strip: a pass's ring of ~42 rows x (512 + reach) texels is ~0.3 MB.
constexpr int kStripWidth = 512;
constexpr int kMinStripWidth = 64;
// Floats a texel of the rings (R, G, B), and of slack after a ring (the tile kernel reads rows
// of 3 eight floats at a time, TileJob).
constexpr int kRingChannels = 3;
constexpr int kRingPad = 8;
// Floats of readable slack before and after a pass's ring: the row kernel's vectors at a strip's
// ends read up to 31 floats before the first column of their row that they store (its vectors
// at f - 16, f, f + 16, f a multiple of 16) and after the last. A ring row starts at a multiple
// of 48 floats (16 texels), so at most 16 of those lie before the row's first float or after its
// last; 64 is that with room to spare, and a whole number of cache lines, so that the rows stay
// 64-byte aligned.
constexpr int kRingFront = 64;
constexpr int kRingBack = 64;
constexpr std::size_t kRowAlign = 16;  // floats: a ring row's stride is a multiple of 64 bytes

// The last pass stores its rows past the cache (TileJob::stream_dst) from this output size on:
// twice a 32 MiB last-level cache, so that nothing of such an output would still be in cache
// for the next stage (docs/design.md, "Streaming stores for a large last pass").
constexpr std::size_t kStreamOutBytes = std::size_t(64) << 20;

// One pass's tables (blur_pass_fast's) and, per output row, the input rows it reads. The bright
// pass has no tables (t null): its row y reads the scene's row y.
struct Pass {
  std::shared_ptr<const detail::PassTables> t;  // kept between runs (detail::pass_tables)
  std::vector<int> need_lo, need_hi;
};

Pass bright_pass(int h) {
  Pass p{nullptr, std::vector<int>(h), {}};
  std::iota(p.need_lo.begin(), p.need_lo.end(), 0);
  p.need_hi = p.need_lo;
  return p;
}

// `approx_reach`: the approximate blur's taps, texels +- approx_reach of each (clamped to the
// edge), 0 for the exact blur. The exact tables still give the strips and rings their shape:
// the reach is added to theirs.
Pass make_pass(Axis axis, int w, int h, const Kernel& kernel, int bits, int approx_reach) {
  Pass p{detail::pass_tables(axis, w, h, kernel, bits), {}, {}};
  p.need_lo.resize(h);
  p.need_hi.resize(h);
  for (int y = 0; y < h; ++y) {
    int lo = y, hi = y;
    if (p.t->horizontal) {
      lo = std::min(lo, p.t->across[y].i0);
      hi = std::max(hi, p.t->across[y].i1);
    } else {
      lo = std::max(y - approx_reach, 0);
      hi = std::min(y + approx_reach, h - 1);
      for (int k = 0; k < p.t->along.per_position; ++k) {
        lo = std::min(lo, p.t->along.at(y)[k].i0);
        hi = std::max(hi, p.t->along.at(y)[k].i1);
      }
    }
    p.need_lo[y] = lo;
    p.need_hi[y] = hi;
  }
  return p;
}

// Rows [r0, r1) of one pass read input rows [lo, hi).
struct RowRange {
  int lo, hi;
};
RowRange input_rows(const Pass& p, int r0, int r1) {
  RowRange r{r0, r1};
  for (int y = r0; y < r1; ++y) {
    r.lo = std::min(r.lo, p.need_lo[y]);
    r.hi = std::max(r.hi, p.need_hi[y] + 1);
  }
  return r;
}

// The rows of the ring each intermediate pass needs, found by walking the chunks in order (every
// pass computes every row, chunk by chunk; the same for every strip). Pass k + 1 computing
// chunk [r, r + kChunk) reads pass k's rows [in.lo, in.hi); pass k has then produced rows up to
// the first chunk boundary at or after in.hi. The ring holds that span.
std::vector<int> ring_rows(const std::vector<Pass>& passes, int h) {
  const int n = static_cast<int>(passes.size());
  std::vector<int> ring(n, 0);
  for (int k = 0; k + 1 < n; ++k) {
    int produced = 0;
    for (int r = 0; r < h; r += kChunk) {
      const RowRange in = input_rows(passes[k + 1], r, std::min(r + kChunk, h));
      while (produced < in.hi) produced = std::min(produced + kChunk, h);
      ring[k] = std::max(ring[k], produced - in.lo);
    }
  }
  return ring;
}

// The columns each pass computes for the strip [sx0, sx1): [x0[k], x1[k]), the strip plus what
// later passes read beside it.
struct Columns {
  std::vector<int> x0, x1;
};

Columns strip_columns(const std::vector<Pass>& passes, int sx0, int sx1, int w,
                      int approx_reach) {
  const int n = static_cast<int>(passes.size());
  Columns c{std::vector<int>(n, sx0), std::vector<int>(n, sx1)};
  for (int k = n - 1; k > 0; --k) {
    const detail::PassTables& t = *passes[k].t;
    int lo = c.x0[k], hi = c.x1[k] - 1;
    if (t.horizontal) {
      lo = std::max(lo - approx_reach, 0);
      hi = std::min(hi + approx_reach, w - 1);
    }
    for (int x = c.x0[k]; x < c.x1[k]; ++x) {
      if (t.horizontal) {
        for (int i = 0; i < t.along.per_position; ++i) {
          lo = std::min(lo, t.along.at(x)[i].i0);
          hi = std::max(hi, t.along.at(x)[i].i1);
        }
      } else {
        lo = std::min(lo, t.across[x].i0);
        hi = std::max(hi, t.across[x].i1);
      }
    }
    c.x0[k - 1] = lo;
    c.x1[k - 1] = hi + 1;
  }
  return c;
}

// A strip's work, roughly (PassTables::column_terms over the columns each pass computes). Only
// the order of strips comes from it (the most expensive first, taken from a shared queue):
// strips differ by ~25% at 3840 columns (columns below 2048 have twice the two-texel taps of
// those above, their coordinates' float rounding being finer), and two threads each taking a
// contiguous half left one of them ~20% more to do.
std::int64_t strip_cost(const std::vector<Pass>& passes, const Columns& c) {
  std::int64_t cost = 0;
  for (std::size_t k = 0; k < passes.size(); ++k)
    if (passes[k].t)
      cost += passes[k].t->column_terms[c.x1[k]] - passes[k].t->column_terms[c.x0[k]];
  return cost;
}

// A pointer that reaches `p` at column x0 of a row of `channels` floats a texel: row tables
// index rows by absolute column.
float* shifted(float* p, int x0, int channels = kRingChannels) {
  return reinterpret_cast<float*>(reinterpret_cast<std::uintptr_t>(p) -
                                  std::uintptr_t(x0) * std::uintptr_t(channels) * sizeof(float));
}

// The row kernels' work on the texels [x0, x1) of a horizontal pass: `segments`, runs [v, e) of
// ok vectors (RowTaps) among those holding a float of those texels, and `gaps`, the texels
// [a0, a1) the vectors do not cover whole (the image's edges, a vector's part texels at either
// end of a run), which the tile kernel or the per-texel path computes after them. A source of
// cin = 4 floats a texel (the RGBA image) keeps the kernel's packing loads inside its rows of w
// texels (RowsExactJob); the rings have room around their rows (kRingFront, kRingBack).
using Runs = std::vector<std::pair<int, int>>;
void row_runs(const detail::RowTaps& rt, int x0, int x1, int cin, int w, Runs& segments,
              Runs& gaps) {
  constexpr int L = detail::RowTaps::kLanes;
  const int va = std::max(3 * x0 / L, cin == 4 ? 1 : 0);
  int vb = (3 * x1 + L - 1) / L;
  if (cin == 4)
    while (vb > va && L * (vb + vb / 3 + 2) > 4 * w) --vb;
  segments.clear();
  gaps.clear();
  int done = x0;  // texels before it are covered or in a gap
  for (int v = va; v < vb;) {
    if (!rt.ok[v]) {
      ++v;
      continue;
    }
    int e = v;
    while (e < vb && rt.ok[e]) ++e;
    segments.push_back({v, e});
    const int c0 = std::max(x0, (L * v + 2) / 3), c1 = std::min(x1, (L * e) / 3);  // whole
    if (done < c0) gaps.push_back({done, c0});
    done = std::max(done, c1);
    v = e;
  }
  if (done < x1) gaps.push_back({done, x1});
}

// The kernels a run calls, for one instruction set.
struct FusedKernels {
  detail::TileKernel tile;
  // The exact horizontal passes into rings along their rows (blur_rows_exact_avx512 and, for
  // their inexact rows, blur_row_inexact_avx512), from a ring or the RGBA source, where the CPU
  // has AVX-512F; the tile kernel does the image's edges and the rest, and everything elsewhere.
  // With AVX2 only the inexact rows between rings go along their rows (blur_row_inexact_avx2).
  detail::RowKernels rows;
  detail::InexactKernels inexact;
  // The approximate blur (blur_pass_approx's stencil) in the same strips and rings.
  bool approx;
  void (*approx_rows)(const detail::ApproxRowsJob&, int, int);
  const std::vector<float>* approx_weights;
  int approx_reach;  // make_pass: texels +- approx_reach of each tap, 0 for the exact blur
};

FusedKernels fused_kernels(BlurIsa isa, BlurImpl impl) {
  FusedKernels k;
  k.tile = detail::tile_kernel_for(isa);
  k.rows = detail::row_kernels_for(isa);
  k.inexact = detail::inexact_kernels_for(isa);
  k.approx = impl == BlurImpl::approx;
  k.approx_rows = detail::approx_kernels_for(isa).rows;
  k.approx_weights = &detail::approx_weights();
  k.approx_reach = k.approx ? static_cast<int>(k.approx_weights->size()) - 1 : 0;
  return k;
}

// The column strips of a run and the order they are taken in.
struct Strips {
  int count = 0, width = 0;
  std::vector<Columns> columns;  // what each pass computes for strip si (strip_columns)
  std::vector<int> order;        // the most expensive first (strip_cost)
  int x0(int si) const { return si * width; }
  int x1(int si, int w) const { return std::min(w, (si + 1) * width); }
};

// Strips of equal width, a whole number per thread (3840 columns on two threads: 8 strips of
// 480, not 7 of 512 and one of 256, which left one thread half a strip of work more), at most
// kStripWidth wide, and at least kMinStripWidth where the image allows (narrower strips
// recompute more columns beside them, but a 256-texel-wide image on one thread would leave the
// other idle).
Strips make_strips(const std::vector<Pass>& passes, int w, int nthreads, int approx_reach) {
  Strips s;
  int nstrips = (w + kStripWidth - 1) / kStripWidth;
  nstrips = (nstrips + nthreads - 1) / nthreads * nthreads;
  nstrips = std::max(1, std::min(nstrips, w / kMinStripWidth));
  s.width = (w + nstrips - 1) / nstrips;
  s.count = (w + s.width - 1) / s.width;
  s.columns.resize(s.count);
  std::vector<std::int64_t> cost(s.count);
  for (int si = 0; si < s.count; ++si) {
    s.columns[si] = strip_columns(passes, s.x0(si), s.x1(si, w), w, approx_reach);
    cost[si] = strip_cost(passes, s.columns[si]);
  }
  s.order.resize(s.count);
  std::iota(s.order.begin(), s.order.end(), 0);
  std::stable_sort(s.order.begin(), s.order.end(), [&](int a, int b) { return cost[a] > cost[b]; });
  return s;
}

// blur_bright_fused: the bright values of the columns beside each strip that its bright pass
// reads, taken before any sink writes the scene: strip si's left ones, then its right ones, row
// by row.
struct Beside {
  std::vector<PixelBuffer<float>> values;
  std::vector<int> width;
};

Beside bright_beside(BasicView<const float> scene, const Strips& strips, float threshold,
                     int threads) {
  const int w = scene.width, h = scene.height;
  Beside b{std::vector<PixelBuffer<float>>(strips.count), std::vector<int>(strips.count)};
  parallel_rows(strips.count, threads, [&](int s0, int s1) {
    for (int si = s0; si < s1; ++si) {
      const Columns& c = strips.columns[si];
      const int sx0 = strips.x0(si), sx1 = strips.x1(si, w);
      const int left = sx0 - c.x0[0], right = c.x1[0] - sx1;
      const int bw = left + right;
      b.width[si] = bw;
      if (bw == 0) continue;
      b.values[si] = PixelBuffer<float>(std::size_t(h) * bw * kRingChannels);
      for (int y = 0; y < h; ++y) {
        float* d = b.values[si].data() + std::size_t(y) * bw * kRingChannels;
        detail::bright_rgb_row(scene.row(y) + std::size_t(c.x0[0]) * kChannels, d, left, threshold);
        detail::bright_rgb_row(scene.row(y) + std::size_t(sx1) * kChannels,
                               d + std::size_t(left) * kRingChannels, right, threshold);
      }
    }
  });
  return b;
}

// What every strip of one run shares. With `threshold`, src is the scene and pass 0 is stage
// bright of it (blur_bright_fused); with `sink`, the last pass's rows go to it, not to dst.
struct FusedRun {
  BasicView<const float> src;
  const FusedBlurSink* sink;
  std::optional<float> threshold;
  int w, h;
  int n;  // passes, the bright one included
  FusedKernels kernels;
  std::vector<Pass> passes;
  std::vector<int> ring;  // ring_rows
  const std::vector<float>* weights;
  std::vector<const float*> src_rows;
  std::vector<float*> dst_rows;  // without a sink
  int tiles_h;                   // horizontal tiles per row block
  int chunks;                    // row blocks of kChunk
  bool stream_out;               // TileJob::stream_dst for the last pass
  Strips strips;
  Beside beside;  // blur_bright_fused

  bool bright() const { return threshold.has_value(); }
};

// One worker's strips, taken one by one: pass by pass, chunk by chunk, each pass asking the one
// before it for the rows it reads.
class StripWorker {
 public:
  explicit StripWorker(const FusedRun& run) : r_(run), rings_(run.n) {}

  void run_strip(int si) {
    si_ = si;
    sx0_ = r_.strips.x0(si);
    sx1_ = r_.strips.x1(si, r_.w);
    strip_ = &r_.strips.columns[si];
    out_rows_.assign(r_.n, {});
    bind_rings();
    if (r_.sink) bind_block();
    produced_.assign(r_.n, 0);
    // The approximate kernel's row before it is converted (ApproxRowsJob::scratch): pass 0
    // computes the most columns.
    approx_scratch_ = PixelBuffer<float>(
        r_.kernels.approx ? std::size_t(strip_->x1[0] - strip_->x0[0]) * kChannels : 0);
    ensure(r_.n - 1, r_.h);
    // The strip's block and scratch go with it; the rings stay.
    block_ = PixelBuffer<float>();
    approx_scratch_ = PixelBuffer<float>();
  }

 private:
  // One pass's rows [r0, r1) over columns [x0, x1), from `in` (cin floats a texel) into `out`.
  struct Chunk {
    int k, r0, r1, x0, x1, cin, cout;
    const float* const* in;
    float* const* out;
  };

  // Pass k's output rows for the intermediate passes: a ring (row r in slot r mod ring[k],
  // columns x0[k] ... x1[k] - 1). A worker's rings are kept from strip to strip (grown where a
  // strip needs more): made anew for every strip, ~9 x 0.4 MB would be freed to the system and
  // faulted in again each time.
  void bind_rings() {
    for (int k = 0; k + 1 < r_.n; ++k) {
      // Rows whole 64-byte cache lines apart: the vertical passes' loads of a row start on one
      // and never straddle two (docs/design.md, "Buffers are aligned to cache lines"). The
      // exact passes' rings start at a column that is a multiple of 16, so that float 0 of a
      // row (3 floats a texel) starts a line: the row kernel's vectors are whole lines. The
      // approximate passes' rings all start at pass 0's first column (the widest), so that a
      // column sits at the same place in every ring's 64-byte lines: a vertical pass then reads
      // and writes whole lines (ApproxRowsJob::whole_lines).
      const bool approx = r_.kernels.approx;
      const int first = approx ? strip_->x0[0] : strip_->x0[k] / 16 * 16;
      const int last = approx ? strip_->x1[0] : strip_->x1[k];
      const std::size_t row_floats =
          detail::round_up(std::size_t(last - first) * kRingChannels, kRowAlign);
      const std::size_t floats =
          kRingFront + std::size_t(r_.ring[k]) * row_floats + std::max(kRingPad, kRingBack);
      if (rings_[k].size() < floats) rings_[k] = PixelBuffer<float>(floats);
      out_rows_[k].resize(r_.h);
      for (int r = 0; r < r_.h; ++r)
        out_rows_[k][r] =
            shifted(rings_[k].data() + kRingFront + (r % r_.ring[k]) * row_floats, first);
    }
  }

  // With a sink, the last pass's rows: a block of kChunk rows of the strip (RGBA), row r in
  // slot r mod kChunk (the last pass computes whole blocks from a multiple of kChunk).
  void bind_block() {
    const std::size_t row_floats = std::size_t(sx1_ - sx0_) * kChannels;
    block_ = PixelBuffer<float>(std::size_t(kChunk) * row_floats + kRingPad);
    block_rows_.assign(r_.h, nullptr);
    for (int r = 0; r < r_.h; ++r)
      block_rows_[r] = shifted(block_.data() + (r % kChunk) * row_floats, sx0_, kChannels);
    handed_.assign(kChunk, nullptr);
    for (int i = 0; i < kChunk; ++i) handed_[i] = block_.data() + i * row_floats;
  }

  // Pass k computes its rows up to `upto`, asking pass k - 1 for what each chunk reads.
  void ensure(int k, int upto) {
    while (produced_[k] < upto) {
      const int r0 = produced_[k], r1 = std::min(r0 + kChunk, r_.h);
      if (k > 0) ensure(k - 1, input_rows(r_.passes[k], r0, r1).hi);
      compute_chunk(k, r0, r1);
      if (r_.sink && k + 1 == r_.n) (*r_.sink)(sx0_, sx1_, r0, r1, handed_.data());
      produced_[k] = r1;
    }
  }

  // Rows [r0, r1) of pass k over the strip's columns for that pass.
  void compute_chunk(int k, int r0, int r1) {
    if (r_.bright() && k == 0) return bright_chunk(r0, r1);
    const bool reads_src = k == 0 && !r_.bright();
    Chunk c;
    c.k = k;
    c.r0 = r0;
    c.r1 = r1;
    c.x0 = strip_->x0[k];
    c.x1 = strip_->x1[k];
    c.in = reads_src ? r_.src_rows.data() : out_rows_[k - 1].data();
    c.out = k + 1 < r_.n ? out_rows_[k].data() : r_.sink ? block_rows_.data() : r_.dst_rows.data();
    c.cin = reads_src ? kChannels : kRingChannels;
    c.cout = k + 1 == r_.n ? kChannels : kRingChannels;
    const detail::PassTables& t = *r_.passes[k].t;
    if (r_.kernels.approx) return approx_chunk(t, c);
    if (t.horizontal) return horizontal_chunk(t, c);
    vertical_chunk(t, c);
  }

  // Stage bright of rows [r0, r1): the strip's own columns from the scene (its sink writes them
  // only after this pass has read them: a block of the last pass is computed from rows of this
  // one at and below it), the others from `beside`.
  void bright_chunk(int r0, int r1) {
    const int x0 = strip_->x0[0], left = sx0_ - x0, bw = r_.beside.width[si_];
    for (int r = r0; r < r1; ++r) {
      float* d = out_rows_[0][r] + std::size_t(x0) * kRingChannels;  // column x0
      const float* b = r_.beside.values[si_].data() + std::size_t(r) * bw * kRingChannels;
      std::copy(b, b + std::size_t(left) * kRingChannels, d);
      detail::bright_rgb_row(r_.src.row(r) + std::size_t(sx0_) * kChannels,
                             d + std::size_t(left) * kRingChannels, sx1_ - sx0_, *r_.threshold);
      std::copy(b + std::size_t(left) * kRingChannels, b + std::size_t(bw) * kRingChannels,
                d + std::size_t(left + sx1_ - sx0_) * kRingChannels);
    }
  }

  void approx_chunk(const detail::PassTables& t, const Chunk& c) {
    detail::ApproxRowsJob job;
    job.src_rows = c.in;
    job.dst_rows = c.out;
    job.src_channels = c.cin;
    job.dst_channels = c.cout;
    job.horizontal = t.horizontal;
    job.width = r_.w;
    job.height = r_.h;
    job.x0 = c.x0;
    job.x1 = c.x1;
    job.weights = r_.kernels.approx_weights->data();
    job.n_weights = static_cast<int>(r_.kernels.approx_weights->size());
    job.scratch = approx_scratch_.data();
    job.whole_lines = c.k > 0 && c.k + 1 < r_.n;  // ring to ring
    job.stream_dst = c.k + 1 == r_.n && r_.stream_out;
    r_.kernels.approx_rows(job, c.r0, c.r1);
  }

  detail::TileJob tile_job(const detail::PassTables& t, const Chunk& c) const {
    detail::TileJob job;
    job.src_channels = c.cin;
    job.dst_channels = c.cout;
    job.stream_dst = c.k + 1 == r_.n && !t.horizontal && r_.stream_out;
    job.src_rows = c.in;
    job.dst_rows = c.out;
    job.horizontal = t.horizontal;
    detail::set_tables(job, t);
    job.weights = r_.weights->data();
    job.width = r_.w;
    return job;
  }

  // Along = rows, block r0 / kChunk; across = columns [x0, x1).
  void vertical_chunk(const detail::PassTables& t, const Chunk& c) {
    detail::TileJob job = tile_job(t, c);
    job.n_along = r_.h;
    job.n_across = r_.w;
    job.tile_along = kChunk;
    job.tile_across = kTileAcrossV;
    job.tiles_along = r_.chunks;
    job.across_lo = c.x0;
    job.across_hi = c.x1;
    for (int col = c.x0 / kTileAcrossV; col * kTileAcrossV < c.x1; ++col) {
      const int tile = col * r_.chunks + c.r0 / kChunk;
      r_.kernels.tile(job, tile, tile + 1);
    }
    detail::blur_inexact_lines(t, c.in, c.out, *r_.weights, c.r0, c.r1, c.x0, c.x1, nullptr, r_.w,
                               false, c.cin, c.cout, r_.kernels.inexact);
  }

  // Along = columns [x0, x1); across = rows, this chunk is across-block r0 / kChunk.
  void horizontal_chunk(const detail::PassTables& t, const Chunk& c) {
    detail::TileJob job = tile_job(t, c);
    job.n_along = r_.w;
    job.n_across = r_.h;
    job.tile_along = kTileAlongH;
    job.tile_across = kChunk;
    job.tiles_along = r_.tiles_h;
    job.along_lo = c.x0;
    job.along_hi = c.x1;
    const detail::RowKernels& rk = r_.kernels.rows;
    if (t.row_taps && c.cout == 3 && (rk.exact || (rk.inexact && c.cin == 3)))
      return horizontal_rows(t, c, job);
    tiles(job, c, c.x0, c.x1);
    detail::blur_inexact_lines(t, c.in, c.out, *r_.weights, c.x0, c.x1, c.r0, c.r1, nullptr, r_.w,
                               false, c.cin, c.cout, r_.kernels.inexact);
  }

  // The tile kernel over columns [a0, a1) of the chunk's row block.
  void tiles(detail::TileJob& job, const Chunk& c, int a0, int a1) const {
    if (a0 >= a1) return;
    const int t0 = (c.r0 / kChunk) * r_.tiles_h;
    job.along_lo = a0;
    job.along_hi = a1;
    r_.kernels.tile(job, t0 + a0 / kTileAlongH, t0 + (a1 + kTileAlongH - 1) / kTileAlongH);
  }

  // A row kernel's job over the runs of ok vectors (row_runs): what both kernels share set once.
  template <class Job, class RowKernel>
  void along_rows(Job& job, const Chunk& c, const detail::RowTaps& rt, RowKernel&& kernel) const {
    job.src_channels = c.cin;
    job.taps = &rt;
    job.weights = r_.weights->data();
    job.f0 = 3 * c.x0;
    job.f1 = 3 * c.x1;
    for (const auto& [v, e] : segments_) {
      job.v0 = v;
      job.v1 = e;
      kernel(job);
    }
  }

  // Along the rows where the row kernel's vectors fit (every one that holds a float of the
  // strip's columns [x0, x1) and is ok: away from the image's edges), storing only the floats of
  // those columns; the tile kernel elsewhere, after it (its whole texels over the vectors' part
  // texels). A stored lane reads only the input columns the pass needs (strip_columns); the
  // others read whatever lies beside them, inside the ring's row or its neighbours' or the pads
  // around the ring (kRingFront, kRingBack). The first pass reads the source's RGBA rows, all of
  // whose columns it may read, as far as the kernel's packing loads stay inside them
  // (RowsExactJob).
  void horizontal_rows(const detail::PassTables& t, const Chunk& c, detail::TileJob& job) {
    const detail::RowTaps& rt = *t.row_taps;
    const detail::RowKernels& rk = r_.kernels.rows;
    row_runs(rt, c.x0, c.x1, c.cin, r_.w, segments_, gaps_);
    if (rk.exact) {
      detail::RowsExactJob rj;
      rj.src_rows = c.in;
      rj.dst_rows = c.out;
      along_rows(rj, c, rt, [&](const detail::RowsExactJob& j) { rk.exact(j, c.r0, c.r1); });
      for (const auto& [a0, a1] : gaps_) tiles(job, c, a0, a1);
    } else {
      tiles(job, c, c.x0, c.x1);  // AVX2: only the inexact rows go along their rows
    }
    inexact_rows(t, c);
  }

  // The inexact rows (the kernels above computed them as if exact; leaving them out of those
  // calls gained nothing measurable) along their rows too (blur_row_inexact_avx512 or _avx2),
  // where every 2-D weight is nonzero as its terms assume (weights are >= 0: the least across
  // weight times the least along one), their gaps then per texel; the others all per texel.
  void inexact_rows(const detail::PassTables& t, const Chunk& c) {
    const detail::RowTaps& rt = *t.row_taps;
    const auto first = std::lower_bound(t.inexact.begin(), t.inexact.end(), c.r0);
    for (auto it = first; it != t.inexact.end() && *it < c.r1; ++it) {
      const int b = *it;
      const AxisTap<float>& o = t.across[b];
      if (std::min(o.w0, o.w1) * rt.min_weight == 0.0f) {
        detail::blur_inexact_lines(t, c.in, c.out, *r_.weights, c.x0, c.x1, b, b + 1, nullptr, r_.w,
                                   false, c.cin, c.cout, r_.kernels.inexact);
        continue;
      }
      detail::RowInexactJob ij;
      ij.a = c.in[o.i0];
      ij.b = c.in[o.i1];
      ij.dst = c.out[b];
      ij.wa = o.w0;
      ij.wb = o.w1;
      along_rows(ij, c, rt, r_.kernels.rows.inexact);
      for (const auto& [a0, a1] : gaps_)
        detail::blur_inexact_lines(t, c.in, c.out, *r_.weights, a0, a1, b, b + 1, nullptr, r_.w,
                                   false, c.cin, c.cout, r_.kernels.inexact);
    }
  }

  const FusedRun& r_;
  std::vector<PixelBuffer<float>> rings_;  // kept from strip to strip
  // The strip being computed.
  int si_ = 0, sx0_ = 0, sx1_ = 0;
  const Columns* strip_ = nullptr;
  std::vector<std::vector<float*>> out_rows_;
  PixelBuffer<float> block_;
  std::vector<float*> block_rows_;
  std::vector<const float*> handed_;
  std::vector<int> produced_;
  Runs segments_, gaps_;  // the row kernels', per chunk (row_runs)
  PixelBuffer<float> approx_scratch_;
};

// One group of passes fused: the last pass writes into dst, or (sink given) into a block of
// kChunk rows of the strip handed to the sink as each is done; with `threshold`, src is the
// scene and pass 0 is stage bright of it (blur_bright_fused).
void fused_group(BasicView<const float> src, BasicView<float> dst, const FusedBlurSink* sink,
                 const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                 int threads, BlurIsa isa, BlurImpl impl, std::optional<float> threshold) {
  FusedRun r;
  r.src = src;
  r.sink = sink;
  r.threshold = threshold;
  r.w = src.width;
  r.h = src.height;
  r.n = static_cast<int>(axes.size()) + (r.bright() ? 1 : 0);
  if (axes.empty()) throw ParamError("blur_passes_fused: no passes");
  if (!sink && (dst.width != r.w || dst.height != r.h))
    throw ParamError("blur_passes_fused: source and destination sizes differ");
  r.kernels = fused_kernels(isa, impl);
  if (r.w == 0 || r.h == 0) return;  // nothing to write (and no strip width to divide by)
  const int w = r.w, h = r.h;
  r.passes.reserve(r.n);
  if (r.bright()) r.passes.push_back(bright_pass(h));
  for (Axis a : axes)
    r.passes.push_back(make_pass(a, w, h, kernel, subtexel_bits, r.kernels.approx_reach));
  r.ring = ring_rows(r.passes, h);
  r.weights = &kernel.weights_f32;
  r.src_rows.resize(h);
  r.dst_rows.resize(sink ? 0 : h);
  for (int y = 0; y < h; ++y) {
    r.src_rows[y] = src.row(y);
    if (!sink) r.dst_rows[y] = dst.row(y);
  }
  r.tiles_h = (w + kTileAlongH - 1) / kTileAlongH;
  // (A sink's block stays in cache for it: never streamed.)
  r.stream_out =
      !sink && std::size_t(w) * std::size_t(h) * kChannels * sizeof(float) >= kStreamOutBytes;
  r.chunks = (h + kChunk - 1) / kChunk;
  const int nthreads = resolve_threads(threads);
  r.strips = make_strips(r.passes, w, nthreads, r.kernels.approx_reach);
  if (r.bright()) r.beside = bright_beside(src, r.strips, *threshold, threads);
  std::atomic<int> next{0};
  parallel_rows(std::min(nthreads, r.strips.count), threads, [&](int, int) {
    StripWorker worker(r);
    for (int taken; (taken = next.fetch_add(1)) < r.strips.count;)
      worker.run_strip(r.strips.order[taken]);
  });
}

// The entry points. At most kMaxFusedDepth passes (stage bright included) are fused at once:
// every pass keeps a ring per worker, as wide as its strip plus the reach of the passes after it
// in the group, so a deeper group costs memory in proportion to its depth (1000 passes fused
// at once over 4096x64 held 4.2 GB, the reference blur 27 MB) and recomputes more columns
// beside each strip. Deeper runs are cut into groups, each written whole into one of two
// images that the next group reads (a ring holds the same floats as such an image: the bits do
// not change, tested); the first group starts with stage bright, the last writes into dst or
// the sink. 16 keeps the seeds' ten passes, with bright, in one group.
constexpr int kMaxFusedDepth = 16;

void fused(BasicView<const float> src, BasicView<float> dst, const FusedBlurSink* sink,
           const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits, int threads,
           BlurIsa isa, BlurImpl impl, std::optional<float> threshold = std::nullopt) {
  const std::size_t depth = axes.size() + (threshold ? 1 : 0);
  if (depth <= std::size_t(kMaxFusedDepth) || src.width == 0 || src.height == 0)
    return fused_group(src, dst, sink, axes, kernel, subtexel_bits, threads, isa, impl, threshold);
  Image images[2];
  BasicView<const float> in = src;
  int next = 0;
  for (std::size_t k = 0; k < axes.size();) {
    const std::size_t len =
        std::min(axes.size() - k, std::size_t(kMaxFusedDepth) - (k == 0 && threshold ? 1 : 0));
    const std::vector<Axis> group(axes.begin() + k, axes.begin() + k + len);
    const std::optional<float> bright = k == 0 ? threshold : std::nullopt;
    k += len;
    if (k == axes.size())
      return fused_group(in, dst, sink, group, kernel, subtexel_bits, threads, isa, impl, bright);
    Image& out = images[next];
    if (out.empty()) out = Image::uninitialised(src.width, src.height);  // written whole
    fused_group(in, out.view(), nullptr, group, kernel, subtexel_bits, threads, isa, impl, bright);
    in = out.cview();
    next ^= 1;
  }
}

}  // namespace

void blur_passes_fused(BasicView<const float> src, BasicView<float> dst,
                       const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                       int threads, BlurIsa isa, BlurImpl impl) {
  fused(src, dst, nullptr, axes, kernel, subtexel_bits, threads, isa, impl);
}

void blur_passes_fused(BasicView<const float> src, const FusedBlurSink& sink,
                       const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                       int threads, BlurIsa isa, BlurImpl impl) {
  if (!sink) throw ParamError("blur_passes_fused: no sink");
  fused(src, BasicView<float>{}, &sink, axes, kernel, subtexel_bits, threads, isa, impl);
}

void blur_bright_fused(BasicView<const float> scene, float threshold, const FusedBlurSink& sink,
                       const std::vector<Axis>& axes, const Kernel& kernel, int subtexel_bits,
                       int threads, BlurIsa isa, BlurImpl impl) {
  if (!sink) throw ParamError("blur_bright_fused: no sink");
  fused(scene, BasicView<float>{}, &sink, axes, kernel, subtexel_bits, threads, isa, impl,
        threshold);
}

}  // namespace bloomref
