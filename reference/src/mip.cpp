// The mip-chain stages (mip.h). Offsets, weights and groups are seed 003's
// (FragShader_BloomFilter), written as in gpu/shaders/downsample.glsl and upsample_tent.glsl.
#include "bloomref/mip.h"

#include <algorithm>
#include <cmath>

#include "bloomref/parallel.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"

namespace bloomref {
namespace {

constexpr int kDownTaps = 13;
constexpr int kDownOffset[kDownTaps][2] = {{0, 0},   {-1, -1}, {1, -1}, {1, 1},  {-1, 1},
                                           {-2, -2}, {0, -2},  {2, -2}, {2, 0},  {2, 2},
                                           {0, 2},   {-2, 2},  {-2, 0}};
constexpr float kDownWeight[kDownTaps] = {0.125f,   0.125f,  0.125f,   0.125f,  0.125f,
                                          0.03125f, 0.0625f, 0.03125f, 0.0625f, 0.03125f,
                                          0.0625f,  0.03125f, 0.0625f};
constexpr int kGroups[5][4] = {{1, 2, 3, 4}, {5, 6, 0, 12}, {6, 7, 8, 0}, {0, 8, 9, 10},
                               {12, 0, 10, 11}};
constexpr float kGroupWeight[5] = {0.5f, 0.125f, 0.125f, 0.125f, 0.125f};

constexpr int kTentTaps = 9;
constexpr int kTentOffset[kTentTaps][2] = {{0, 0}, {-1, -1}, {0, -1}, {1, -1}, {1, 0},
                                           {1, 1}, {0, 1},   {-1, 1}, {-1, 0}};
constexpr float kTentWeight[kTentTaps] = {0.25f,  0.0625f, 0.125f,  0.0625f, 0.125f,
                                          0.0625f, 0.125f, 0.0625f, 0.125f};

// One lookup of `src` for target texel (x, y) of a tw x th target, offset (ox, oy) source
// texels: f32 as the shader computes uv + o * texel; f64 exactly in texel units.
void lookup(BasicView<const float> src, int x, int y, int tw, int th, int ox, int oy, int bits,
            float out[3]) {
  const float u = texel_centre(x, tw), v = texel_centre(y, th);
  const float tx = 1.0f / static_cast<float>(src.width), ty = 1.0f / static_cast<float>(src.height);
  const float s = u + static_cast<float>(ox) * tx, t = v + static_cast<float>(oy) * ty;
  sample_rgb(src, gl_axis_tap(s, src.width, bits), gl_axis_tap(t, src.height, bits), out);
}

void lookup(BasicView<const double> src, int x, int y, int tw, int th, int ox, int oy, int,
            double out[3]) {
  const double u = (x + 0.5) * src.width / tw - 0.5 + ox;
  const double v = (y + 0.5) * src.height / th - 0.5 + oy;
  sample_rgb(src, exact_axis_tap(u, src.width), exact_axis_tap(v, src.height), out);
}

}  // namespace

const std::vector<MipTap>& downsample_taps() {
  static const std::vector<MipTap> t = [] {
    std::vector<MipTap> v;
    for (int i = 0; i < kDownTaps; ++i) v.push_back({kDownOffset[i][0], kDownOffset[i][1], kDownWeight[i]});
    return v;
  }();
  return t;
}

const std::vector<std::vector<int>>& karis_groups() {
  static const std::vector<std::vector<int>> g = [] {
    std::vector<std::vector<int>> v;
    for (const auto& grp : kGroups) v.push_back({grp[0], grp[1], grp[2], grp[3]});
    return v;
  }();
  return g;
}

const std::vector<float>& karis_group_weights() {
  static const std::vector<float> w(kGroupWeight, kGroupWeight + 5);
  return w;
}

const std::vector<MipTap>& tent_taps() {
  static const std::vector<MipTap> t = [] {
    std::vector<MipTap> v;
    for (int i = 0; i < kTentTaps; ++i) v.push_back({kTentOffset[i][0], kTentOffset[i][1], kTentWeight[i]});
    return v;
  }();
  return t;
}

void mip_lookup(ConstImageView src, int x, int y, int tw, int th, int ox, int oy,
                int subtexel_bits, float out[3]) {
  lookup(src, x, y, tw, th, ox, oy, subtexel_bits, out);
}

std::vector<LevelSize> mip_levels(int width, int height, int levels) {
  std::vector<LevelSize> out;
  int w = width, h = height;
  for (int k = 0; k < levels; ++k) {
    if (w == 1 && h == 1 && !out.empty()) break;  // out of pixels (a 1x1 image keeps one level)
    w = std::max(1, w / 2);
    h = std::max(1, h / 2);
    out.push_back({w, h});
  }
  return out;
}

template <class T>
void downsample(BasicView<const T> src, BasicView<T> dst, const DownsampleOptions& opt,
                int threads) {
  const T threshold = static_cast<T>(opt.threshold);
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        T q[kDownTaps][3];
        for (int i = 0; i < kDownTaps; ++i) {
          lookup(src, x, y, dst.width, dst.height, kDownOffset[i][0], kDownOffset[i][1],
                 opt.subtexel_bits, q[i]);
          if (opt.first && luminance(q[i][0], q[i][1], q[i][2]) < threshold)
            q[i][0] = q[i][1] = q[i][2] = T(0);
        }
        T r[3] = {0, 0, 0};
        if (opt.first && opt.karis) {
          T w[kDownTaps];
          // Karis weight 1 / (1 + L): negative L (out-of-gamut input) would make it grow
          // without bound and divide by zero at L = -1; the weight uses max(L, 0) (at most 1).
          for (int i = 0; i < kDownTaps; ++i)
            w[i] = T(1) / (T(1) + std::max(luminance(q[i][0], q[i][1], q[i][2]), T(0)));
          for (int g = 0; g < 5; ++g) {
            T s = T(0);
            for (int j = 0; j < 4; ++j) s = s + w[kGroups[g][j]];
            for (int j = 0; j < 4; ++j) {
              const int i = kGroups[g][j];
              const T f = static_cast<T>(kGroupWeight[g]) * w[i] / s;
              for (int c = 0; c < 3; ++c) r[c] = r[c] + f * q[i][c];
            }
          }
        } else {
          for (int i = 0; i < kDownTaps; ++i)
            for (int c = 0; c < 3; ++c) r[c] = r[c] + q[i][c] * static_cast<T>(kDownWeight[i]);
        }
        T* d = dst.pixel(x, y);
        d[0] = r[0];
        d[1] = r[1];
        d[2] = r[2];
        d[3] = T(1);
      }
  });
}

template <class T>
void upsample_tent(BasicView<const T> small, BasicView<const T> current, BasicView<T> dst,
                   int subtexel_bits, int threads) {
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        T r[3] = {0, 0, 0};
        if (!current.empty())
          for (int c = 0; c < 3; ++c) r[c] = current.pixel(x, y)[c];
        for (int i = 0; i < kTentTaps; ++i) {
          T s[3];
          lookup(small, x, y, dst.width, dst.height, kTentOffset[i][0], kTentOffset[i][1],
                 subtexel_bits, s);
          for (int c = 0; c < 3; ++c) r[c] = r[c] + s[c] * static_cast<T>(kTentWeight[i]);
        }
        T* d = dst.pixel(x, y);
        d[0] = r[0];
        d[1] = r[1];
        d[2] = r[2];
        d[3] = T(1);
      }
  });
}

template void downsample<float>(BasicView<const float>, BasicView<float>,
                                const DownsampleOptions&, int);
template void downsample<double>(BasicView<const double>, BasicView<double>,
                                 const DownsampleOptions&, int);
template void upsample_tent<float>(BasicView<const float>, BasicView<const float>,
                                   BasicView<float>, int, int);
template void upsample_tent<double>(BasicView<const double>, BasicView<const double>,
                                    BasicView<double>, int, int);

}  // namespace bloomref
