// BlurTaps (window_sums.h): window statistics in two passes over a band's rows, then their
// weighted sums over the taps.
#include "window_sums.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace bloomref::parity::detail {
namespace {

// A NaN or Inf texel where a lookup may touch it makes the lookup's result unpinned: the GL
// formula (1 - a) t0 + a t1 turns 0 * Inf into NaN, llvmpipe computes t0 + a (t1 - t0) (Inf -
// Inf = NaN, measured on BrightRingsNanInf.exr), the oracle leaves zero weights out. Such values
// get an infinite bound ("the footprint holds NaN/Inf"): where NaN/Inf appear is compared, not
// which of them. The window magnitude carries it as +Inf.
//
// Local range (max - min) and magnitude (max |t|) of each channel over the texels a tap based
// at texel p may touch once its coordinate is a little off: [p-1, p+2] along the blurred axis
// (linear5 taps sit between p and p+1), [q-1, q+1] across it. Computed for the rows a band's
// taps reach, in two passes: along the axis, then across. Min and max are exact, so the band's
// statistics are the whole image's.

// Folds value v into a window's (min, max, magnitude) as std::min, std::max and std::max of |v|
// in turn would, over finite values only; a non-finite one makes the magnitude +Inf (see above).
// Written as selects so that the loops below vectorise.
inline void fold(float v, float& mn, float& mx, float& ma) {
  const float a = std::fabs(v);
  const bool finite = a <= FLT_MAX;  // false for NaN and +-Inf
  mn = finite && v < mn ? v : mn;
  mx = finite && mx < v ? v : mx;
  ma = !finite ? INFINITY : ma < a ? a : ma;
}

// Pass 1 over n values (RGBA interleaved, alpha too: its results are not read): value i folds
// t0[i], t1[i], t2[i], t3[i] in that order.
template <bool Range>
void pass1(const float* __restrict t0, const float* __restrict t1, const float* __restrict t2,
           const float* __restrict t3, std::size_t n, float* __restrict lo, float* __restrict hi,
           float* __restrict ma) {
  for (std::size_t i = 0; i < n; ++i) {
    float mn = INFINITY, mx = -INFINITY, m = 0;
    fold(t0[i], mn, mx, m);
    fold(t1[i], mn, mx, m);
    fold(t2[i], mn, mx, m);
    fold(t3[i], mn, mx, m);
    if (Range) {
      lo[i] = mn;
      hi[i] = mx;
    }
    ma[i] = m;
  }
}

// Pass 2 over n values: value i combines entries i of three pass-1 results (d = 0, 1, 2 in that
// order; std::min / std::max: none is NaN), into the range and the magnitude.
template <bool Range>
void pass2(const float* const lo[3], const float* const hi[3], const float* const ma[3],
           std::size_t n, float* __restrict range, float* __restrict magnitude) {
  const float *__restrict l0 = lo[0], *__restrict l1 = lo[1], *__restrict l2 = lo[2];
  const float *__restrict h0 = hi[0], *__restrict h1 = hi[1], *__restrict h2 = hi[2];
  const float *__restrict m0 = ma[0], *__restrict m1 = ma[1], *__restrict m2 = ma[2];
  for (std::size_t i = 0; i < n; ++i) {
    float m = 0;
    m = m < m0[i] ? m0[i] : m;
    m = m < m1[i] ? m1[i] : m;
    m = m < m2[i] ? m2[i] : m;
    magnitude[i] = m;
    if (Range) {
      float mn = INFINITY, mx = -INFINITY;
      mn = l0[i] < mn ? l0[i] : mn;
      mn = l1[i] < mn ? l1[i] : mn;
      mn = l2[i] < mn ? l2[i] : mn;
      mx = mx < h0[i] ? h0[i] : mx;
      mx = mx < h1[i] ? h1[i] : mx;
      mx = mx < h2[i] ? h2[i] : mx;
      range[i] = mx >= mn ? mx - mn : 0.0f;
    }
  }
}

// Per-thread scratch of a band (reused band after band: stage-wide buffers would be mapped and
// faulted in afresh on every allocation).
struct WindowScratch {
  std::vector<float> lo, hi, mag;       // pass 1, RGBA rows
  std::vector<float> range, magnitude;  // the window statistics, RGBA rows
  std::vector<std::uint8_t> src_const, p1_const, p1_filled, w_const, w_filled;
  std::vector<int> src_a, src_b;        // a source row's span (row_span)
  std::vector<std::array<float, 4>> src_c, p1_lo, p1_hi, p1_ma, w_range, w_mag;
};

WindowScratch& window_scratch() {
  thread_local WindowScratch s;
  return s;
}

template <class T>
T* sized(std::vector<T>& v, std::size_t n) {
  if (v.size() < n) v.resize(n);
  return v.data();
}

// The span [a, b) of a row of w outside which every texel has the first texel's bits (`c`):
// a = b = 0, and true, when the whole row has them. Rows of one value (dark and empty regions,
// their bounds) have one window statistic and one sum, computed once; a row that differs only
// in a span (a sparse bright pass) has those everywhere else.
bool row_span(const float* row, int w, std::array<float, 4>& c, int& a, int& b) {
  std::uint64_t first[2];
  std::memcpy(first, row, sizeof first);
  std::memcpy(c.data(), row, sizeof first);
  // Texels [x, x + n) all have the first texel's bits: compared 64 bits at a time, n at once.
  const auto same = [&](int x, int n) {
    std::uint64_t d = 0;
    for (int i = 0; i < n; ++i) {
      std::uint64_t t[2];
      std::memcpy(t, row + std::size_t(x + i) * kChannels, sizeof t);
      d |= (t[0] ^ first[0]) | (t[1] ^ first[1]);
    }
    return d == 0;
  };
  constexpr int kBlock = 8;
  a = 1;
  while (a + kBlock <= w && same(a, kBlock)) a += kBlock;
  while (a < w && same(a, 1)) ++a;
  if (a == w) {
    a = b = 0;
    return true;
  }
  b = w;
  while (b - kBlock > a && same(b - kBlock, kBlock)) b -= kBlock;
  while (same(b - 1, 1)) --b;
  return false;
}

void fill_row(float* row, int x0, int x1, const std::array<float, 4>& c) {
  for (int x = x0; x < x1; ++x) std::memcpy(row + std::size_t(x) * kChannels, c.data(), sizeof c);
}

// The texels of a row of w whose four (pass 1: x-1..x+2) or three (pass 2: x-1..x+1) neighbours
// along x are all inside: [1, w - reach), the others clamp.
inline bool inside(int x, int w, int reach) { return x >= 1 && x + reach < w; }

// Pass 1 along x of texels [x0, x1) of one row (each from its texels x-1..x+2, clamped at the
// edges).
template <bool Range>
void pass1_along_x(const float* in, int w, int x0, int x1, float* lo, float* hi, float* ma) {
  constexpr int C = kChannels;
  const int i0 = std::max(x0, 1), i1 = std::min(x1, w - 2);  // inside
  if (i1 > i0) {
    const std::size_t o = std::size_t(i0) * C;
    const float* t = in + o - C;
    pass1<Range>(t, t + C, t + 2 * C, t + 3 * C, std::size_t(i1 - i0) * C, lo + o, hi + o, ma + o);
  }
  for (int x = x0; x < x1; ++x) {
    if (inside(x, w, 2)) continue;
    const float* t[4];
    for (int d = 0; d < 4; ++d) t[d] = in + std::size_t(std::clamp(x + d - 1, 0, w - 1)) * C;
    const std::size_t o = std::size_t(x) * C;
    pass1<Range>(t[0], t[1], t[2], t[3], C, Range ? lo + o : nullptr, Range ? hi + o : nullptr,
                 ma + o);
  }
}

// Pass 2 across x of texels [x0, x1) of one row (each from x-1..x+1, clamped at the edges).
template <bool Range>
void pass2_across_x(const float* lo, const float* hi, const float* ma, int w, int x0, int x1,
                    float* range, float* magnitude) {
  constexpr int C = kChannels;
  const int i0 = std::max(x0, 1), i1 = std::min(x1, w - 1);  // inside
  if (i1 > i0) {
    const std::size_t o = std::size_t(i0) * C;
    const float* l[3] = {lo + o - C, lo + o, lo + o + C};
    const float* g[3] = {hi + o - C, hi + o, hi + o + C};
    const float* m[3] = {ma + o - C, ma + o, ma + o + C};
    pass2<Range>(l, g, m, std::size_t(i1 - i0) * C, range ? range + o : nullptr, magnitude + o);
  }
  for (int x = x0; x < x1; ++x) {
    if (inside(x, w, 1)) continue;
    const float *l[3], *g[3], *m[3];
    for (int d = 0; d < 3; ++d) {
      const std::size_t at = std::size_t(std::clamp(x + d - 1, 0, w - 1)) * C;
      l[d] = lo + at;
      g[d] = hi + at;
      m[d] = ma + at;
    }
    const std::size_t o = std::size_t(x) * C;
    pass2<Range>(l, g, m, C, range + o, magnitude + o);
  }
}

// The horizontal pass's windows (window_rows) at columns [x0, x1): pass 1 along x on the source
// rows [q0, q1), a constant row's from its one texel (made whole only when a window row that is
// not constant reads it); pass 2 across the rows y-1..y+1.
template <bool Range>
void windows_h(ConstImageView src, int r0, int r1, int q0, int q1, int x0, int x1, float* range,
               float* magnitude, WindowScratch& s) {
  const int w = src.width, h = src.height;
  const std::size_t row = std::size_t(w) * kChannels, n = std::size_t(q1 - q0) * row;
  const std::size_t first = std::size_t(x0) * kChannels, count = std::size_t(x1 - x0) * kChannels;
  auto at = [&](std::vector<float>& v, int i) {
    return v.empty() ? nullptr : v.data() + std::size_t(i) * row;
  };
  sized(s.lo, Range ? n : 0);
  sized(s.hi, Range ? n : 0);
  sized(s.mag, n);
  for (auto* v : {&s.p1_const, &s.p1_filled}) sized(*v, std::size_t(q1 - q0));
  for (auto* v : {&s.p1_lo, &s.p1_hi, &s.p1_ma}) sized(*v, std::size_t(q1 - q0));
  for (int y = q0; y < q1; ++y) {
    const int i = y - q0;
    s.p1_const[i] = s.src_const[i];
    s.p1_filled[i] = !s.src_const[i];
    const float* c = s.src_c[i].data();
    if (s.src_const[i])
      pass1<Range>(c, c, c, c, kChannels, s.p1_lo[i].data(), s.p1_hi[i].data(), s.p1_ma[i].data());
    else
      pass1_along_x<Range>(src.row(y), w, x0, x1, at(s.lo, i), at(s.hi, i), at(s.mag, i));
  }
  for (int r = r0; r < r1; ++r) {
    int rows[3];
    bool all_const = true;
    for (int d = 0; d < 3; ++d) {
      rows[d] = std::clamp(r + d - 1, 0, h - 1) - q0;
      all_const = all_const && s.p1_const[rows[d]];
    }
    const float *l[3], *g[3], *m[3];
    for (int d = 0; d < 3; ++d) {
      const int i = rows[d];
      if (!all_const && !s.p1_filled[i]) {
        if (Range) fill_row(at(s.lo, i), x0, x1, s.p1_lo[i]);
        if (Range) fill_row(at(s.hi, i), x0, x1, s.p1_hi[i]);
        fill_row(at(s.mag, i), x0, x1, s.p1_ma[i]);
        s.p1_filled[i] = 1;
      }
      l[d] = all_const ? s.p1_lo[i].data() : Range ? at(s.lo, i) + first : nullptr;
      g[d] = all_const ? s.p1_hi[i].data() : Range ? at(s.hi, i) + first : nullptr;
      m[d] = all_const ? s.p1_ma[i].data() : at(s.mag, i) + first;
    }
    s.w_const[r - r0] = all_const;
    const std::size_t o = std::size_t(r - r0) * row + first;
    if (all_const) pass2<Range>(l, g, m, kChannels, s.w_range[r - r0].data(), s.w_mag[r - r0].data());
    else pass2<Range>(l, g, m, count, Range ? range + o : nullptr, magnitude + o);
  }
}

// The vertical pass's windows (window_rows) at columns [x0, x1): per row, pass 1 along y over
// the source rows y-1..y+2, pass 2 across x; from one texel where the four source rows are
// constant.
template <bool Range>
void windows_v(ConstImageView src, int r0, int r1, int q0, int x0, int x1, float* range,
               float* magnitude, WindowScratch& s) {
  const int w = src.width, h = src.height;
  const std::size_t row = std::size_t(w) * kChannels;
  float *lo = sized(s.lo, Range ? row : 0), *hi = sized(s.hi, Range ? row : 0);
  float* ma = sized(s.mag, row);
  // Pass 2 at [x0, x1) reads pass 1 at [x0 - 1, x1 + 1), clamped.
  const int p0 = std::max(x0 - 1, 0), p1 = std::min(x1 + 1, w);
  const std::size_t first = std::size_t(p0) * kChannels, count = std::size_t(p1 - p0) * kChannels;
  for (int r = r0; r < r1; ++r) {
    const float* t[4];
    bool all_const = true;
    for (int d = 0; d < 4; ++d) {
      const int y = std::clamp(r + d - 1, 0, h - 1);
      all_const = all_const && s.src_const[y - q0];
      t[d] = all_const ? s.src_c[y - q0].data() : src.row(y);
    }
    if (all_const) {
      float l[4], g[4], m[4];
      pass1<Range>(t[0], t[1], t[2], t[3], kChannels, l, g, m);
      const float *ls[3] = {l, l, l}, *gs[3] = {g, g, g}, *ms[3] = {m, m, m};
      s.w_const[r - r0] = 1;
      pass2<Range>(ls, gs, ms, kChannels, s.w_range[r - r0].data(), s.w_mag[r - r0].data());
      continue;
    }
    for (int d = 0; d < 4; ++d) t[d] = src.row(std::clamp(r + d - 1, 0, h - 1)) + first;
    pass1<Range>(t[0], t[1], t[2], t[3], count, Range ? lo + first : nullptr,
                 Range ? hi + first : nullptr, ma + first);
    const std::size_t o = std::size_t(r - r0) * row;
    pass2_across_x<Range>(lo, hi, ma, w, x0, x1, Range ? range + o : nullptr, magnitude + o);
  }
}

// Each source row's span (row_span) for the window rows [r0, r1), into s; returns the columns
// [x0, x1) whose windows may differ from one another: where every source row has the same
// value outside its span, the windows that reach no span (the horizontal pass's window at x
// covers x-1..x+2, the vertical one's x-1..x+1) all have that value's statistics. Otherwise
// every column.
std::pair<int, int> source_spans(ConstImageView src, Axis axis, int r0, int r1, WindowScratch& s) {
  const int w = src.width, h = src.height;
  const bool hz = axis == Axis::horizontal;
  const int q0 = std::max(r0 - 1, 0), q1 = std::min(r1 + (hz ? 1 : 2), h);
  const std::size_t n = std::size_t(q1 - q0);
  sized(s.src_const, n);
  sized(s.src_c, n);
  sized(s.src_a, n);
  sized(s.src_b, n);
  bool same = true;
  int a = w, b = 0;
  for (int y = q0; y < q1; ++y) {
    const int i = y - q0;
    s.src_const[i] = row_span(src.row(y), w, s.src_c[i], s.src_a[i], s.src_b[i]);
    same = same &&
           std::memcmp(s.src_c[i].data(), s.src_c[0].data(), sizeof(float) * kChannels) == 0;
    if (!s.src_const[i]) {
      a = std::min(a, s.src_a[i]);
      b = std::max(b, s.src_b[i]);
    }
  }
  if (!same || a >= b) return {0, w};
  return {std::max(a - (hz ? 2 : 1), 0), std::min(b + 1, w)};
}

// Window statistics of rows [r0, r1) of src at columns [x0, x1) into range / magnitude (RGBA
// rows; without Range only the magnitude), edges clamped; source_spans has run. A window row
// all of whose source rows are constant is constant: it is flagged in s.w_const with its values
// in s.w_range / s.w_mag, and its rows are left unwritten (window_filled writes them).
template <bool Range>
void window_rows(ConstImageView src, Axis axis, int r0, int r1, int x0, int x1, float* range,
                 float* magnitude, WindowScratch& s) {
  const int h = src.height;
  const std::size_t rows = std::size_t(r1 - r0);
  const bool hz = axis == Axis::horizontal;
  const int q0 = std::max(r0 - 1, 0), q1 = std::min(r1 + (hz ? 1 : 2), h);
  for (auto* v : {&s.w_const, &s.w_filled}) std::fill(sized(*v, rows), sized(*v, rows) + rows, 0);
  sized(s.w_range, rows);
  sized(s.w_mag, rows);
  if (hz) windows_h<Range>(src, r0, r1, q0, q1, x0, x1, range, magnitude, s);
  else windows_v<Range>(src, r0, r1, q0, x0, x1, range, magnitude, s);
}

// Writes columns [x0, x1) of window row i if it was left constant (window_rows).
void window_filled(WindowScratch& s, int i, int w, int x0, int x1, float* range, float* magnitude) {
  if (!s.w_const[i] || s.w_filled[i]) return;
  const std::size_t o = std::size_t(i) * w * kChannels;
  if (range) fill_row(range + o, x0, x1, s.w_range[i]);
  fill_row(magnitude + o, x0, x1, s.w_mag[i]);
  s.w_filled[i] = 1;
}

}  // namespace

BlurTaps::BlurTaps(Axis a, int n, const Kernel& k) : axis(a), taps(k.taps()) {
  if (taps > kMaxTaps) throw std::logic_error("blur bounds: more than 16 taps");
  for (int pos = 0; pos < n; ++pos)
    for (std::size_t i = 0; i < k.offsets_f64.size(); ++i)
      for (double sign : {1.0, -1.0}) {
        if (i == 0 && sign < 0) continue;
        base.push_back(std::clamp(static_cast<int>(std::floor(pos + sign * k.offsets_f64[i])), 0, n - 1));
        weight.push_back(k.weights_f64[i]);
      }
  const int mid = n / 2;
  for (int t = 0; t < taps; ++t) offset.push_back(base[std::size_t(mid) * taps + t] - mid);
  auto fixed = [&](int pos) {
    for (int t = 0; t < taps; ++t)
      if (base[std::size_t(pos) * taps + t] != pos + offset[t]) return false;
    return true;
  };
  inner0 = inner1 = mid;
  while (inner0 > 0 && fixed(inner0 - 1)) --inner0;
  while (inner1 < n && fixed(inner1)) ++inner1;
  reach0 = *std::min_element(offset.begin(), offset.end());
  reach1 = *std::max_element(offset.begin(), offset.end());
}

// sum over taps of weight * statistic(tap base), per channel, for rows [y0, y1) of src's
// window statistics (range_sum may be null: magnitude only). RGBA rows. In double, tap by tap
// in the kernel's order, rounded to float once. Every tap of a position has the same weights,
// so where every tap reads constant window statistics (a constant row, or the columns outside
// the band's spans) the sum is one texel's.
void BlurTaps::sums(ConstImageView src, int y0, int y1, float* range_sum,
                    float* magnitude_sum) const {
  sums(src, y0, y1, range_sum, magnitude_sum, nullptr);
}

void BlurTaps::sums(ConstImageView src, int y0, int y1, float* range_sum, float* magnitude_sum,
                    RowShape* shapes) const {
  const bool hz = axis == Axis::horizontal;
  const int w = src.width;
  // The window rows the band's taps read: its own (horizontal), or every tap's base row.
  int r0 = y0, r1 = y1;
  if (!hz) {
    r0 = *std::min_element(base.begin() + std::ptrdiff_t(y0) * taps, base.begin() + std::ptrdiff_t(y0 + 1) * taps);
    r1 = 1 + *std::max_element(base.begin() + std::ptrdiff_t(y1 - 1) * taps, base.begin() + std::ptrdiff_t(y1) * taps);
  }
  WindowScratch& s = window_scratch();
  // The columns whose windows may differ, [wx0, wx1); the sums that read them, [ox0, ox1) (a
  // horizontal tap based at x + offset, clamped); the windows those read, [sx0, sx1).
  const auto [wx0, wx1] = source_spans(src, axis, r0, r1, s);
  int ox0 = wx0, ox1 = wx1, sx0 = wx0, sx1 = wx1;
  if (hz && (wx0 > 0 || wx1 < w)) {
    ox0 = std::clamp(wx0 - reach1, 0, w);
    ox1 = std::clamp(wx1 - reach0, 0, w);
    sx0 = std::clamp(ox0 + reach0, 0, w);
    sx1 = std::clamp(ox1 + reach1, 0, w);
  }
  const std::size_t row = std::size_t(w) * kChannels, n = std::size_t(r1 - r0) * row;
  float* range = range_sum ? sized(s.range, n) : nullptr;
  float* magnitude = sized(s.magnitude, n);
  if (range) window_rows<true>(src, axis, r0, r1, sx0, sx1, range, magnitude, s);
  else window_rows<false>(src, axis, r0, r1, sx0, sx1, nullptr, magnitude, s);
  // The statistics of a window of the value outside the spans, and their sum over the taps.
  std::array<float, 4> outside_range{}, outside_magnitude{};
  if (ox0 > 0 || ox1 < w) {
    const float* c = s.src_c[0].data();
    float l[4], g[4], m[4], range_c[4], magnitude_c[4];
    pass1<true>(c, c, c, c, kChannels, l, g, m);
    const float *ls[3] = {l, l, l}, *gs[3] = {g, g, g}, *ms[3] = {m, m, m};
    pass2<true>(ls, gs, ms, kChannels, range_c, magnitude_c);
    const float* rc[kMaxTaps];
    const float* mc[kMaxTaps];
    for (int t = 0; t < taps; ++t) {
      rc[t] = range_c;
      mc[t] = magnitude_c;
    }
    weighted_sums(rc, &weight[0], kChannels, outside_range.data());
    weighted_sums(mc, &weight[0], kChannels, outside_magnitude.data());
  }
  for (int which = 0; which < 2; ++which) {
    const float* stat = which == 0 ? range : magnitude;
    float* out = which == 0 ? range_sum : magnitude_sum;
    if (!out) continue;
    const auto& consts = which == 0 ? s.w_range : s.w_mag;
    const std::array<float, 4>& outside = which == 0 ? outside_range : outside_magnitude;
    for (int y = y0; y < y1; ++y) {
      float* o = out + std::size_t(y - y0) * row;
      const int* b = hz ? nullptr : &base[std::size_t(y) * taps];
      bool all_const = true;
      for (int t = 0; t < (hz ? 1 : taps) && all_const; ++t) all_const = s.w_const[(hz ? y : b[t]) - r0];
      if (all_const) {
        const float* src_c[kMaxTaps];
        for (int t = 0; t < taps; ++t) src_c[t] = consts[(hz ? y : b[t]) - r0].data();
        std::array<float, 4> v;
        weighted_sums(src_c, &weight[0], kChannels, v.data());
        if (shapes) {
          RowShape& sh = shapes[y - y0];
          sh.x0 = sh.x1 = 0;
          (which == 0 ? sh.range : sh.magnitude) = v;
        } else {
          fill_row(o, 0, w, v);
        }
        continue;
      }
      RowShape local;
      RowShape& sh = shapes ? shapes[y - y0] : local;
      sh.x0 = ox0;
      sh.x1 = ox1;
      (which == 0 ? sh.range : sh.magnitude) = outside;
      if (!shapes) sh.fill_outside(o, w, outside.data());
      if (hz) {
        window_filled(s, y - r0, w, sx0, sx1, range, magnitude);
        along_row(stat + std::size_t(y - r0) * row, ox0, ox1, o);
        continue;
      }
      const float* rows[kMaxTaps];
      for (int t = 0; t < taps; ++t) {
        window_filled(s, b[t] - r0, w, sx0, sx1, range, magnitude);
        rows[t] = stat + std::size_t(b[t] - r0) * row + std::size_t(ox0) * kChannels;
      }
      weighted_sums(rows, &weight[std::size_t(y) * taps], std::size_t(ox1 - ox0) * kChannels,
                    o + std::size_t(ox0) * kChannels);
    }
  }
}

void BlurTaps::RowShape::fill_outside(float* row, int w, const float* c) const {
  const auto put = [&](int from, int to) {
    for (int x = from; x < to; ++x)
      std::memcpy(row + std::size_t(x) * kChannels, c, sizeof(float) * kChannels);
  };
  put(0, x0);
  put(x1, w);
}

// out[i] = sum over taps t of w[t] * src[t][i], in double from 0, tap by tap in order, rounded
// to float once: the kernels' tap counts unrolled.
namespace {

template <int T>
void sums_of(const float* const* src, const double* w, std::size_t n, float* out) {
  for (std::size_t i = 0; i < n; ++i) {
    double a = 0;
    for (int t = 0; t < T; ++t) a += w[t] * src[t][i];
    out[i] = static_cast<float>(a);
  }
}
}  // namespace

void BlurTaps::weighted_sums(const float* const* src, const double* w, std::size_t n,
                             float* out) const {
  if (taps == 9) return sums_of<9>(src, w, n, out);
  if (taps == 5) return sums_of<5>(src, w, n, out);
  for (std::size_t i = 0; i < n; ++i) {
    double a = 0;
    for (int t = 0; t < taps; ++t) a += w[t] * src[t][i];
    out[i] = static_cast<float>(a);
  }
}

// A horizontal pass's sums over columns [x0, x1) of one row of statistics: the inner texels by
// fixed offsets, the edges by their clamped bases.
void BlurTaps::along_row(const float* stat, int x0, int x1, float* out) const {
  constexpr int C = kChannels;
  const float* src[kMaxTaps];
  const int i0 = std::max(x0, inner0), i1 = std::min(x1, inner1);
  if (i1 > i0) {
    for (int t = 0; t < taps; ++t) src[t] = stat + std::ptrdiff_t(i0 + offset[t]) * C;
    weighted_sums(src, weight.data(), std::size_t(i1 - i0) * C, out + std::size_t(i0) * C);
  }
  for (int x = x0; x < x1; ++x) {
    if (x >= inner0 && x < inner1) continue;
    for (int t = 0; t < taps; ++t) src[t] = stat + std::size_t(base[std::size_t(x) * taps + t]) * C;
    weighted_sums(src, &weight[std::size_t(x) * taps], C, out + std::size_t(x) * C);
  }
}

}  // namespace bloomref::parity::detail
