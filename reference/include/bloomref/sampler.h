// bloomref — texture lookups with OpenGL semantics (GL 4.6 core spec, 8.14 "Texture
// Minification": GL_LINEAR, and 8.14.2 wrap mode GL_CLAMP_TO_EDGE).
//
// A lookup at normalised coordinate s on an axis of n texels computes u = s * n - 0.5,
// i = floor(u), a = frac(u); the texels i and i + 1 are clamped to [0, n - 1] and weighted
// 1 - a and a. In f32 every step is done in float as a shader would, and `subtexel_bits` > 0
// rounds a to that many fractional bits (hardware filtering units use 8-bit fixed point;
// llvmpipe uses float weights, measured: docs/design.md, "GL path"). The f64 truth takes coordinates in texel
// units directly (u = 0 is the centre of texel 0), so integer taps are exact.
//
// A texel whose weight is exactly zero does not contribute (so an Inf beside an exact tap does
// not turn into NaN through 0 * Inf).
#pragma once

#include <cmath>

#include "bloomref/image.h"

namespace bloomref {

/// One axis of a GL_LINEAR lookup, after clamp-to-edge.
template <class T>
struct AxisTap {
  int i0 = 0, i1 = 0;
  T w0 = 1, w1 = 0;
};

/// Normalised coordinate of the centre of texel x on an axis of n texels: (x + 0.5f) / n in float.
inline float texel_centre(int x, int n) {
  return (static_cast<float>(x) + 0.5f) / static_cast<float>(n);
}

/// GL_LINEAR along one axis at normalised coordinate s, computed in float.
AxisTap<float> gl_axis_tap(float s, int n, int subtexel_bits);

/// GL_LINEAR along one axis at texel-space coordinate u, computed exactly in double.
AxisTap<double> exact_axis_tap(double u, int n);

/// Bilinear RGB at the product of two axis taps: the GL formula's four terms in its order,
/// (1-a)(1-b) t00 + a(1-b) t10 + (1-a)b t01 + ab t11, zero-weight terms left out.
template <class T>
inline void sample_rgb(BasicView<const T> img, const AxisTap<T>& tx, const AxisTap<T>& ty,
                       T out[3]) {
  const T wx[2] = {tx.w0, tx.w1};
  const T wy[2] = {ty.w0, ty.w1};
  const int ix[2] = {tx.i0, tx.i1};
  const int iy[2] = {ty.i0, ty.i1};
  bool first = true;
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      const T w = wx[i] * wy[j];
      if (w == T(0)) continue;
      const T* t = img.pixel(ix[i], iy[j]);
      for (int c = 0; c < 3; ++c) out[c] = first ? w * t[c] : out[c] + w * t[c];
      first = false;
    }
  }
  if (first) out[0] = out[1] = out[2] = T(0);
}

/// Convenience for tests and debugging: GL texture(img, vec2(s, t)).rgb in float.
void gl_texture_rgb(ConstImageView img, float s, float t, int subtexel_bits, float out[3]);

}  // namespace bloomref
