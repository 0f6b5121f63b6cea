// The adaptive plan's support through the blur passes (engine/support.h): which texels of each
// pass may differ from +0, from the pass's own tap tables.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <vector>

#include "blur_internal.h"
#include "bloomref/engine/support.h"
#include "bloomref/parallel.h"

namespace bloomref {

using detail::TapTable;
using detail::centre_tap;
using detail::make_taps;

template <class T>
std::size_t nonzero_support(BasicView<const T> img, std::uint8_t* mask, int threads) {
  std::vector<std::size_t> counts(img.height, 0);
  parallel_rows(img.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      std::size_t n = 0;
      for (int x = 0; x < img.width; ++x) {
        const bool nz = rgb_not_plus_zero(img.pixel(x, y));
        mask[std::size_t(y) * img.width + x] = nz;
        n += nz;
      }
      counts[y] = n;
    }
  });
  std::size_t total = 0;
  for (std::size_t n : counts) total += n;
  return total;
}

namespace {

// What blur_support and blur_support_spans read of a pass's tables: along the blur, the range
// of positions each output position's taps read (blur_support's lo, hi); across it, the one or
// two lines each line's lookup reads; and whether they have the shape the spans rely on (ranges whose
// ends never decrease, adjacent lines across).
struct SpanReach {
  std::vector<int> lo, hi, alo, ahi;
  bool shaped = true;
};

template <class T>
SpanReach make_span_reach(bool horizontal, int width, int height, const Kernel& kernel,
                          int bits) {
  const int n_along = horizontal ? width : height;
  const int n_across = horizontal ? height : width;
  SpanReach r;
  const TapTable<T> along = make_taps(n_along, kernel, bits, T());
  r.lo.resize(n_along);
  r.hi.resize(n_along);
  for (int p = 0; p < n_along; ++p) {
    r.lo[p] = n_along;
    r.hi[p] = -1;
    for (int k = 0; k < along.per_position; ++k) {
      const AxisTap<T>& t = along.at(p)[k];
      r.lo[p] = std::min({r.lo[p], t.i0, t.i1});
      r.hi[p] = std::max({r.hi[p], t.i0, t.i1});
    }
  }
  r.alo.resize(n_across);
  r.ahi.resize(n_across);
  for (int i = 0; i < n_across; ++i) {
    const AxisTap<T> a = centre_tap(i, n_across, bits, T());
    r.alo[i] = std::min(a.i0, a.i1);
    r.ahi[i] = std::max(a.i0, a.i1);
  }
  auto shaped = [](const std::vector<int>& l, const std::vector<int>& h, int max_width) {
    for (std::size_t p = 0; p < l.size(); ++p) {
      if (h[p] - l[p] > max_width) return false;
      if (p > 0 && (l[p] < l[p - 1] || h[p] < h[p - 1])) return false;
    }
    return true;
  };
  // Along, the taps are contiguous by construction (make_taps: offsets step by at most a
  // texel); blur_support relies on the same.
  r.shaped = shaped(r.lo, r.hi, n_along) && shaped(r.alo, r.ahi, 1);
  return r;
}

// make_span_reach for a pass, kept between passes and runs (the plan's passes ask for the same
// two): building it is serial work that every pass would otherwise repeat (docs/design.md, "A
// pass's tables are built once and kept").
template <class T>
std::shared_ptr<const SpanReach> span_reach(const BlurPassOptions& opt, int width, int height) {
  static detail::TableMemo<SpanReach> memo;
  return memo.get(detail::TableKey(opt.axis, width, height, *opt.kernel, opt.subtexel_bits,
                                   std::is_same_v<T, double>),
                  [&] {
                    return make_span_reach<T>(opt.axis == Axis::horizontal, width, height,
                                              *opt.kernel, opt.subtexel_bits);
                  });
}

}  // namespace

template <class T>
std::size_t blur_support(const std::uint8_t* in, std::uint8_t* out, int width, int height,
                         const BlurPassOptions& opt, int threads) {
  // Every lookup of output position p along the axis reads texels in [lo(p), hi(p)] (the taps
  // are contiguous), on the lines [alo, ahi] across (one or two): so the output support is a
  // sliding-window OR, computed with prefix counts (horizontal) or row ORs (vertical).
  const bool horizontal = opt.axis == Axis::horizontal;
  const std::shared_ptr<const SpanReach> reach = span_reach<T>(opt, width, height);
  const std::vector<int>&lo = reach->lo, &hi = reach->hi, &alo = reach->alo, &ahi = reach->ahi;
  std::vector<std::size_t> counts(height, 0);
  const std::size_t w = static_cast<std::size_t>(width);
  // Which input rows have a set texel (masks hold 0 or 1): an output row whose lookups read
  // only empty rows is empty, found without reading its texels (the adaptive plan's supports
  // are mostly empty rows: the demo scene at 3840x2160 has 1% of its texels set).
  std::vector<std::uint8_t> row_set(height);
  parallel_rows(height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      row_set[y] = std::memchr(in + std::size_t(y) * w, 1, w) != nullptr;
  });
  parallel_rows(height, threads, [&](int y0, int y1) {
    std::vector<int> prefix(w + 1);
    std::vector<std::uint8_t> row(w);
    // Vertical: per-column counts of set texels over the window [lo[y], hi[y]], slid row by row
    // (lo and hi never decrease), so each output row costs two row updates, not ten.
    std::vector<std::uint32_t> count(horizontal ? 0 : w);
    int win_lo = 0, win_hi = -1;  // rows currently counted
    int win_set = 0;
    for (int y = y0; y < y1; ++y) {
      std::uint8_t* o = out + std::size_t(y) * w;
      std::size_t n = 0;
      if (horizontal) {
        if (!row_set[alo[y]] && !row_set[ahi[y]]) {
          std::fill(o, o + w, 0);
          continue;
        }
        const std::uint8_t* r0 = in + std::size_t(alo[y]) * w;
        const std::uint8_t* r1 = in + std::size_t(ahi[y]) * w;
        for (std::size_t x = 0; x < w; ++x) prefix[x + 1] = prefix[x] + (r0[x] | r1[x]);
        if (prefix[w] == 0) {
          std::fill(o, o + w, 0);
          continue;
        }
        for (std::size_t x = 0; x < w; ++x) {
          o[x] = prefix[hi[x] + 1] - prefix[lo[x]] > 0;
          n += o[x];
        }
      } else {
        // count[] sums the window's set rows only (adding an empty row changes nothing);
        // win_set counts those rows.
        if (lo[y] > win_hi) {  // restart the window (first row of this range, or a gap)
          if (win_set) std::fill(count.begin(), count.end(), 0);
          win_set = 0;
          win_lo = lo[y];
          win_hi = win_lo - 1;
        }
        for (; win_hi < hi[y];) {
          if (!row_set[++win_hi]) continue;
          ++win_set;
          const std::uint8_t* src = in + std::size_t(win_hi) * w;
          for (std::size_t x = 0; x < w; ++x) count[x] += src[x];
        }
        for (; win_lo < lo[y]; ++win_lo) {
          if (!row_set[win_lo]) continue;
          --win_set;
          const std::uint8_t* src = in + std::size_t(win_lo) * w;
          for (std::size_t x = 0; x < w; ++x) count[x] -= src[x];
        }
        if (win_set == 0) {
          std::fill(o, o + w, 0);
          continue;
        }
        for (std::size_t x = 0; x < w; ++x) row[x] = count[x] != 0;
        for (std::size_t x = 0; x < w; ++x) {
          o[x] = row[alo[x]] | row[ahi[x]];
          n += o[x];
        }
      }
      counts[y] = n;
    }
  });
  std::size_t total = 0;
  for (std::size_t n : counts) total += n;
  return total;
}

std::size_t mask_spans(const std::uint8_t* mask, int width, int height, RowSpans& out,
                       int threads, const std::uint8_t* rows) {
  out.resize(height);
  std::vector<std::size_t> counts(height, 0);
  const std::size_t w = static_cast<std::size_t>(width);
  parallel_rows(height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      std::vector<Span>& row = out[y];
      row.clear();
      if (rows && !rows[y]) continue;
      const std::uint8_t* m = mask + std::size_t(y) * w;
      std::size_t x = 0, n = 0;
      // Masks hold 0 or 1: a span starts at the next 1 and ends at the next 0 after it.
      while (x < w) {
        const void* one = std::memchr(m + x, 1, w - x);
        if (!one) break;
        const std::size_t x0 = std::size_t(static_cast<const std::uint8_t*>(one) - m);
        const void* zero = std::memchr(m + x0, 0, w - x0);
        const std::size_t x1 = zero ? std::size_t(static_cast<const std::uint8_t*>(zero) - m) : w;
        row.push_back(Span{int(x0), int(x1)});
        n += x1 - x0;
        x = x1;
      }
      counts[y] = n;
    }
  });
  std::size_t total = 0;
  for (std::size_t n : counts) total += n;
  return total;
}

namespace {

// Spans `in` (sorted by x0) merged where they overlap or touch, into `out` (appended).
void merge_sorted(const std::vector<Span>& in, std::vector<Span>& out) {
  for (const Span& s : in) {
    if (!out.empty() && s.x0 <= out.back().x1) out.back().x1 = std::max(out.back().x1, s.x1);
    else out.push_back(s);
  }
}

// Positions p in [0, n) whose reads [lo[p], hi[p]] meet the set `in` (lo and hi non-decreasing):
// for an input span [s, e), the p with hi[p] >= s and lo[p] <= e - 1, a range found by two
// binary searches. The output ranges come in order; appended to `out`, merged.
void dilate(const std::vector<Span>& in, const std::vector<int>& lo, const std::vector<int>& hi,
            std::vector<Span>& out) {
  for (const Span& s : in) {
    const int p0 = int(std::lower_bound(hi.begin(), hi.end(), s.x0) - hi.begin());
    const int p1 = int(std::upper_bound(lo.begin(), lo.end(), s.x1 - 1) - lo.begin());
    if (p0 >= p1) continue;
    if (!out.empty() && p0 <= out.back().x1) out.back().x1 = std::max(out.back().x1, p1);
    else out.push_back(Span{p0, p1});
  }
}

}  // namespace

template <class T>
std::optional<std::size_t> blur_support_spans(const RowSpans& in, RowSpans& out, int width,
                                              int height, const BlurPassOptions& opt,
                                              int threads) {
  const bool horizontal = opt.axis == Axis::horizontal;
  const std::shared_ptr<const SpanReach> reach = span_reach<T>(opt, width, height);
  if (!reach->shaped) return std::nullopt;
  const std::vector<int>&lo = reach->lo, &hi = reach->hi, &alo = reach->alo, &ahi = reach->ahi;

  out.resize(height);
  std::vector<std::size_t> counts(height, 0);
  parallel_rows(height, threads, [&](int y0, int y1) {
    std::vector<Span> gathered, merged;
    for (int y = y0; y < y1; ++y) {
      std::vector<Span>& o = out[y];
      o.clear();
      gathered.clear();
      merged.clear();
      // The input lines this output row reads: across (horizontal) or along (vertical).
      // Rows equal to the one before them add nothing: a support grown from a few pixels is a
      // union of rectangles, so most of a window's rows are alike.
      const int r0 = horizontal ? alo[y] : lo[y], r1 = horizontal ? ahi[y] : hi[y];
      int distinct = 0, last = -1;
      for (int r = r0; r <= r1; ++r)
        if (!in[r].empty() && (last < 0 || in[r] != in[last])) ++distinct, last = r;
      if (distinct == 0) continue;
      const std::vector<Span>* row = &in[last];
      if (distinct > 1) {
        for (int r = r0, prev = -1; r <= r1; ++r) {
          if (in[r].empty() || (prev >= 0 && in[r] == in[prev])) continue;
          gathered.insert(gathered.end(), in[r].begin(), in[r].end());
          prev = r;
        }
        std::sort(gathered.begin(), gathered.end(),
                  [](const Span& a, const Span& b) { return a.x0 < b.x0; });
        merge_sorted(gathered, merged);
        row = &merged;
      }
      // Then along x: the blur's reach (horizontal) or the lookup across (vertical): at most as
      // many spans (reserved at once: growing each row's vector span by span was a quarter of
      // the adaptive plan's support tracking).
      o.reserve(row->size());
      if (horizontal) dilate(*row, lo, hi, o);
      else dilate(*row, alo, ahi, o);
      std::size_t n = 0;
      for (const Span& s : o) n += std::size_t(s.x1 - s.x0);
      counts[y] = n;
    }
  });
  std::size_t total = 0;
  for (std::size_t n : counts) total += n;
  return total;
}

template <class T>
void BlurSupportTracker::start(BasicView<const T> bright, int threads) {
  mask_.resize(std::size_t(width_) * height_);
  nonzero_support(bright, mask_.data(), threads);
  count_ = mask_spans(mask_.data(), width_, height_, spans_, threads);
}

void BlurSupportTracker::start(std::vector<std::uint8_t>&& support, int threads,
                               const std::uint8_t* rows) {
  mask_ = std::move(support);
  count_ = mask_spans(mask_.data(), width_, height_, spans_, threads, rows);
}

template <class T>
const std::uint8_t* BlurSupportTracker::advance(const BlurPassOptions& opt, int threads) {
  if (!dense_) {
    const std::size_t w = std::size_t(width_);
    const std::optional<std::size_t> n =
        blur_support_spans<T>(spans_, next_, width_, height_, opt, threads);
    if (n) {
      count_ = *n;
    } else {  // tables without the spans' shape: through masks
      std::vector<std::uint8_t> grown(mask_.size());
      count_ = blur_support<T>(mask_.data(), grown.data(), width_, height_, opt, threads);
      mask_spans(grown.data(), width_, height_, next_, threads);
    }
    dense_ = double(count_) > dense_fraction_ * double(width_) * height_;
    if (!dense_) {
      // The mask follows the spans: the old ones cleared, the new ones set.
      parallel_rows(height_, threads, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
          std::uint8_t* m = mask_.data() + std::size_t(y) * w;
          for (const Span& s : spans_[y]) std::memset(m + s.x0, 0, std::size_t(s.x1 - s.x0));
          for (const Span& s : next_[y]) std::memset(m + s.x0, 1, std::size_t(s.x1 - s.x0));
        }
      });
    }
    std::swap(spans_, next_);
  }
  if (dense_) count_ = std::size_t(width_) * height_;
  return dense_ ? nullptr : mask_.data();
}

template void BlurSupportTracker::start<float>(BasicView<const float>, int);
template void BlurSupportTracker::start<double>(BasicView<const double>, int);
template const std::uint8_t* BlurSupportTracker::advance<float>(const BlurPassOptions&, int);
template const std::uint8_t* BlurSupportTracker::advance<double>(const BlurPassOptions&, int);

template std::size_t nonzero_support<float>(BasicView<const float>, std::uint8_t*, int);
template std::size_t nonzero_support<double>(BasicView<const double>, std::uint8_t*, int);
template std::size_t blur_support<float>(const std::uint8_t*, std::uint8_t*, int, int,
                                         const BlurPassOptions&, int);
template std::size_t blur_support<double>(const std::uint8_t*, std::uint8_t*, int, int,
                                          const BlurPassOptions&, int);
template std::optional<std::size_t> blur_support_spans<float>(const RowSpans&, RowSpans&, int,
                                                              int, const BlurPassOptions&, int);
template std::optional<std::size_t> blur_support_spans<double>(const RowSpans&, RowSpans&, int,
                                                               int, const BlurPassOptions&, int);

}  // namespace bloomref
