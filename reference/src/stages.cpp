#include "bloomref/stages.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <type_traits>
#include <vector>

#include "bloomref/parallel.h"
#include "bloomref/sampler.h"
#include "bloomref/exact/oracle_math.h"
#include "bloomref/simd/simd_lanes.h"

namespace bloomref {

// ---- the sampler (sampler.h) -------------------------------------------------------------

AxisTap<float> gl_axis_tap(float s, int n, int subtexel_bits) {
  const float u = s * static_cast<float>(n) - 0.5f;
  float fi = std::floor(u);
  // Rounds when u is a tiny negative: u = -2.98e-8 (1920 columns, x = 1, offset 1) gives
  // a = 1 - 2.98e-8 -> 1.0f, so w0 = 0 and the lookup is texel i1 alone.
  float a = u - fi;
  if (subtexel_bits > 0) {
    const float scale = std::ldexp(1.0f, subtexel_bits);
    a = std::nearbyint(a * scale) / scale;
    if (a == 1.0f) {
      fi += 1.0f;
      a = 0.0f;
    }
  }
  // Clamp in float before converting: a coordinate far outside [0, 1] must not overflow int.
  const float last = static_cast<float>(n - 1);
  AxisTap<float> t;
  t.i0 = static_cast<int>(std::min(std::max(fi, 0.0f), last));
  t.i1 = static_cast<int>(std::min(std::max(fi + 1.0f, 0.0f), last));
  t.w0 = 1.0f - a;
  t.w1 = a;
  return t;
}

AxisTap<double> exact_axis_tap(double u, int n) {
  const double fi = std::floor(u);
  const double a = u - fi;
  const double last = n - 1;
  AxisTap<double> t;
  t.i0 = static_cast<int>(std::min(std::max(fi, 0.0), last));
  t.i1 = static_cast<int>(std::min(std::max(fi + 1.0, 0.0), last));
  t.w0 = 1.0 - a;
  t.w1 = a;
  return t;
}

void gl_texture_rgb(ConstImageView img, float s, float t, int subtexel_bits, float out[3]) {
  sample_rgb(img, gl_axis_tap(s, img.width, subtexel_bits),
             gl_axis_tap(t, img.height, subtexel_bits), out);
}

// ---- per-pixel stages --------------------------------------------------------------------

int nonfinite_code(NonFinite n) {
  switch (n) {
    case NonFinite::zero: return 0;
    case NonFinite::clamp: return 1;
    case NonFinite::propagate: return 2;
    case NonFinite::error: return 3;
  }
  return 0;
}

double storage_max(Storage s) {
  return s == Storage::f16         ? kHalfMax
         : s == Storage::r11g11b10 ? 65024.0
         : s == Storage::rgba8     ? 1.0
                                   : kRangeGuard;
}

// One sweep: each row counted, then rewritten while it is in cache. A row with nothing to count
// holds only finite values within kRangeGuard, which sanitize_value returns as they are (bit for
// bit, -0 too): in place there is nothing to write (the dense plan's input stage: 133 MB read
// twice and written once at 3840x2160, now read once).
template <class T>
NonFiniteCounts sanitize(BasicView<const T> src, BasicView<T> dst, NonFinite policy,
                         Storage storage, int threads) {
  NonFiniteCounts total;
  std::mutex m;
  const int n = src.width * kChannels;
  parallel_rows(src.height, threads, [&](int y0, int y1) {
    NonFiniteCounts c;
    for (int y = y0; y < y1; ++y) {
      const T* s = src.row(y);
      T* d = dst.row(y);
      if (!count_nonfinite_values(s, n, c)) {
        if (static_cast<const T*>(d) != s) std::copy(s, s + n, d);
        continue;
      }
      for (int i = 0; i < n; ++i) d[i] = sanitize_value(s[i], policy, storage);
    }
    std::lock_guard<std::mutex> lock(m);
    total += c;
  });
  return total;
}

namespace detail {
namespace {
/// The luminance of the four RGBA pixels at p, one a lane: the pixels transposed into R, G and
/// B lanes, then luminance() on the lanes (built with -ffp-contract=off: no fused multiply-add),
/// so each lane's value, and any comparison of it, is the scalar one.
inline v4f luminance4(const float* p, const LumaWeights<float>& w) {
  const v4f a = load<v4f>(p), b = load<v4f>(p + 4), c = load<v4f>(p + 8), d = load<v4f>(p + 12);
  const v4f rg01 = BLOOMREF_SHUFFLE2(v4i, a, b, 0, 4, 1, 5);  // r0 r1 g0 g1
  const v4f rg23 = BLOOMREF_SHUFFLE2(v4i, c, d, 0, 4, 1, 5);
  const v4f b01 = BLOOMREF_SHUFFLE2(v4i, a, b, 2, 6, 3, 7);  // b0 b1 a0 a1
  const v4f b23 = BLOOMREF_SHUFFLE2(v4i, c, d, 2, 6, 3, 7);
  return luminance<v4f, float>(BLOOMREF_SHUFFLE2(v4i, rg01, rg23, 0, 1, 4, 5),
                               BLOOMREF_SHUFFLE2(v4i, rg01, rg23, 2, 3, 6, 7),
                               BLOOMREF_SHUFFLE2(v4i, b01, b23, 0, 1, 4, 5), w);
}
}  // namespace
}  // namespace detail

// Whether any of the four RGBA pixels at p has luminance > threshold (luminance4: each lane's
// comparison is the scalar one).
namespace {
inline bool any_bright4(const float* p, float threshold, const LumaWeights<float>& w) {
  const detail::v4i bright = detail::luminance4(p, w) > threshold;
  return (bright[0] | bright[1] | bright[2] | bright[3]) != 0;
}
}  // namespace

template <class T>
void extract_bright(BasicView<const T> src, BasicView<T> dst, T threshold, int threads,
                    bool dst_zeroed, std::uint8_t* nonzero, const std::uint8_t* bright_rows,
                    const LumaRule& luma) {
  const LumaWeights<T> w = luma_weights<T>(luma.weights);
  const bool linear = luma.space == LumaSpace::linear;
  // The threshold's luminance: the weighted sum of linear colour, or of encoded colour.
  auto lum = [&](const T* s) {
    return linear ? luminance(s[0], s[1], s[2], w) : threshold_luminance(s[0], s[1], s[2], luma);
  };
  parallel_rows(src.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      if (dst_zeroed && bright_rows && !bright_rows[y]) continue;  // nothing to write
      if (!dst_zeroed && !nonzero) {  // the dense sweep, kept branch-free
        for (int x = 0; x < src.width; ++x) {
          const T* s = src.pixel(x, y);
          T* d = dst.pixel(x, y);
          const bool bright = lum(s) > threshold;
          for (int c = 0; c < 3; ++c) d[c] = bright ? s[c] : T(0);
          d[3] = T(1);
        }
        continue;
      }
      std::uint8_t* nz = nonzero ? nonzero + std::size_t(y) * src.width : nullptr;
      auto one = [&](int x) {
        const T* s = src.pixel(x, y);
        const bool bright = lum(s) > threshold;
        if (nz) nz[x] = bright && rgb_not_plus_zero(s);  // nonzero_support's test on what is written
        if (dst_zeroed && !bright) return;  // +0 already; the page may stay unwritten
        T* d = dst.pixel(x, y);
        for (int c = 0; c < 3; ++c) d[c] = bright ? s[c] : T(0);
        d[3] = T(1);
      };
      int x = 0;
      if constexpr (std::is_same_v<T, float>) {
        // Into a zeroed image a pixel that is not bright writes nothing: four at a time, the
        // luminance of each in one lane (the same operations, so the same test), and only a
        // group with a bright pixel taken pixel by pixel (StarField.exr, 0.03% bright: most of
        // the sparse sweep's time was the per-pixel branches).
        if (dst_zeroed && linear)  // the lanes weigh linear colour
          for (; x + 4 <= src.width; x += 4) {
            if (!any_bright4(src.pixel(x, y), threshold, w)) {
              if (nz) std::memset(nz + x, 0, 4);
              continue;
            }
            for (int i = x; i < x + 4; ++i) one(i);
          }
      }
      for (; x < src.width; ++x) one(x);
    }
  });
}

namespace detail {
void bright_rgb_row(const float* rgba, float* rgb, int n, float threshold, const LumaRule& luma) {
  const LumaWeights<float> w = luma_weights<float>(luma.weights);
  const bool linear = luma.space == LumaSpace::linear;
  int x = 0;
  // Four pixels at a time: each lane's luminance and test are the scalar ones (luminance4); a
  // pixel's RGB kept or zeroed by its lane's mask, then packed into three vectors of RGB.
  for (; linear && x + 4 <= n; x += 4) {
    const float* s = rgba + std::size_t(x) * kChannels;
    const v4i bright = luminance4(s, w) > threshold;
    const auto kept = [&](int i) {  // pixel i's RGBA, all bits kept or all cleared
      return reinterpret_cast<v4i>(load<v4f>(s + 4 * i)) & (v4i{} + bright[i]);
    };
    const v4i a = kept(0), b = kept(1), c = kept(2), d = kept(3);
    const v4i out[3] = {BLOOMREF_SHUFFLE2(v4i, a, b, 0, 1, 2, 4),   // r0 g0 b0 r1
                        BLOOMREF_SHUFFLE2(v4i, b, c, 1, 2, 4, 5),   // g1 b1 r2 g2
                        BLOOMREF_SHUFFLE2(v4i, c, d, 2, 4, 5, 6)};  // b2 r3 g3 b3
    std::memcpy(rgb + std::size_t(x) * 3, out, sizeof out);
  }
  for (; x < n; ++x) {
    const float* s = rgba + std::size_t(x) * kChannels;
    const bool bright = threshold_luminance(s[0], s[1], s[2], luma) > threshold;
    for (int c = 0; c < 3; ++c) rgb[std::size_t(x) * 3 + c] = bright ? s[c] : 0.0f;
  }
}
}  // namespace detail

template <class T>
void composite(BasicView<const T> scene, BasicView<const T> bloom, BasicView<T> dst, T strength,
               int threads) {
  parallel_rows(scene.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < scene.width; ++x) {
        const T* s = scene.pixel(x, y);
        const T* b = bloom.pixel(x, y);
        T* d = dst.pixel(x, y);
        for (int c = 0; c < 3; ++c) {
          const T t = strength * b[c];
          d[c] = s[c] + t;
        }
        d[3] = s[3];
      }
    }
  });
}

namespace {
// f32: the shader's order, with the series below |x| = 0.5 (detail::tonemap_f32, which the
// fast stages run in vector lanes).
inline float tonemap_value(float h, float exposure) { return detail::tonemap_f32<1>(h, exposure); }
inline double tonemap_value(double h, double exposure) { return -std::expm1(-h * exposure); }
}  // namespace

template <class T>
void composite_mix(BasicView<const T> scene, BasicView<const T> bloom, BasicView<T> dst, T a,
                   int threads) {
  const T keep = T(1) - a;
  parallel_rows(scene.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < scene.width; ++x) {
        const T* s = scene.pixel(x, y);
        const T* b = bloom.pixel(x, y);
        T* d = dst.pixel(x, y);
        const T alpha = s[3];
        for (int c = 0; c < 3; ++c) {
          const T u = s[c] * keep;
          const T v = b[c] * a;
          d[c] = u + v;
        }
        d[3] = alpha;
      }
  });
}

template <class T>
void tonemap(BasicView<const T> hdr, BasicView<T> dst, T exposure, int threads) {
  parallel_rows(hdr.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < hdr.width; ++x) {
        const T* s = hdr.pixel(x, y);
        T* d = dst.pixel(x, y);
        for (int c = 0; c < 3; ++c) d[c] = tonemap_value(s[c], exposure);
        d[3] = s[3];
      }
    }
  });
}

float oracle_exp(float x) { return detail::exp_f32<1>(x); }
float oracle_pow(float x, float y) { return detail::PowF32<1>(y)(x); }

namespace {
// pow as the output stage's T computes it; f32 builds the oracle's pow for 1 / gamma once.
struct PowOf {
  explicit PowOf(double y) : y(y) {}
  double operator()(double x) const { return std::pow(x, y); }
  double y;
};
template <class T>
using PowFor = std::conditional_t<std::is_same_v<T, float>, detail::PowF32<1>, PowOf>;
}  // namespace

template <class T>
void encode_output(BasicView<const T> mapped, BasicView<T> dst, T gamma, int threads) {
  const T inv_gamma = T(1) / gamma;
  const PowFor<T> pow(inv_gamma);
  parallel_rows(mapped.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < mapped.width; ++x) {
        const T* s = mapped.pixel(x, y);
        T* d = dst.pixel(x, y);
        // std::max(NaN, 0) is NaN: a propagated NaN stays visible in the output.
        for (int c = 0; c < 3; ++c) d[c] = pow(std::max(s[c], T(0)));
        d[3] = s[3];
      }
    }
  });
}

template <class T>
void store(BasicView<T> img, Storage storage, HalfRounding rounding, int threads) {
  if (storage == Storage::f32) return;
  if (storage == Storage::r11g11b10) {
    const bool toward_zero = rounding == HalfRounding::toward_zero;
    parallel_rows(img.height, threads, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y) {
        T* p = img.row(y);
        for (int x = 0; x < img.width; ++x, p += kChannels) {
          for (int c = 0; c < 3; ++c)
            p[c] = static_cast<T>(round_to_packed(double(p[c]), c == 2 ? 5 : 6, toward_zero));
          p[3] = T(1);  // no alpha: read back as 1
        }
      }
    });
    return;
  }
  if (storage == Storage::rgba8) {
    parallel_rows(img.height, threads, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y) {
        T* p = img.row(y);
        for (int i = 0; i < img.width * kChannels; ++i) p[i] = round_to_unorm8(p[i]);
      }
    });
    return;
  }
  parallel_rows(img.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      T* p = img.row(y);
      for (int i = 0; i < img.width * kChannels; ++i) p[i] = round_to_half(p[i], rounding);
    }
  });
}

std::uint8_t quantize_8bit(float x) {
  if (!(x > 0.0f)) return 0;  // also NaN
  if (x >= 1.0f) return 255;
  return static_cast<std::uint8_t>(std::lround(x * 255.0f));
}

#define BLOOMREF_INSTANTIATE(T)                                                                  \
  template NonFiniteCounts sanitize<T>(BasicView<const T>, BasicView<T>, NonFinite, Storage,     \
                                       int);                                                      \
  template void extract_bright<T>(BasicView<const T>, BasicView<T>, T, int, bool,              \
                                  std::uint8_t*, const std::uint8_t*, const LumaRule&);           \
  template void composite<T>(BasicView<const T>, BasicView<const T>, BasicView<T>, T, int);      \
  template void composite_mix<T>(BasicView<const T>, BasicView<const T>, BasicView<T>, T, int);  \
  template void tonemap<T>(BasicView<const T>, BasicView<T>, T, int);                            \
  template void encode_output<T>(BasicView<const T>, BasicView<T>, T, int);                      \
  template void store<T>(BasicView<T>, Storage, HalfRounding, int);
BLOOMREF_INSTANTIATE(float)
BLOOMREF_INSTANTIATE(double)
#undef BLOOMREF_INSTANTIATE

}  // namespace bloomref
