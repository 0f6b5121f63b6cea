// bloomref — the reference blur's texel: the sums of one output texel of blur_pass, in the
// shader's order (stages.h), shared by the reference blur (blur.cpp) and the fast engine's
// inexact lines (engine/src/blur_inexact.cpp), which must give the same bits.
// Internal linkage on purpose: each translation unit keeps its own copy, so no weak symbol exists
// that the linker could take from a file built for a wider instruction set
// (scripts/check-isa-symbols).
#pragma once

#include <type_traits>
#include <vector>

#include "bloomref/simd/simd_lanes.h"
#include "bloomref/exact/taps.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"

namespace bloomref {
namespace {

using detail::TapTable;
using detail::centre_tap;
using detail::make_taps;

inline const std::vector<float>& weights(const Kernel& k, float) { return k.weights_f32; }
inline const std::vector<double>& weights(const Kernel& k, double) { return k.weights_f64; }

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
}  // namespace bloomref
