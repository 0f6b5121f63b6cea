// The adaptive plan's blur of a sparse scene in boxes (engine/boxes.h).
//
// Why: a sparse support spread over the image (StarField.exr: a few hundred bright pixels, the
// last pass's support 8.5% of the texels) still touches most of the pages of two whole-image
// buffers, since a 1000-texel row of RGBA floats is four pages and a star's support crosses one
// or two of them on most rows; a process's first run pays a page fault for each
// (docs/design.md, "A sparse scene is blurred in boxes"). Blurred box by box, in buffers the
// size of the largest box reused from box to box, a run touches a few hundred pages, and the
// passes of one box need no synchronisation with the others: one parallel loop for all the
// passes instead of three per pass.
//
// Why the same bits: the passes compute the tiles blur_pass_fast lists for the adaptive plan's
// supports, with its kernels and tables; a tile only reads the texels within its taps' reach and
// one line either side across, and writes its own texels. A box holds every texel a connected
// group of those tiles reads or writes (over every pass), and no other group reads or writes
// there, so within a box the buffers hold what whole images would: the tiles' values, and +0
// elsewhere (zeroed, and +0 is what the blur gives outside its support). Which tiles a pass is
// cut into changes no texel's value (every schedule has blur_pass's bits).
#include "bloomref/engine/boxes.h"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <mutex>
#include <optional>
#include <utility>

#include "blur_internal.h"
#include "bloomref/image.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"
#include "bloomref/engine/support.h"

namespace bloomref {
namespace {

// Tiles: blur_pass_fast's small tiles for sparse supports (blur_internal.h).
constexpr int kTileAlong = detail::kTileAlongListed;
constexpr int kTileAcrossH = detail::kTileAcrossHListed;
constexpr int kTileAcrossV = detail::kTileAcrossVListed;
// Boxes are unions of cells of kCell x kCell texels: a box's left edge is then a multiple of 8
// texels (128 bytes), so that its rows sit in 64-byte lines as an image's do. (16: StarField.exr's
// boxes cover 20.3% of it, 8: 16.5%.)
constexpr int kCell = 8;
// Floats after a box buffer: the kernels' vector loads may read a few floats past a line's end.
constexpr std::size_t kPad = 64;

}  // namespace

struct PassLayout {
  std::shared_ptr<const detail::PassTables> tables;
  bool horizontal = true;
  int n_along = 0, n_across = 0, tile_across = 0, tiles_along = 0;
  std::vector<int> tiles;  // the tiles the support touches, ascending
  // The support's spans per row (TileJob::row_spans: the vertical pass's; and the inexact
  // lines').
  std::vector<const Span*> span_rows;
  std::vector<int> span_counts;
  // Tile t's output texels along [a0, a1) and across [b0, b1).
  void tile_range(int t, int& a0, int& a1, int& b0, int& b1) const {
    a0 = (t % tiles_along) * kTileAlong;
    a1 = std::min(a0 + kTileAlong, n_along);
    b0 = (t / tiles_along) * tile_across;
    b1 = std::min(b0 + tile_across, n_across);
  }
};

struct BoxedBlurLayout {
  int width = 0, height = 0;
  std::vector<float> weights;  // the kernel's, centre first
  std::vector<RowSpans> supports;
  std::vector<std::size_t> counts;
  std::vector<PassLayout> passes;
  std::vector<Box> boxes;
  std::vector<std::vector<std::vector<int>>> box_tiles;  // [box][pass]: its tiles, ascending
  std::vector<std::size_t> box_work;                     // texels its tiles compute
};

namespace {

// The tiles of a pass that its support touches (blur_pass_fast's listing).
std::vector<int> listed_tiles(const PassLayout& p, const RowSpans& support, int height) {
  const int tiles_across = (p.n_across + p.tile_across - 1) / p.tile_across;
  std::vector<std::uint8_t> touched(std::size_t(p.tiles_along) * tiles_across);
  for (int y = 0; y < height; ++y)
    for (const Span& s : support[std::size_t(y)]) {
      // Horizontal: x runs along, y across; vertical the other way.
      const int step = p.horizontal ? kTileAlong : p.tile_across;
      for (int b = s.x0 / step; b <= (s.x1 - 1) / step; ++b)
        touched[p.horizontal ? std::size_t(y / p.tile_across) * p.tiles_along + b
                             : std::size_t(b) * p.tiles_along + y / kTileAlong] = 1;
    }
  std::vector<int> out;
  for (std::size_t t = 0; t < touched.size(); ++t)
    if (touched[t]) out.push_back(int(t));
  return out;
}

// The texels tile t of pass p reads or writes, as a rectangle [x0, x1) x [y0, y1): along the
// blur its own texels and its taps' reach, across its lines and one either side (an inexact
// line's lookup mixes it with a neighbour).
Box footprint(const PassLayout& p, int t, int width, int height) {
  int a0, a1, b0, b1;
  p.tile_range(t, a0, a1, b0, b1);
  const auto [lo, hi] = p.tables->reach(a0, a1);
  const int along0 = std::min(lo, a0), along1 = std::max(hi + 1, a1);
  const int across0 = b0 - 1, across1 = b1 + 1;
  Box b =
      p.horizontal ? Box{along0, across0, along1, across1} : Box{across0, along0, across1, along1};
  b.x0 = std::max(b.x0, 0);
  b.y0 = std::max(b.y0, 0);
  b.x1 = std::min(b.x1, width);
  b.y1 = std::min(b.y1, height);
  return b;
}

bool overlap(const Box& a, const Box& b) {
  return a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
}

// The boxes of the cells `marked` (gw x gh): the bounding rectangles of its 8-connected groups,
// merged while two overlap; in texels, clipped to the image.
std::vector<Box> cell_boxes(const std::vector<std::uint8_t>& marked, int gw, int gh, int width,
                            int height) {
  std::vector<Box> boxes;
  std::vector<std::uint8_t> seen(marked.size());
  std::vector<int> stack;
  for (int i = 0; i < gw * gh; ++i) {
    if (!marked[std::size_t(i)] || seen[std::size_t(i)]) continue;
    Box b{gw, gh, 0, 0};
    seen[std::size_t(i)] = 1;
    stack.assign(1, i);
    while (!stack.empty()) {
      const int j = stack.back();
      stack.pop_back();
      const int cx = j % gw, cy = j / gw;
      b = {std::min(b.x0, cx), std::min(b.y0, cy), std::max(b.x1, cx + 1), std::max(b.y1, cy + 1)};
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int x = cx + dx, y = cy + dy;
          if (x < 0 || y < 0 || x >= gw || y >= gh) continue;
          const std::size_t k = std::size_t(y) * gw + x;
          if (marked[k] && !seen[k]) {
            seen[k] = 1;
            stack.push_back(int(k));
          }
        }
    }
    boxes.push_back(b);
  }
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < boxes.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < boxes.size() && !merged; ++j)
        if (overlap(boxes[i], boxes[j])) {
          const Box& a = boxes[i];
          const Box& c = boxes[j];
          boxes[i] = {std::min(a.x0, c.x0), std::min(a.y0, c.y0), std::max(a.x1, c.x1),
                      std::max(a.y1, c.y1)};
          boxes.erase(boxes.begin() + std::ptrdiff_t(j));
          merged = true;
        }
  }
  for (Box& b : boxes)
    b = {b.x0 * kCell, b.y0 * kCell, std::min(b.x1 * kCell, width), std::min(b.y1 * kCell, height)};
  return boxes;
}

// Two zeroed buffers for a box's passes: q (stage bright, then the even passes) and p (the odd
// passes), rows `stride` texels apart. Only what an earlier box may have written (`dirty`
// floats from the start) is zeroed again: the rest of a buffer is still zero, most of it never
// written, and its pages are only materialised where a box writes.
struct BoxBuffers {
  PixelBuffer<float> q, p;
  std::size_t dirty = 0;
  // Room for `floats` floats each, zero.
  void reserve(std::size_t floats) {
    if (q.size() >= floats) return;
    q = PixelBuffer<float>(floats);
    p = PixelBuffer<float>(floats);
    for (PixelBuffer<float>* v : {&q, &p})
      zero_lazily(v->data(), v->size() * sizeof(float));
    dirty = 0;
  }
  // Zero over the box's rows (and the padding after them), for the box to write there.
  void prepare(const Box& b, std::ptrdiff_t stride) {
    const std::size_t need = std::size_t(stride) * kChannels * std::size_t(b.y1 - b.y0) + kPad;
    reserve(need);
    for (PixelBuffer<float>* v : {&q, &p})
      std::memset(v->data(), 0, std::min(dirty, need) * sizeof(float));
    dirty = std::max(dirty, need);
  }
};

// The buffers of the boxes run one thread each, kept for the next box.
class BufferPool {
 public:
  std::unique_ptr<BoxBuffers> take() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (free_.empty()) return std::make_unique<BoxBuffers>();
    auto b = std::move(free_.back());
    free_.pop_back();
    return b;
  }
  void give(std::unique_ptr<BoxBuffers> b) {
    std::lock_guard<std::mutex> lock(mutex_);
    free_.push_back(std::move(b));
  }

 private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<BoxBuffers>> free_;
};

}  // namespace

BoxedBlur::BoxedBlur(int width, int height, RowSpans bright_support, const std::vector<Axis>& axes,
                     const Kernel& kernel, int subtexel_bits, double max_fraction, int threads) {
  auto l = std::make_unique<BoxedBlurLayout>();
  l->width = width;
  l->height = height;
  l->weights = kernel.weights_f32;
  const int n = static_cast<int>(axes.size());
  if (n == 0 || width <= 0 || height <= 0 || bright_support.size() != std::size_t(height)) return;
  std::size_t count0 = 0;
  for (const auto& row : bright_support)
    for (const Span& s : row) count0 += std::size_t(s.x1 - s.x0);
  l->supports.push_back(std::move(bright_support));
  l->counts.push_back(count0);
  // The supports pass after pass, and beside them the passes' tables (one per axis), which the
  // tiles' footprints need next.
  std::vector<Axis> distinct;
  for (Axis a : axes)
    if (std::find(distinct.begin(), distinct.end(), a) == distinct.end()) distinct.push_back(a);
  bool shaped = true;  // and small enough
  parallel_rows(1 + int(distinct.size()), threads, [&](int i0, int i1) {
    for (int i = i0; i < i1; ++i) {
      if (i > 0) {
        detail::pass_tables(distinct[std::size_t(i - 1)], width, height, kernel, subtexel_bits);
        continue;
      }
      for (int k = 1; k <= n && shaped; ++k) {
        BlurPassOptions o{axes[std::size_t(k - 1)], &kernel, subtexel_bits};
        RowSpans next;
        const std::optional<std::size_t> c =
            blur_support_spans<float>(l->supports.back(), next, width, height, o, threads);
        // The boxes hold the support: past max_fraction, no need to go on.
        shaped = c.has_value() && double(*c) <= max_fraction * double(width) * double(height);
        if (!shaped) break;
        l->supports.push_back(std::move(next));
        l->counts.push_back(*c);
      }
    }
  });
  if (!shaped) return;

  // Each pass's tiles, and the cells their footprints cover.
  const int gw = (width + kCell - 1) / kCell, gh = (height + kCell - 1) / kCell;
  std::vector<std::uint8_t> marked(std::size_t(gw) * gh);
  for (int k = 1; k <= n; ++k) {
    PassLayout p;
    p.horizontal = axes[std::size_t(k - 1)] == Axis::horizontal;
    p.tables = detail::pass_tables(axes[std::size_t(k - 1)], width, height, kernel, subtexel_bits);
    p.n_along = p.horizontal ? width : height;
    p.n_across = p.horizontal ? height : width;
    p.tile_across = p.horizontal ? kTileAcrossH : kTileAcrossV;
    p.tiles_along = (p.n_along + kTileAlong - 1) / kTileAlong;
    const RowSpans& s = l->supports[std::size_t(k)];
    p.tiles = listed_tiles(p, s, height);
    p.span_rows.resize(std::size_t(height));
    p.span_counts.resize(std::size_t(height));
    for (int y = 0; y < height; ++y) {
      p.span_rows[std::size_t(y)] = s[std::size_t(y)].data();
      p.span_counts[std::size_t(y)] = int(s[std::size_t(y)].size());
    }
    for (int t : p.tiles) {
      const Box f = footprint(p, t, width, height);
      for (int cy = f.y0 / kCell; cy <= (f.y1 - 1) / kCell; ++cy)
        for (int cx = f.x0 / kCell; cx <= (f.x1 - 1) / kCell; ++cx)
          marked[std::size_t(cy) * gw + cx] = 1;
    }
    l->passes.push_back(std::move(p));
  }
  l->boxes = cell_boxes(marked, gw, gh, width, height);
  std::size_t area = 0;
  for (const Box& b : l->boxes) area += b.area();
  if (double(area) > max_fraction * double(width) * double(height)) return;

  // Each tile goes to the box holding its footprint (one box holds all of it).
  std::vector<int> box_of(std::size_t(gw) * gh, -1);
  for (std::size_t i = 0; i < l->boxes.size(); ++i) {
    const Box& b = l->boxes[i];
    for (int cy = b.y0 / kCell; cy < (b.y1 + kCell - 1) / kCell; ++cy)
      for (int cx = b.x0 / kCell; cx < (b.x1 + kCell - 1) / kCell; ++cx)
        box_of[std::size_t(cy) * gw + cx] = int(i);
  }
  l->box_tiles.assign(l->boxes.size(), std::vector<std::vector<int>>(std::size_t(n)));
  l->box_work.assign(l->boxes.size(), 0);
  for (int k = 0; k < n; ++k) {
    const PassLayout& p = l->passes[std::size_t(k)];
    for (int t : p.tiles) {
      int a0, a1, b0, b1;
      p.tile_range(t, a0, a1, b0, b1);
      const int x = p.horizontal ? a0 : b0, y = p.horizontal ? b0 : a0;
      const int i = box_of[std::size_t(y / kCell) * gw + x / kCell];
      l->box_tiles[std::size_t(i)][std::size_t(k)].push_back(t);
      l->box_work[std::size_t(i)] += std::size_t(a1 - a0) * std::size_t(b1 - b0);
    }
  }
  layout_ = std::move(l);
}

BoxedBlur::BoxedBlur() = default;
BoxedBlur::~BoxedBlur() = default;
BoxedBlur::BoxedBlur(BoxedBlur&&) noexcept = default;
BoxedBlur& BoxedBlur::operator=(BoxedBlur&&) noexcept = default;

const std::vector<Box>& BoxedBlur::boxes() const {
  return layout_->boxes;
}
const RowSpans& BoxedBlur::support(int k) const {
  return layout_->supports[std::size_t(k)];
}
std::size_t BoxedBlur::support_count(int k) const {
  return layout_->counts[std::size_t(k)];
}

namespace {

// One run of the boxed blur over a scene: a box's bright image, its passes and the sink.
struct BoxRun {
  const BoxedBlurLayout& l;
  BasicView<const float> scene;
  float threshold;
  const std::uint8_t* bright_rows;
  const BoxedBlur::Sink& sink;
  detail::TileKernel kernel;
  detail::InexactKernels inexact;

  // Pass k + 1 of box bi over its tiles, shared out over `threads`: rows src -> dst.
  void pass(std::size_t bi, std::size_t k, float* const* src, float* const* dst,
            int threads) const {
    const PassLayout& p = l.passes[k];
    const std::vector<int>& tiles = l.box_tiles[bi][k];
    if (tiles.empty()) return;
    detail::TileJob job;
    job.src_rows = src;
    job.dst_rows = dst;
    job.horizontal = p.horizontal;
    job.n_along = p.n_along;
    job.n_across = p.n_across;
    job.tile_along = kTileAlong;
    job.tile_across = p.tile_across;
    job.tiles_along = p.tiles_along;
    detail::set_tables(job, *p.tables);
    job.weights = l.weights.data();
    job.tile_ids = tiles.data();
    job.dst_zero_outside = true;
    if (!p.horizontal) {
      job.row_spans = p.span_rows.data();
      job.row_span_counts = p.span_counts.data();
    }
    job.width = l.width;
    parallel_rows(int(tiles.size()), threads, [&](int i0, int i1) {
      kernel(job, i0, i1);
      for (int i = i0; i < i1; ++i) {
        int a0, a1, b0, b1;
        p.tile_range(tiles[std::size_t(i)], a0, a1, b0, b1);
        detail::blur_inexact_lines(*p.tables, job.src_rows, job.dst_rows, l.weights, a0, a1, b0,
                                   b1, nullptr, l.width, true, 4, 4, inexact, p.span_rows.data(),
                                   p.span_counts.data());
      }
    });
  }

  // One box: stage bright into q, the passes (tiles shared out over `threads`), the sink.
  void box(std::size_t bi, BoxBuffers& buf, int threads) const {
    const Box& b = l.boxes[bi];
    const int bw = b.x1 - b.x0, bh = b.y1 - b.y0;
    const std::ptrdiff_t stride = std::ptrdiff_t((bw + 3) / 4 * 4);
    buf.prepare(b, stride);
    const BasicView<const float> in{bw, bh, scene.stride, scene.pixel(b.x0, b.y0)};
    extract_bright<float>(in, BasicView<float>{bw, bh, stride, buf.q.data()}, threshold,
                          threads, /*dst_zeroed=*/true, nullptr,
                          bright_rows ? bright_rows + b.y0 : nullptr);
    // Image row y of each buffer, texel x at rows[y] + 4 x (rows outside the box: none).
    std::vector<float*> rq(std::size_t(l.height), nullptr), rp(std::size_t(l.height), nullptr);
    for (int y = b.y0; y < b.y1; ++y) {
      const std::ptrdiff_t at = (std::ptrdiff_t(y - b.y0) * stride - b.x0) * kChannels;
      rq[std::size_t(y)] = buf.q.data() + at;
      rp[std::size_t(y)] = buf.p.data() + at;
    }
    for (std::size_t k = 0; k < l.passes.size(); ++k) {
      const bool odd = k % 2 == 0;  // pass k + 1: bright (q) -> p, then back
      pass(bi, k, odd ? rq.data() : rp.data(), odd ? rp.data() : rq.data(), threads);
    }
    const float* last = l.passes.size() % 2 == 1 ? buf.p.data() : buf.q.data();
    std::vector<const float*> rows(static_cast<std::size_t>(bh));
    for (int i = 0; i < bh; ++i)
      rows[std::size_t(i)] = last + std::ptrdiff_t(i) * stride * kChannels;
    sink(b, rows.data());
  }
};

}  // namespace

void BoxedBlur::run(BasicView<const float> scene, float threshold, const std::uint8_t* bright_rows,
                    const Sink& sink, int threads, BlurIsa isa,
                    const std::function<void(int)>& also, int also_items) const {
  const BoxedBlurLayout& l = *layout_;
  if (scene.width != l.width || scene.height != l.height) return;
  const BoxRun run{l, scene, threshold, bright_rows, sink, detail::tile_kernel_for(isa),
                   detail::inexact_kernels_for(isa)};
  const int nthreads = resolve_threads(threads);

  // A box with more than its share of the work runs alone, its tiles on every thread; the
  // others side by side.
  std::size_t total = 0;
  for (std::size_t w : l.box_work) total += w;
  std::vector<std::size_t> small;
  for (std::size_t i = 0; i < l.boxes.size(); ++i) {
    if (nthreads > 1 && l.box_work[i] * std::size_t(2 * nthreads) > total) {
      BoxBuffers own;
      run.box(i, own, nthreads);
    } else {
      small.push_back(i);
    }
  }
  // The largest first, so that the last ones taken are short; then the other work.
  std::sort(small.begin(), small.end(),
            [&](std::size_t a, std::size_t b) { return l.box_work[a] > l.box_work[b]; });
  std::size_t most = 0;
  for (std::size_t i : small) {
    const Box& b = l.boxes[i];
    most = std::max(most, std::size_t((b.x1 - b.x0 + 3) / 4 * 4) * std::size_t(b.y1 - b.y0));
  }
  const int items = int(small.size()) + (also ? also_items : 0);
  std::atomic<int> next{0};
  BufferPool pool;
  parallel_rows(std::min(nthreads, items), threads, [&](int, int) {
    std::unique_ptr<BoxBuffers> buf;
    for (int i = next++; i < items; i = next++) {
      if (i >= int(small.size())) {
        also(i - int(small.size()));
        continue;
      }
      if (!buf) {
        buf = pool.take();
        buf->reserve(most * kChannels + kPad);  // the largest box's, so that it is made once
      }
      run.box(small[std::size_t(i)], *buf, 1);
    }
    if (buf) pool.give(std::move(buf));
  });
}

std::size_t bright_support_spans(BasicView<const float> scene, float threshold,
                                 const std::uint8_t* bright_rows, RowSpans& out, int threads) {
  out.assign(std::size_t(scene.height), {});
  std::vector<std::size_t> counts(std::size_t(scene.height), 0);
  parallel_rows(scene.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      if (bright_rows && !bright_rows[y]) continue;
      std::vector<Span>& row = out[std::size_t(y)];
      std::size_t n = 0;
      for (int x = 0; x < scene.width; ++x) {
        const float* s = scene.pixel(x, y);
        if (!(luminance(s[0], s[1], s[2]) > threshold && rgb_not_plus_zero(s))) continue;
        if (!row.empty() && row.back().x1 == x)
          ++row.back().x1;
        else
          row.push_back({x, x + 1});
        ++n;
      }
      counts[std::size_t(y)] = n;
    }
  });
  std::size_t total = 0;
  for (std::size_t n : counts) total += n;
  return total;
}

RowSpans outside_boxes(const std::vector<Box>& boxes, int width, int height) {
  RowSpans out(std::size_t(std::max(height, 0)));
  std::vector<Span> in;
  for (int y = 0; y < height; ++y) {
    in.clear();
    for (const Box& b : boxes)
      if (y >= b.y0 && y < b.y1) in.push_back({b.x0, b.x1});
    std::sort(in.begin(), in.end(), [](const Span& a, const Span& b) { return a.x0 < b.x0; });
    int x = 0;
    for (const Span& s : in) {
      if (s.x0 > x) out[std::size_t(y)].push_back({x, s.x0});
      x = std::max(x, s.x1);
    }
    if (x < width) out[std::size_t(y)].push_back({x, width});
  }
  return out;
}

}  // namespace bloomref
