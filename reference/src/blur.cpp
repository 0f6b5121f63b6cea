// Stage blur.k (stages.h). The coordinates of every tap depend on one axis only, so they are
// computed once per pass into tables, with exactly the arithmetic a per-pixel shader would do.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <vector>

#include "blur_internal.h"
#include "simd_lanes.h"
#include "bloomref/parallel.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"

namespace bloomref {
namespace detail {

TapTable<float> make_taps(int n, const Kernel& k, int bits, float) {
  const float d = 1.0f / static_cast<float>(n);  // tex_offset = 1.0 / textureSize
  TapTable<float> t{k.taps(), {}};
  t.taps.reserve(std::size_t(n) * t.per_position);
  for (int x = 0; x < n; ++x) {
    const float uv = texel_centre(x, n);
    t.taps.push_back(gl_axis_tap(uv, n, bits));
    for (std::size_t i = 1; i < k.offsets_f32.size(); ++i) {
      const float step = d * k.offsets_f32[i];
      t.taps.push_back(gl_axis_tap(uv + step, n, bits));
      t.taps.push_back(gl_axis_tap(uv - step, n, bits));
    }
  }
  return t;
}

TapTable<double> make_taps(int n, const Kernel& k, int, double) {
  TapTable<double> t{k.taps(), {}};
  t.taps.reserve(std::size_t(n) * t.per_position);
  for (int x = 0; x < n; ++x) {
    t.taps.push_back(exact_axis_tap(x, n));
    for (std::size_t i = 1; i < k.offsets_f64.size(); ++i) {
      t.taps.push_back(exact_axis_tap(x + k.offsets_f64[i], n));
      t.taps.push_back(exact_axis_tap(x - k.offsets_f64[i], n));
    }
  }
  return t;
}

AxisTap<float> centre_tap(int x, int n, int bits, float) {
  return gl_axis_tap(texel_centre(x, n), n, bits);
}
AxisTap<double> centre_tap(int x, int n, int, double) { return exact_axis_tap(x, n); }

}  // namespace detail

namespace {

using detail::TapTable;
using detail::centre_tap;
using detail::make_taps;

const std::vector<float>& weights(const Kernel& k, float) { return k.weights_f32; }
const std::vector<double>& weights(const Kernel& k, double) { return k.weights_f64; }

// Two texels along one axis, in sample_rgb's order, zero weights left out.
template <class T>
inline void sample_pair(const T* p0, const T* p1, T w0, T w1, T s[3]) {
  if (w0 != T(0)) {
    for (int c = 0; c < 3; ++c) s[c] = w0 * p0[c];
    if (w1 != T(0))
      for (int c = 0; c < 3; ++c) s[c] = s[c] + w1 * p1[c];
  } else {
    for (int c = 0; c < 3; ++c) s[c] = w1 * p1[c];
  }
}

// r = T(c) * w0; r = r + T(+i) * wi; r = r + T(-i) * wi  (the seeds' blur shader).
template <class T, class Sample>
inline void convolve(const std::vector<T>& w, Sample sample, T out[3]) {
  T s[3] = {};  // every entry is written by sample(); the init only quiets -Wuninitialized
  sample(0, s);
  for (int c = 0; c < 3; ++c) out[c] = s[c] * w[0];
  for (std::size_t i = 1; i < w.size(); ++i) {
    for (int side = 0; side < 2; ++side) {
      sample(int(2 * i - 1 + side), s);
      for (int c = 0; c < 3; ++c) out[c] = out[c] + s[c] * w[i];
    }
  }
}

// RGBA as one 4-lane vector (simd_lanes.h: SSE on x86-64, IEEE per lane).
using detail::load;
using v4 = detail::v4f;

// convolve()'s sum of the samples sample(k), four lanes: r = s(0) w0, then r = r + s(k) w(k).
// With N > 0 the weight count is N, known at compile time, and the loop is unrolled.
template <int N, class Sample>
inline v4 sum_samples_v4(const float* w, int n, const Sample& sample) {
  if constexpr (N > 0) n = N;
  v4 r = sample(0) * w[0];
#pragma GCC unroll 8
  for (int i = 1; i < n; ++i) {
    r = r + sample(2 * i - 1) * w[i];
    r = r + sample(2 * i) * w[i];
  }
  return r;
}
template <class Sample>
inline v4 convolve_samples_v4(const std::vector<float>& w, const Sample& sample) {
  if (w.size() == 5) return sum_samples_v4<5>(w.data(), 5, sample);  // discrete9
  return sum_samples_v4<0>(w.data(), int(w.size()), sample);
}

// convolve() with sample_pair(), four lanes at once.
template <class Texel>
inline v4 convolve_v4(const std::vector<float>& w, const AxisTap<float>* taps, Texel texel) {
  return convolve_samples_v4(w, [&](int k) {
    const AxisTap<float>& t = taps[k];
    if (t.w0 != 0.0f) {
      v4 s = load<v4>(texel(t, 0)) * t.w0;
      if (t.w1 != 0.0f) s = s + load<v4>(texel(t, 1)) * t.w1;
      return s;
    }
    return load<v4>(texel(t, 1)) * t.w1;
  });
}

// sample_rgb's 2-D mix of the texels (tx.i0 | tx.i1, ty.i0 | ty.i1), four lanes from each
// texel's address: its four terms in its order (the vertical axis outer), zero-weight terms left
// out. Src gives pixel(x, y): an image view or a row table.
template <class Src>
inline v4 bilinear_v4(const Src& src, const AxisTap<float>& tx, const AxisTap<float>& ty) {
  const float wx[2] = {tx.w0, tx.w1};
  const float wy[2] = {ty.w0, ty.w1};
  const int ix[2] = {tx.i0, tx.i1};
  const int iy[2] = {ty.i0, ty.i1};
  v4 s = {0.0f, 0.0f, 0.0f, 0.0f};
  bool first = true;
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      const float wij = wx[i] * wy[j];
      if (wij == 0.0f) continue;
      const v4 t = load<v4>(src.pixel(ix[i], iy[j]));
      s = first ? t * wij : s + t * wij;
      first = false;
    }
  }
  return s;
}

inline void store_rgb(const v4& rv, float* d, int out_channels) {
  d[0] = rv[0];
  d[1] = rv[1];
  d[2] = rv[2];
  if (out_channels == 4) d[3] = 1.0f;
}

// blur_texel in f32, four lanes from each texel's address (the fourth, alpha or with RGB rows
// the next texel's red, is never written): the same IEEE single
// multiplications and additions in the same order per lane as the scalar path, so the same bits
// (the shader-loop test checks them). Src gives pixel(x, y): an image view or a row table.
template <class Src>
void blur_texel_f32(const Src& src, bool horizontal, const AxisTap<float>* taps,
                    const AxisTap<float>& other, const std::vector<float>& w, float* d,
                    int out_channels = 4) {
  v4 rv;
  if (other.w1 == 0.0f) {
    // The lookup sits on one line across the blur (weight exactly 1 there).
    const int fixed = other.i0;
    rv = convolve_v4(w, taps, [&](const AxisTap<float>& t, int which) {
      const int i = which ? t.i1 : t.i0;
      return horizontal ? src.pixel(i, fixed) : src.pixel(fixed, i);
    });
  } else {
    // It mixes two lines across the blur.
    rv = convolve_samples_v4(w, [&](int k) {
      return horizontal ? bilinear_v4(src, taps[k], other) : bilinear_v4(src, other, taps[k]);
    });
  }
  store_rgb(rv, d, out_channels);
}

struct RowTable {
  const float* const* rows;
  int channels;
  const float* pixel(int x, int y) const { return rows[y] + std::ptrdiff_t(x) * channels; }
};

}  // namespace

namespace detail {

// The texels of lines whose lookup across the blur is off them: blur_texel_f32's sums, with
// each tap whose kernel form is one texel at weight 1 (the tile kernel's `one`) read from a
// line mixed once across the blur instead of mixed anew per tap and per texel.
//
// Why that is the same: such a tap's sample is bilinear_v4 of along-weights {1, 0} (or {0, 1} on
// the next texel, which leaves out the same terms and multiplies by the same products), so it is
// bilinear_v4(i, {i, i, 1, 0}) of its texel i along, whatever the output position; computed once
// per line i, it is that sample's bits. Other taps (two texels along) take bilinear_v4 per texel as
// blur_texel_f32 does, and both lookups (off one line, or on another line: across weights {1, 0})
// are the same bilinear_v4 (convolve_v4's sample_pair on one fixed line is bilinear_v4 with
// across weights {1, 0}: the same terms, each weight times exactly 1).
void blur_inexact_lines(const PassTables& t, const float* const* in, float* const* out,
                        const std::vector<float>& w, int a0, int a1, int b0, int b1,
                        const std::uint8_t* active, int width, bool dst_zero_outside,
                        int in_channels, int out_channels, InexactKernels kernels) {
  if (a0 >= a1) return;
  const RowTable src{in, in_channels};
  const bool h = t.horizontal;
  const int per = t.kernel_taps.per_position;
  constexpr int L = PassTables::kGroupLanes;
  std::vector<v4> mixed;
  TileScratch scratch;
  // Positions [p0, p1) of line b, texel by texel.
  auto per_texel = [&](int b, int p0, int p1) {
    if (p0 >= p1) return;
    const AxisTap<float>& o = t.across[b];
    const auto [lo, hi] = t.reach(p0, p1);
    mixed.resize(std::size_t(hi - lo + 1));
    for (int i = lo; i <= hi; ++i) {
      const AxisTap<float> one{i, i, 1.0f, 0.0f};
      mixed[i - lo] = h ? bilinear_v4(src, one, o) : bilinear_v4(src, o, one);
    }
    for (int a = p0; a < p1; ++a) {
      const int x = h ? a : b, y = h ? b : a;
      float* d = out[y] + std::ptrdiff_t(x) * out_channels;
      if (active && !active[std::size_t(y) * width + x]) {
        if (!dst_zero_outside) fill_zero_texels(d, 1, out_channels);
        continue;
      }
      const AxisTap<float>* kt = t.kernel_taps.at(a);
      const AxisTap<float>* at = t.along.at(a);
      const TapForm* forms = t.forms.data() + std::size_t(a) * per;
      const v4 rv = convolve_samples_v4(w, [&](int k) {
        if (forms[k] == TapForm::one) return mixed[kt[k].i0 - lo];
        return h ? bilinear_v4(src, at[k], o) : bilinear_v4(src, o, at[k]);
      });
      store_rgb(rv, d, out_channels);
    }
  };
  const auto first = std::lower_bound(t.inexact.begin(), t.inexact.end(), b0);
  const auto last = std::lower_bound(first, t.inexact.end(), b1);
  if (!h) {
    // The vertical pass: the columns whose lookup across mixes two (both weights nonzero) side
    // by side in one call of the columns kernel, the others (and all where it declines) per
    // texel.
    std::vector<int> cols;
    for (auto it = first; it != last; ++it) {
      const AxisTap<float>& o = t.across[*it];
      if (kernels.columns && o.w0 != 0.0f && o.w1 != 0.0f) cols.push_back(*it);
      else per_texel(*it, a0, a1);
    }
    if (!cols.empty() &&
        !kernels.columns(t, in, out, w.data(), a0, a1, cols.data(), int(cols.size()), active,
                         width, dst_zero_outside, in_channels, out_channels, scratch))
      for (int b : cols) per_texel(b, a0, a1);
    return;
  }
  // The horizontal pass: the whole groups inside [a0, a1) go to the group kernel where the
  // lookup across mixes two rows (both weights nonzero, as its terms assume) and the group's
  // taps fit its form; the other positions per texel.
  const int g0 = (a0 + L - 1) / L, g1 = a1 / L;
  for (auto it = first; it != last; ++it) {
    const int b = *it;
    const AxisTap<float>& o = t.across[b];
    if (!kernels.group || g0 >= g1 || o.w0 == 0.0f || o.w1 == 0.0f || t.group_ok.empty()) {
      per_texel(b, a0, a1);
      continue;
    }
    kernels.group(t, in, out, w.data(), b, g0, g1, active, width, dst_zero_outside, in_channels,
                  out_channels, scratch);
    int p = a0;  // the first position not yet done
    for (int g = g0; g < g1; ++g) {
      if (!t.group_ok[g]) continue;
      per_texel(b, p, g * L);
      p = (g + 1) * L;
    }
    per_texel(b, p, a1);
  }
}

template <class T>
void blur_texel(BasicView<const T> src, bool horizontal, const AxisTap<T>* taps,
                const AxisTap<T>& other, const std::vector<T>& w, T* d) {
  if constexpr (std::is_same_v<T, float>) {
    blur_texel_f32(src, horizontal, taps, other, w, d);
  } else {
    T r[3];
    if (other.w1 == T(0)) {
      // The lookup sits on one row (column) across the blur: its weight there is exactly 1,
      // so the bilinear weights are the along-axis ones and sample_rgb reduces to this.
      const int fixed = other.i0;
      convolve(w, [&](int k, T s[3]) {
        const AxisTap<T>& t = taps[k];
        const T* p0 = horizontal ? src.pixel(t.i0, fixed) : src.pixel(fixed, t.i0);
        const T* p1 = horizontal ? src.pixel(t.i1, fixed) : src.pixel(fixed, t.i1);
        sample_pair(p0, p1, t.w0, t.w1, s);
      }, r);
    } else {
      convolve(w, [&](int k, T s[3]) {
        if (horizontal) sample_rgb(src, taps[k], other, s);
        else sample_rgb(src, other, taps[k], s);
      }, r);
    }
    d[0] = r[0];
    d[1] = r[1];
    d[2] = r[2];
    d[3] = T(1);
  }
}

template void blur_texel<float>(BasicView<const float>, bool, const AxisTap<float>*,
                                const AxisTap<float>&, const std::vector<float>&, float*);
template void blur_texel<double>(BasicView<const double>, bool,
                                 const AxisTap<double>*, const AxisTap<double>&,
                                 const std::vector<double>&, double*);

}  // namespace detail

template <class T>
void blur_pass(BasicView<const T> src, BasicView<T> dst, const BlurPassOptions& opt,
               int threads) {
  const bool horizontal = opt.axis == Axis::horizontal;
  const int n_along = horizontal ? src.width : src.height;
  const int n_across = horizontal ? src.height : src.width;
  const TapTable<T> along = make_taps(n_along, *opt.kernel, opt.subtexel_bits, T());
  std::vector<AxisTap<T>> across(n_across);
  for (int i = 0; i < n_across; ++i) across[i] = centre_tap(i, n_across, opt.subtexel_bits, T());
  const std::vector<T>& w = weights(*opt.kernel, T());

  parallel_rows(src.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const std::uint8_t* active = opt.active ? opt.active + std::size_t(y) * src.width : nullptr;
      if (active && std::find(active, active + src.width, std::uint8_t(1)) == active + src.width) {
        T* d = dst.row(y);
        for (int x = 0; x < src.width; ++x, d += kChannels) {
          d[0] = d[1] = d[2] = T(0);
          d[3] = T(1);
        }
        continue;
      }
      for (int x = 0; x < src.width; ++x) {
        T* d = dst.pixel(x, y);
        if (active && !active[x]) {
          d[0] = d[1] = d[2] = T(0);
          d[3] = T(1);
          continue;
        }
        detail::blur_texel(src, horizontal, along.at(horizontal ? x : y),
                           across[horizontal ? y : x], w, d);
      }
    }
  });
}

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
// two): building it was a serial 0.4 ms of every pass at 3840x2160.
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
      const int r0 = horizontal ? alo[y] : lo[y], r1 = horizontal ? ahi[y] : hi[y];
      int nonempty = 0, last = -1;
      for (int r = r0; r <= r1; ++r)
        if (!in[r].empty()) ++nonempty, last = r;
      if (nonempty == 0) continue;
      const std::vector<Span>* row = &in[last];
      if (nonempty > 1) {
        for (int r = r0; r <= r1; ++r) gathered.insert(gathered.end(), in[r].begin(), in[r].end());
        std::sort(gathered.begin(), gathered.end(),
                  [](const Span& a, const Span& b) { return a.x0 < b.x0; });
        merge_sorted(gathered, merged);
        row = &merged;
      }
      // Then along x: the blur's reach (horizontal) or the lookup across (vertical).
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

template void blur_pass<float>(BasicView<const float>, BasicView<float>, const BlurPassOptions&,
                               int);
template void blur_pass<double>(BasicView<const double>, BasicView<double>,
                                const BlurPassOptions&, int);

}  // namespace bloomref
