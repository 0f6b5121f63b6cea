// Stage blur.k (stages.h). The coordinates of every tap depend on one axis only, so they are
// computed once per pass into tables, with exactly the arithmetic a per-pixel shader would do.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <vector>

#include "bloomref/exact/texel.h"
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

namespace detail {


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


template void blur_pass<float>(BasicView<const float>, BasicView<float>, const BlurPassOptions&,
                               int);
template void blur_pass<double>(BasicView<const double>, BasicView<double>,
                                const BlurPassOptions&, int);

}  // namespace bloomref
