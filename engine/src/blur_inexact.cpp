// The fast blur's lines whose lookup across the blur is off them (blur_internal.h), with the
// reference texel's bits (texel.h).
#include <algorithm>
#include <cstdint>
#include <vector>

#include "blur_internal.h"
#include "bloomref/exact/texel.h"

namespace bloomref {
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
namespace {

// Whether x lies in one of the n sorted spans s.
bool in_spans(const Span* s, int n, int x) {
  const Span* e = s + n;
  const Span* it = std::upper_bound(s, e, x, [](int v, const Span& sp) { return v < sp.x1; });
  return it != e && it->x0 <= x;
}

}  // namespace

void blur_inexact_lines(const PassTables& t, const float* const* in, float* const* out,
                        const std::vector<float>& w, int a0, int a1, int b0, int b1,
                        const std::uint8_t* active, int width, bool dst_zero_outside,
                        int in_channels, int out_channels, InexactKernels kernels,
                        const Span* const* spans, const int* span_counts) {
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
    const auto reach = t.reach(p0, p1);
    const int lo = reach.first, hi = reach.second;  // a lambda below reads lo (C++17: no binding)
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
      if (spans && dst_zero_outside && !in_spans(spans[y], span_counts[y], x)) continue;
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

}  // namespace detail
}  // namespace bloomref
