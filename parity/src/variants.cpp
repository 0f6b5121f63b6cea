// The stages with one thing changed (variants.h). Weights, offsets and groups of the mip chain
// are the reference's (mip.h: seed 003's taps); the operation order is the reference's
// (stages.h, mip.h), written out again here as plain loops.
#include "bloomref/parity/variants.h"

#include <algorithm>
#include <cmath>

#include "bloomref/mip.h"
#include "bloomref/parallel.h"

namespace bloomref::parity {

int wrap_index(int i, int n, Wrap wrap) {
  switch (wrap) {
    case Wrap::clamp_to_edge:
      return std::clamp(i, 0, n - 1);
    case Wrap::repeat:
      return ((i % n) + n) % n;
    case Wrap::mirrored_repeat: {
      const int m = ((i % (2 * n)) + 2 * n) % (2 * n);  // mirror(a) over a period of 2n
      return m < n ? m : 2 * n - 1 - m;
    }
    case Wrap::border:
      return i < 0 || i >= n ? -1 : i;  // the border: variant_axis_tap gives it weight 0
  }
  return i;
}

AxisTap<float> variant_axis_tap(float s, int n, const Sampling& smp) {
  if (!smp.nearest && smp.wrap == Wrap::clamp_to_edge) return gl_axis_tap(s, n, smp.subtexel_bits);
  AxisTap<float> t;
  const float u = s * static_cast<float>(n);
  if (smp.nearest) {
    // Clamp in float first, as gl_axis_tap does: a far coordinate must not overflow int.
    const float f = std::clamp(std::floor(u), -4.0f * n, 4.0f * n);
    t.i0 = t.i1 = wrap_index(static_cast<int>(f), n, smp.wrap);
    t.w0 = t.i0 < 0 ? 0.0f : 1.0f;  // the black border
    t.w1 = 0.0f;
    t.i0 = t.i1 = std::max(t.i0, 0);
    return t;
  }
  const float v = u - 0.5f;
  float fi = std::floor(v);
  float a = v - fi;
  if (smp.subtexel_bits > 0) {
    const float scale = std::ldexp(1.0f, smp.subtexel_bits);
    a = std::nearbyint(a * scale) / scale;
    if (a == 1.0f) {
      fi += 1.0f;
      a = 0.0f;
    }
  }
  fi = std::clamp(fi, -4.0f * n, 4.0f * n);
  t.i0 = wrap_index(static_cast<int>(fi), n, smp.wrap);
  t.i1 = wrap_index(static_cast<int>(fi) + 1, n, smp.wrap);
  t.w0 = 1.0f - a;
  t.w1 = a;
  // The black border: a texel past the edge adds nothing (its index kept in the image).
  if (t.i0 < 0) t.w0 = 0.0f, t.i0 = std::max(t.i1, 0);
  if (t.i1 < 0) t.w1 = 0.0f, t.i1 = t.i0;
  return t;
}

namespace {

// Normalised coordinate of texel x's centre, shifted by smp.shift texels (exactly the centre
// when the shift is 0).
float centre(int x, int n, const Sampling& smp) {
  const float c = texel_centre(x, n);
  return smp.shift == 0.0f ? c : c + smp.shift / static_cast<float>(n);
}

}  // namespace

void blur_pass_variant(ConstImageView src, ImageView dst, Axis axis,
                       const std::vector<float>& offsets, const std::vector<float>& weights,
                       const Sampling& smp, int threads, float texel_step) {
  const bool hz = axis == Axis::horizontal;
  const int n = hz ? src.width : src.height, m = hz ? src.height : src.width;
  const int taps = 2 * static_cast<int>(weights.size()) - 1;
  // Per position along the axis: the centre tap, then +o_i and -o_i (the seeds' order).
  std::vector<AxisTap<float>> along;
  along.reserve(std::size_t(n) * taps);
  const float d = texel_step > 0.0f ? texel_step : 1.0f / static_cast<float>(n);
  for (int x = 0; x < n; ++x) {
    const float uv = centre(x, n, smp);
    along.push_back(variant_axis_tap(uv, n, smp));
    for (std::size_t i = 1; i < weights.size(); ++i) {
      const float step = d * offsets[i];
      along.push_back(variant_axis_tap(uv + step, n, smp));
      along.push_back(variant_axis_tap(uv - step, n, smp));
    }
  }
  std::vector<AxisTap<float>> across(m);
  for (int i = 0; i < m; ++i) across[i] = variant_axis_tap(centre(i, m, smp), m, smp);
  parallel_rows(src.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < src.width; ++x) {
        const AxisTap<float>* t = &along[std::size_t(hz ? x : y) * taps];
        const AxisTap<float>& other = across[hz ? y : x];
        auto sample = [&](int k, float s[3]) {
          if (hz) sample_rgb(src, t[k], other, s);
          else sample_rgb(src, other, t[k], s);
        };
        float s[3] = {}, r[3];  // sample_rgb writes s; the init only quiets -Wuninitialized
        sample(0, s);
        for (int c = 0; c < 3; ++c) r[c] = s[c] * weights[0];
        for (std::size_t i = 1; i < weights.size(); ++i)
          for (int side = 0; side < 2; ++side) {
            sample(int(2 * i - 1 + side), s);
            for (int c = 0; c < 3; ++c) r[c] = r[c] + s[c] * weights[i];
          }
        float* o = dst.pixel(x, y);
        o[0] = r[0], o[1] = r[1], o[2] = r[2], o[3] = 1.0f;
      }
  });
}

namespace {

// The lookup of a mip stage: uv + o * texel (mip.h, mip_lookup), each axis through `smp`.
void mip_sample(ConstImageView src, int x, int y, int tw, int th, int ox, int oy,
                const Sampling& smp, float out[3]) {
  const float tx = 1.0f / static_cast<float>(src.width), ty = 1.0f / static_cast<float>(src.height);
  const AxisTap<float> ax = variant_axis_tap(centre(x, tw, smp) + static_cast<float>(ox) * tx,
                                             src.width, smp);
  const AxisTap<float> ay = variant_axis_tap(centre(y, th, smp) + static_cast<float>(oy) * ty,
                                             src.height, smp);
  sample_rgb(src, ax, ay, out);
}

}  // namespace

void downsample_variant(ConstImageView src, ImageView dst, bool first, float threshold,
                        bool karis, bool tie_kept, const Sampling& smp, int threads,
                        const LumaRule& luma) {
  const LumaWeights<float> lw = luma_weights<float>(luma.weights);
  const auto& taps = downsample_taps();
  const auto& groups = karis_groups();
  const auto& gw = karis_group_weights();
  const int n = static_cast<int>(taps.size());
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    std::vector<float> q(std::size_t(n) * 3), w(n);
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        for (int i = 0; i < n; ++i) {
          float* qi = &q[std::size_t(i) * 3];
          mip_sample(src, x, y, dst.width, dst.height, taps[i].ox, taps[i].oy, smp, qi);
          const float l = threshold_luminance(qi[0], qi[1], qi[2], luma);
          if (first && (tie_kept ? l < threshold : l <= threshold)) qi[0] = qi[1] = qi[2] = 0.0f;
        }
        float r[3] = {0, 0, 0};
        if (first && karis) {
          for (int i = 0; i < n; ++i) {
            const float* qi = &q[std::size_t(i) * 3];
            w[i] = 1.0f / (1.0f + std::max(luminance(qi[0], qi[1], qi[2], lw), 0.0f));
          }
          for (std::size_t g = 0; g < groups.size(); ++g) {
            float s = 0.0f;
            for (int j = 0; j < 4; ++j) s = s + w[groups[g][j]];
            for (int j = 0; j < 4; ++j) {
              const int i = groups[g][j];
              const float f = gw[g] * w[i] / s;
              for (int c = 0; c < 3; ++c) r[c] = r[c] + f * q[std::size_t(i) * 3 + c];
            }
          }
        } else {
          for (int i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) r[c] = r[c] + q[std::size_t(i) * 3 + c] * taps[i].weight;
        }
        float* o = dst.pixel(x, y);
        o[0] = r[0], o[1] = r[1], o[2] = r[2], o[3] = 1.0f;
      }
  });
}

void upsample_variant(ConstImageView small, ConstImageView current, ImageView dst,
                      const Sampling& smp, int threads) {
  const auto& taps = tent_taps();
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        float r[3] = {0, 0, 0};
        if (!current.empty())
          for (int c = 0; c < 3; ++c) r[c] = current.pixel(x, y)[c];
        for (const MipTap& t : taps) {
          float s[3];
          mip_sample(small, x, y, dst.width, dst.height, t.ox, t.oy, smp, s);
          for (int c = 0; c < 3; ++c) r[c] = r[c] + s[c] * t.weight;
        }
        float* o = dst.pixel(x, y);
        o[0] = r[0], o[1] = r[1], o[2] = r[2], o[3] = 1.0f;
      }
  });
}

void extract_bright_variant(ConstImageView src, ImageView dst, float threshold, bool ge,
                            bool clamp01, int threads, const LumaRule& luma) {
  parallel_rows(src.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < src.width; ++x) {
        const float* s = src.pixel(x, y);
        float* d = dst.pixel(x, y);
        const float l = threshold_luminance(s[0], s[1], s[2], luma);
        const bool bright = ge ? l >= threshold : l > threshold;
        for (int c = 0; c < 3; ++c) {
          const float v = bright ? s[c] : 0.0f;
          d[c] = clamp01 ? std::min(std::max(v, 0.0f), 1.0f) : v;
        }
        d[3] = 1.0f;
      }
  });
}

void flip_vertically(Image& img) {
  const std::size_t row = std::size_t(img.width()) * kChannels;
  for (int y = 0; y < img.height() / 2; ++y)
    std::swap_ranges(img.view().row(y), img.view().row(y) + row, img.view().row(img.height() - 1 - y));
}

void swap_red_blue(Image& img) {
  for (std::size_t i = 0; i < img.pixel_count(); ++i) std::swap(img.data()[i * 4], img.data()[i * 4 + 2]);
}

}  // namespace bloomref::parity
