// The mip-chain stages (mip.h). Offsets, weights and groups are seed 003's
// (FragShader_BloomFilter), written as in gpu/shaders/downsample.glsl and upsample_tent.glsl.
#include "bloomref/mip.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>

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

// Unity URP's Gaussian pyramid (Bloom.shader, FragBlurH and FragBlurV): offsets in units of
// the horizontal step and in texels, f32 as the shader's literals and f64 as written.
constexpr float kGaussHOffset[9] = {-4.0f, -3.0f, -2.0f, -1.0f, 0.0f, 1.0f, 2.0f, 3.0f, 4.0f};
constexpr float kGaussHWeight[9] = {0.01621622f, 0.05405405f, 0.12162162f,
                                    0.19459459f, 0.22702703f, 0.19459459f,
                                    0.12162162f, 0.05405405f, 0.01621622f};
constexpr double kGaussHWeight64[9] = {0.01621622, 0.05405405, 0.12162162, 0.19459459, 0.22702703,
                                       0.19459459, 0.12162162, 0.05405405, 0.01621622};
constexpr float kGaussVOffset[5] = {-3.23076923f, -1.38461538f, 0.0f, 1.38461538f, 3.23076923f};
constexpr double kGaussVOffset64[5] = {-3.23076923, -1.38461538, 0.0, 1.38461538, 3.23076923};
constexpr float kGaussVWeight[5] = {0.07027027f, 0.31621622f, 0.22702703f, 0.31621622f,
                                    0.07027027f};
constexpr double kGaussVWeight64[5] = {0.07027027, 0.31621622, 0.22702703, 0.31621622,
                                       0.07027027};

// The distance of one offset unit in texture coordinates: 1 / `size` (a source texture's size,
// or the host's float size), or a radius given in texture coordinates.
struct Step {
  float size = 0.0f, radius = 0.0f;
  float f32() const { return radius > 0.0f ? radius : 1.0f / size; }
  double f64() const { return radius > 0.0f ? double(radius) : 1.0 / double(size); }
};

// One axis of a lookup for target texel x of a tn-texel target axis, offset o steps on an
// sn-texel source axis: f32 as the shader computes uv + o * step; f64 exactly in texel units.
AxisTap<float> axis_lookup(int x, int tn, int sn, int o, int bits, Step step, float) {
  const float u = texel_centre(x, tn);
  return gl_axis_tap(u + static_cast<float>(o) * step.f32(), sn, bits);
}

AxisTap<double> axis_lookup(int x, int tn, int sn, int o, int, Step step, double) {
  if (step.radius == 0.0f && step.size == float(sn))  // integer texels: exact as before
    return exact_axis_tap((x + 0.5) * sn / tn - 0.5 + o, sn);
  return exact_axis_tap(((x + 0.5) / tn + o * step.f64()) * sn - 0.5, sn);
}

Step texture_step(int sn) { return {static_cast<float>(sn), 0.0f}; }

// A lookup's two axes depend on one coordinate and one offset each, so a stage computes them
// once into tables (with axis_lookup, so the bits are the same) instead of per texel and tap.
template <class T>
class AxisTable {
 public:
  AxisTable(int tn, int sn, int o_min, int o_max, int bits, Step step) : n_(tn), o_min_(o_min) {
    taps_.reserve(std::size_t(o_max - o_min + 1) * tn);
    for (int o = o_min; o <= o_max; ++o)
      for (int x = 0; x < tn; ++x) taps_.push_back(axis_lookup(x, tn, sn, o, bits, step, T()));
  }
  const AxisTap<T>& at(int x, int o) const { return taps_[std::size_t(o - o_min_) * n_ + x]; }

 private:
  int n_, o_min_;
  std::vector<AxisTap<T>> taps_;
};

template <class T>
struct Lookups {
  AxisTable<T> x, y;
  Lookups(BasicView<const T> src, int tw, int th, int reach, int bits, Step sx, Step sy)
      : x(tw, src.width, -reach, reach, bits, sx), y(th, src.height, -reach, reach, bits, sy) {}
  Lookups(BasicView<const T> src, int tw, int th, int reach, int bits)
      : Lookups(src, tw, th, reach, bits, texture_step(src.width), texture_step(src.height)) {}
  void sample(BasicView<const T> src, int tx, int ty, int ox, int oy, T out[3]) const {
    sample_rgb(src, x.at(tx, ox), y.at(ty, oy), out);
  }
};

// A stage's texel: RGB and alpha 1.
template <class T>
void write_rgb1(T* d, const T r[3]) {
  d[0] = r[0];
  d[1] = r[1];
  d[2] = r[2];
  d[3] = T(1);
}

// Where a stage's texel is left out (its mask is 0), it is written (+0, +0, +0, 1): what it
// computes when every texel it reads is +0 (mip_support).
template <class T>
void write_zero(T* d) {
  const T zero[3] = {T(0), T(0), T(0)};
  write_rgb1(d, zero);
}

// The lookups of one axis at offsets given in texture coordinates (f32 as the shader computes
// them, f64 as written), for every target texel: uv + offset, then GL_LINEAR.
template <class T>
class OffsetTable {
 public:
  OffsetTable(int tn, int sn, const std::vector<float>& off32, const std::vector<double>& off64,
              int bits)
      : n_(tn) {
    taps_.reserve(off32.size() * std::size_t(tn));
    for (std::size_t i = 0; i < off32.size(); ++i)
      for (int x = 0; x < tn; ++x) {
        if constexpr (std::is_same_v<T, float>)
          taps_.push_back(gl_axis_tap(texel_centre(x, tn) + off32[i], sn, bits));
        else
          taps_.push_back(exact_axis_tap(((x + 0.5) / tn + off64[i]) * sn - 0.5, sn));
      }
  }
  const AxisTap<T>& at(int x, std::size_t i) const { return taps_[i * std::size_t(n_) + x]; }

 private:
  int n_;
  std::vector<AxisTap<T>> taps_;
};

// Unity URP's FragBlurH into `hv` (the level's size), unrounded.
template <class T>
void gaussian_h_pass(BasicView<const T> src, BasicView<T> hv, const DownsampleOptions& opt,
                     int threads) {
  const int tw = hv.width, th = hv.height, bits = opt.subtexel_bits;
  // float texelSize = _BlitTex_TexelSize.x * 2.0; uv +- texelSize * i.
  const float step = (1.0f / static_cast<float>(src.width)) * 2.0f;
  std::vector<float> ox32;
  std::vector<double> ox64;
  for (float o : kGaussHOffset) {
    ox32.push_back(o < 0 ? -(step * -o) : step * o);
    ox64.push_back(2.0 * double(o) / src.width);
  }
  const OffsetTable<T> xs(tw, src.width, ox32, ox64, bits);
  const OffsetTable<T> ys(th, src.height, {0.0f}, {0.0}, bits);
  parallel_rows(th, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < tw; ++x) {
        T r[3] = {0, 0, 0};
        for (std::size_t i = 0; i < 9; ++i) {
          T q[3] = {};
          sample_rgb(src, xs.at(x, i), ys.at(y, 0), q);
          const T w = std::is_same_v<T, float> ? T(kGaussHWeight[i]) : T(kGaussHWeight64[i]);
          for (int c = 0; c < 3; ++c) r[c] = r[c] + q[c] * w;
        }
        write_rgb1(hv.pixel(x, y), r);
      }
  });
}

// Unity URP's Gaussian pyramid level (FragBlurH, stored as `opt.intermediate`, then FragBlurV).
template <class T>
void downsample_gaussian(BasicView<const T> src, BasicView<T> dst, const DownsampleOptions& opt,
                         int threads) {
  const int tw = dst.width, th = dst.height, bits = opt.subtexel_bits;
  BasicImage<T> h(tw, th);
  gaussian_h_pass(src, h.view(), opt, threads);
  store(h.view(), opt.intermediate, opt.rounding, threads);
  const BasicView<const T> hc = h.cview();
  // float texelSize = _BlitTex_TexelSize.y; uv +- texelSize * o.
  const float step = 1.0f / static_cast<float>(th);
  std::vector<float> oy32;
  std::vector<double> oy64;
  for (int j = 0; j < 5; ++j) {
    const float o = kGaussVOffset[j];
    oy32.push_back(o < 0 ? -(step * -o) : step * o);
    oy64.push_back(kGaussVOffset64[j] / th);
  }
  const OffsetTable<T> xs(tw, tw, {0.0f}, {0.0}, bits);
  const OffsetTable<T> ys(th, th, oy32, oy64, bits);
  parallel_rows(th, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < tw; ++x) {
        T r[3] = {0, 0, 0};
        for (std::size_t j = 0; j < 5; ++j) {
          T q[3] = {};
          sample_rgb(hc, xs.at(x, 0), ys.at(y, j), q);
          const T w = std::is_same_v<T, float> ? T(kGaussVWeight[j]) : T(kGaussVWeight64[j]);
          for (int c = 0; c < 3; ++c) r[c] = r[c] + q[c] * w;
        }
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}

// One pass of three.js's separable blur into `dst` (its uniform invSize is 1 / dst's size; the
// taps one texel of dst apart along `horizontal`'s axis), unrounded.
template <class T>
void separable_pass(BasicView<const T> src, BasicView<T> dst, int radius, double sigma,
                    bool normalise, bool horizontal, int bits, int threads) {
  const int tw = dst.width, th = dst.height;
  const std::vector<float> c = separable_coefficients(radius, sigma, normalise);
  // uvOffset = direction * invSize * x: the step (exact times 1 or 0), then times i; the lookups
  // at uv + uvOffset and uv - uvOffset.
  const int n = horizontal ? tw : th;
  const float inv = 1.0f / static_cast<float>(n);
  std::vector<float> o32 = {0.0f};
  std::vector<double> o64 = {0.0};
  for (int i = 1; i < radius; ++i) {
    const float o = inv * static_cast<float>(i);
    o32.insert(o32.end(), {o, -o});
    o64.insert(o64.end(), {double(i) / n, -double(i) / n});
  }
  const OffsetTable<T> along(n, horizontal ? src.width : src.height, o32, o64, bits);
  const OffsetTable<T> across(horizontal ? th : tw, horizontal ? src.height : src.width, {0.0f},
                              {0.0}, bits);
  parallel_rows(th, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < tw; ++x) {
        const int a = horizontal ? x : y, b = horizontal ? y : x;
        auto sample = [&](std::size_t i, T out[3]) {
          if (horizontal) sample_rgb(src, along.at(a, i), across.at(b, 0), out);
          else sample_rgb(src, across.at(b, 0), along.at(a, i), out);
        };
        T r[3] = {}, q[3] = {}, m[3] = {};
        sample(0, q);
        for (int ch = 0; ch < 3; ++ch) r[ch] = q[ch] * static_cast<T>(c[0]);
        for (int i = 1; i < radius; ++i) {
          sample(std::size_t(2 * i - 1), q);
          sample(std::size_t(2 * i), m);
          const T w = static_cast<T>(c[std::size_t(i)]);
          for (int ch = 0; ch < 3; ++ch) r[ch] = r[ch] + (q[ch] + m[ch]) * w;
        }
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}

// three.js's blurred mip: along x into the level's size, stored as `opt.intermediate`, then
// along y.
template <class T>
void downsample_separable(BasicView<const T> src, BasicView<T> dst, const DownsampleOptions& opt,
                          int threads) {
  BasicImage<T> h(dst.width, dst.height);
  separable_pass(src, h.view(), opt.kernel_radius, opt.kernel_sigma, opt.kernel_normalise, true, opt.subtexel_bits,
                 threads);
  store(h.view(), opt.intermediate, opt.rounding, threads);
  separable_pass(h.cview(), dst, opt.kernel_radius, opt.kernel_sigma, opt.kernel_normalise, false, opt.subtexel_bits,
                 threads);
}

}  // namespace

std::vector<float> separable_coefficients(int radius, double given_sigma, bool normalise) {
  const double sigma = given_sigma > 0 ? given_sigma : radius / 3.0;
  std::vector<double> w;
  double sum = 0.0;
  for (int i = 0; i < radius; ++i) {
    w.push_back(0.39894 * std::exp(-0.5 * i * i / (sigma * sigma)) / sigma);
    sum += i == 0 ? w.back() : 2.0 * w.back();
  }
  std::vector<float> c;
  for (double v : w) c.push_back(static_cast<float>(normalise ? v / sum : v));
  return c;
}

double level_sigma(const BloomParams& p, int k) {
  const std::size_t i = std::size_t(k - 2);
  return k >= 2 && i < p.level_sigmas.size() ? double(p.level_sigmas[i]) : 0.0;
}

template <class T>
T smoothstep_factor(T luminance, float threshold, float width) {
  const float e1 = threshold + width;
  const T t = std::clamp((luminance - T(threshold)) / (T(e1) - T(threshold)), T(0), T(1));
  return t * t * (T(3) - T(2) * t);
}
template float smoothstep_factor<float>(float, float, float);
template double smoothstep_factor<double>(double, float, float);

float sum_factor(float f, float radius) {
  const float mirror = 1.2f - f;
  return f * (1.0f - radius) + mirror * radius;
}

template <class T>
void sum_levels(const std::vector<BasicView<const T>>& levels, BasicView<T> dst,
                const std::vector<float>& factors, float radius, float strength, int subtexel_bits,
                int threads) {
  std::vector<Lookups<T>> lookups;
  std::vector<T> f;
  for (std::size_t i = 0; i < levels.size(); ++i) {
    lookups.emplace_back(levels[i], dst.width, dst.height, 0, subtexel_bits);
    f.push_back(static_cast<T>(sum_factor(factors[i], radius)));
  }
  const T s = static_cast<T>(strength);
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        T r[3] = {0, 0, 0};
        for (std::size_t i = 0; i < levels.size(); ++i) {
          T q[3] = {};
          lookups[i].sample(levels[i], x, y, 0, 0, q);
          for (int c = 0; c < 3; ++c) r[c] = i == 0 ? f[i] * q[c] : r[c] + f[i] * q[c];
        }
        for (int c = 0; c < 3; ++c) r[c] = r[c] * s;
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}
template void sum_levels<float>(const std::vector<BasicView<const float>>&, BasicView<float>,
                                const std::vector<float>&, float, float, int, int);
template void sum_levels<double>(const std::vector<BasicView<const double>>&, BasicView<double>,
                                 const std::vector<float>&, float, float, int, int);

const std::vector<MipTap>& box4_taps() {
  static const std::vector<MipTap> t = {{-1, -1, 0.25f}, {1, -1, 0.25f}, {-1, 1, 0.25f},
                                        {1, 1, 0.25f}};
  return t;
}

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

const std::vector<GaussianTap>& gaussian_down_h_taps() {
  static const std::vector<GaussianTap> t = [] {
    std::vector<GaussianTap> v;
    for (int i = 0; i < 9; ++i) v.push_back({kGaussHOffset[i], kGaussHWeight[i]});
    return v;
  }();
  return t;
}

const std::vector<GaussianTap>& gaussian_down_v_taps() {
  static const std::vector<GaussianTap> t = [] {
    std::vector<GaussianTap> v;
    for (int i = 0; i < 5; ++i) v.push_back({kGaussVOffset[i], kGaussVWeight[i]});
    return v;
  }();
  return t;
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
  sample_rgb(src, axis_lookup(x, tw, src.width, ox, subtexel_bits, texture_step(src.width), float()),
             axis_lookup(y, th, src.height, oy, subtexel_bits, texture_step(src.height), float()),
             out);
}

DownsampleOptions downsample_options(const BloomParams& p, int k, int width, int height,
                                     int subtexel_bits) {
  DownsampleOptions o;
  o.first = k == 1;
  o.threshold = p.threshold;
  o.luma = luma_rule(p);
  o.karis = p.karis && k == 1;
  o.subtexel_bits = subtexel_bits;
  o.threshold_taps = p.prefilter == Prefilter::per_lookup;  // the others: no tap threshold
  o.soft_knee = p.prefilter == Prefilter::soft_knee && k == 1;
  o.knee = p.threshold * std::clamp(p.knee, 0.0f, 1.0f);  // Bevy's extract_component
  o.karis_form = p.karis_form;
  o.knee_form = p.knee_form;
  o.first_filter = p.first_downsample;
  o.clamp_max = k == 1 ? p.clamp_max : 0.0f;
  o.filter = p.downsample;
  o.intermediate = p.level_storage();
  o.smoothstep = p.prefilter == Prefilter::smoothstep && k == 1;
  o.smooth_width = p.smooth_width;
  if (p.downsample == DownsampleFilter::separable && k >= 2 &&
      std::size_t(k - 2) < p.level_kernels.size())
    o.kernel_radius = p.level_kernels[std::size_t(k - 2)];
  o.kernel_sigma = level_sigma(p, k);
  o.kernel_normalise = p.level_normalise;
  if (p.texel_step == TexelStep::halved_float) {
    o.step_width = halved_size(width, k - 1);
    o.step_height = halved_size(height, k - 1);
  } else if (p.texel_step == TexelStep::target) {
    // 0.5 / size: the step of a source twice the target's size (exactly, in float).
    const LevelSize l = chain_levels(p, width, height)[std::size_t(k - 1)];
    o.step_width = 2.0f * static_cast<float>(l.width);
    o.step_height = 2.0f * static_cast<float>(l.height);
  }
  return o;
}

float halved_size(int n, int k) {
  float s = static_cast<float>(n);
  for (int i = 0; i < k; ++i) s *= 0.5f;
  return s;
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

std::vector<LevelSize> chain_levels(const BloomParams& p, int width, int height) {
  if (p.level_count == LevelCount::threejs) {
    // BloomNode.js setSize: resx = Math.round(width / 2) (halves round up), the bright target
    // and mip 0 at it, each next mip Math.round(resx / 2); nMips blurred mips.
    auto half = [](int n) { return (n + 1) / 2; };
    std::vector<LevelSize> out = {{half(width), half(height)}};
    LevelSize l = out.front();
    for (int k = 0; k < p.levels; ++k) {
      out.push_back(l);
      l = {half(l.width), half(l.height)};
    }
    return out;
  }
  if (p.level_count == LevelCount::unity) {
    // PostProcessPass.SetupBloom: tw = width >> 1, th = height >> 1; iterations =
    // FloorToInt(Mathf.Log(max(tw, th), 2f) - 1) (Math.Log in double, then float); mipCount =
    // Clamp(iterations, 1, k_MaxPyramidSize); each level Max(1, n >> 1) of the one above.
    const int top = std::max(width >> 1, height >> 1);
    int count = 1;
    if (top > 0) {
      const float log2 = static_cast<float>(std::log(double(top)) / std::log(2.0));
      count = static_cast<int>(std::floor(log2 - 1.0f));
    }
    count = std::clamp(count, 1, p.levels);
    std::vector<LevelSize> out;
    int w = width, h = height;
    for (int k = 0; k < count; ++k) {
      w = std::max(1, w >> 1);
      h = std::max(1, h >> 1);
      out.push_back({w, h});
    }
    return out;
  }
  if (p.first_level_height == 0) return mip_levels(width, height, p.levels);
  // Bevy: mip_height_ratio = max_mip_dimension as f32 / viewport.y as f32, then
  // (viewport.as_vec2() * ratio).round() (half away from zero), at least 1.
  const float ratio = static_cast<float>(p.first_level_height) / static_cast<float>(height);
  const int w0 = std::max(1, static_cast<int>(std::round(static_cast<float>(width) * ratio)));
  const int h0 = std::max(1, static_cast<int>(std::round(static_cast<float>(height) * ratio)));
  std::vector<LevelSize> out;
  for (int k = 0; k < p.levels; ++k) {
    const LevelSize l{std::max(1, w0 >> k), std::max(1, h0 >> k)};
    if (!out.empty() && out.back().width == 1 && out.back().height == 1) break;
    out.push_back(l);
  }
  return out;
}

LevelBlend level_blend(const BloomParams& p, int k, int levels) {
  LevelBlend b;
  b.combine = p.level_combine;
  if (p.level_weights == LevelWeights::one) return b;
  if (p.level_weights == LevelWeights::constant) {
    b.weight = p.level_weight;
    return b;
  }
  // bevyengine/bevy crates/bevy_post_process/src/bloom/mod.rs, compute_blend_factor, in f32:
  // up.k reads level k + 1, Bevy's mip k (its mip 0 is down.1); max_mip the last level's index.
  const float mip = static_cast<float>(k), max_mip = static_cast<float>(levels - 1);
  const float x = max_mip > 0.0f ? mip / max_mip : 0.0f;
  float boost = (1.0f - std::pow(1.0f - x, 1.0f / (1.0f - p.low_frequency_boost_curvature))) *
                p.low_frequency_boost;
  const float high_pass =
      1.0f - std::clamp((x - p.high_pass_frequency) / p.high_pass_frequency, 0.0f, 1.0f);
  if (p.level_combine == LevelCombine::mix) boost *= 1.0f - p.strength;
  b.weight = (p.strength + boost) * high_pass;
  return b;
}

template <class T>
T soft_knee_factor(const T rgb[3], float threshold, float knee, KneeForm form) {
  if (form == KneeForm::unity) {
    // Bloom.shader, FragPrefilter, with _Params.z = threshold and .w = knee.
    const T t = T(threshold), kn = T(knee);
    const T brightness = std::max(rgb[0], std::max(rgb[1], rgb[2]));
    T softness = std::clamp(brightness - t + kn, T(0), T(2) * kn);
    softness = (softness * softness) / (T(4) * kn + T(1e-4f));
    return std::max(brightness - t, softness) / std::max(brightness, T(1e-4f));
  }
  // The host's threshold_precomputations (bevy settings.rs, extract_component), in f32.
  const T x = T(threshold), y = T(threshold - knee), z = T(2.0f * knee),
          w = T(0.25f / (knee + 0.00001f));
  const T brightness = std::max(rgb[0], std::max(rgb[1], rgb[2]));
  T softness = std::clamp(brightness - y, T(0), z);
  softness = softness * softness * w;
  const T contribution = std::max(brightness - x, softness);
  return contribution / std::max(brightness, T(0.00001f));
}

template float soft_knee_factor<float>(const float[3], float, float, KneeForm);
template double soft_knee_factor<double>(const double[3], float, float, KneeForm);

// The group forms of the Karis average, in their shaders' order: the article's
// (6.new_downsample.fs, case 0) and Bevy's (bloom.wesl, downsample_first). Their groups in tap
// indices: a b d e, b c e f, d e g h, e f h i (the corners and edges around the centre, uv y
// counting down the image as the rows do) and j k l m (the inner four). Each group is the sum
// of its four lookups times its weight / 4, then times 1 / (1 + luma(group)); the five summed.
template <class T, class Luma>
void karis_group_sum(const T q[13][3], T r[3], Luma luma) {
  // Tap indices of kDownOffset: a (-2,+2) = 11, b (0,+2) = 10, c (2,2) = 9, d (-2,0) = 12,
  // e = 0, f (2,0) = 8, g (-2,-2) = 5, h (0,-2) = 6, i (2,-2) = 7, j (-1,+1) = 4, k (1,1) = 3,
  // l (-1,-1) = 1, m (1,-1) = 2.
  constexpr int kGroup[5][4] = {{11, 10, 12, 0}, {10, 9, 0, 8}, {12, 0, 5, 6}, {0, 8, 6, 7},
                                {4, 3, 1, 2}};
  const T scale[5] = {T(0.125f / 4.0f), T(0.125f / 4.0f), T(0.125f / 4.0f), T(0.125f / 4.0f),
                      T(0.5f / 4.0f)};
  for (int g = 0; g < 5; ++g) {
    T v[3];
    for (int c = 0; c < 3; ++c) {
      const int* t = kGroup[g];
      v[c] = (((q[t[0]][c] + q[t[1]][c]) + q[t[2]][c]) + q[t[3]][c]) * scale[g];
    }
    const T w = T(1) / (T(1) + luma(v));
    for (int c = 0; c < 3; ++c) r[c] = r[c] + v[c] * w;
  }
}

// The article's: luma the Rec. 601 weights of pow(group, 1 / 2.2), times 0.25; then
// max(r, 0.0001). A group with a negative channel makes pow, and so r, NaN; GLSL leaves max of a
// NaN undefined, and the devices measured return the other operand (IEEE maxNum: llvmpipe's GL
// and lavapipe's Vulkan store 0.0001 there, WideColorGamut.exr), as fmax does.
template <class T>
void karis_group_srgb(const T q[13][3], T r[3]) {
  const T inv_gamma = static_cast<T>(1.0f / 2.2f);  // the shader's const float 1.0 / 2.2
  karis_group_sum(q, r, [&](const T v[3]) {
    return (std::pow(v[0], inv_gamma) * T(0.299f) + std::pow(v[1], inv_gamma) * T(0.587f) +
            std::pow(v[2], inv_gamma) * T(0.114f)) *
           T(0.25f);
  });
  for (int c = 0; c < 3; ++c) r[c] = std::fmax(r[c], T(0.0001f));
}

// Bevy's: luma the Rec. 709 luminance of the group in linear colour, / 4; then the sum clamped
// to [0.0001, 3.40282347e37] (WGSL's clamp, min(max(.)), with maxNum's NaN as above).
template <class T>
void karis_group_linear(const T q[13][3], T r[3]) {
  karis_group_sum(q, r, [](const T v[3]) {
    return (v[0] * T(0.2126f) + v[1] * T(0.7152f) + v[2] * T(0.0722f)) / T(4);
  });
  for (int c = 0; c < 3; ++c) r[c] = std::fmin(std::fmax(r[c], T(0.0001f)), T(3.40282347e37f));
}

// The first level's clamp (Unity's ClampMax) and soft threshold, where they apply.
template <class T>
void finish_first(T r[3], const DownsampleOptions& opt) {
  if (opt.first && opt.clamp_max > 0.0f)
    for (int c = 0; c < 3; ++c) r[c] = std::min(T(opt.clamp_max), r[c]);
  if (opt.soft_knee) {
    const T f = soft_knee_factor(r, opt.threshold, opt.knee, opt.knee_form);
    for (int c = 0; c < 3; ++c) r[c] = r[c] * f;
  }
  if (opt.smoothstep) {
    // mix(vec4(0), texel, alpha): 0 (1 - alpha) + texel alpha, the product alone.
    const T a = smoothstep_factor(threshold_luminance(r[0], r[1], r[2], opt.luma), opt.threshold,
                                  opt.smooth_width);
    for (int c = 0; c < 3; ++c) r[c] = r[c] * a;
  }
}

// Unity URP's FragPrefilter: one lookup at the target texel's centre.
template <class T>
void downsample_bilinear(BasicView<const T> src, BasicView<T> dst, const DownsampleOptions& opt,
                         int threads) {
  const Lookups<T> lookups(src, dst.width, dst.height, 0, opt.subtexel_bits);
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        T r[3] = {};
        lookups.sample(src, x, y, 0, 0, r);
        finish_first(r, opt);
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}

template <class T>
void downsample(BasicView<const T> src, BasicView<T> dst, const DownsampleOptions& opt,
                int threads) {
  if (!opt.first && opt.filter == DownsampleFilter::gaussian)
    return downsample_gaussian(src, dst, opt, threads);
  if (!opt.first && opt.filter == DownsampleFilter::separable)
    return downsample_separable(src, dst, opt, threads);
  if (opt.first && opt.first_filter == FirstDownsample::bilinear)
    return downsample_bilinear(src, dst, opt, threads);
  const T threshold = static_cast<T>(opt.threshold);
  const LumaWeights<T> lw = luma_weights<T>(opt.luma.weights);
  const bool thresholded = opt.first && opt.threshold_taps;
  const bool karis = opt.first && opt.karis;
  const Step sx{opt.step_width > 0 ? opt.step_width : float(src.width), 0.0f};
  const Step sy{opt.step_height > 0 ? opt.step_height : float(src.height), 0.0f};
  const Lookups<T> lookups(src, dst.width, dst.height, 2, opt.subtexel_bits, sx, sy);
  // The 4-tap box: its four taps in order, each times 0.25 (a power of two: the same bits as
  // the shaders' sum of the four times 0.25).
  const bool box = opt.first ? opt.first_filter == FirstDownsample::box4
                             : opt.filter == DownsampleFilter::box4;
  const std::vector<MipTap>& box_taps = box4_taps();
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        if (opt.active && !opt.active[std::size_t(y) * dst.width + x]) {
          write_zero(dst.pixel(x, y));
          continue;
        }
        if (box) {
          T r[3] = {0, 0, 0};
          for (const MipTap& t : box_taps) {
            T q[3] = {};
            lookups.sample(src, x, y, t.ox, t.oy, q);
            if (thresholded && threshold_luminance(q[0], q[1], q[2], opt.luma) < threshold)
              q[0] = q[1] = q[2] = T(0);
            for (int c = 0; c < 3; ++c) r[c] = r[c] + q[c] * static_cast<T>(t.weight);
          }
          finish_first(r, opt);
          write_rgb1(dst.pixel(x, y), r);
          continue;
        }
        T q[kDownTaps][3];
        for (int i = 0; i < kDownTaps; ++i) {
          lookups.sample(src, x, y, kDownOffset[i][0], kDownOffset[i][1], q[i]);
          if (thresholded && threshold_luminance(q[i][0], q[i][1], q[i][2], opt.luma) < threshold)
            q[i][0] = q[i][1] = q[i][2] = T(0);
        }
        T r[3] = {0, 0, 0};
        if (karis && opt.karis_form == KarisForm::group_srgb) {
          karis_group_srgb(q, r);
        } else if (karis && opt.karis_form == KarisForm::group_linear) {
          karis_group_linear(q, r);
        } else if (karis) {
          T w[kDownTaps];
          // Karis weight 1 / (1 + L): negative L (out-of-gamut input) would make it grow
          // without bound and divide by zero at L = -1; the weight uses max(L, 0) (at most 1).
          for (int i = 0; i < kDownTaps; ++i)
            w[i] = T(1) / (T(1) + std::max(luminance(q[i][0], q[i][1], q[i][2], lw), T(0)));
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
        finish_first(r, opt);
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}

template <class T>
void upsample_tent(BasicView<const T> small, BasicView<const T> current, BasicView<T> dst,
                   int subtexel_bits, int threads, const std::uint8_t* active, float radius,
                   LevelBlend blend, bool target_step, UpsampleFilter filter) {
  const bool plain = current.empty() || blend.plain();
  const bool lerp = !plain && blend.combine == LevelCombine::lerp;
  const int taps = filter == UpsampleFilter::bilinear ? 1 : kTentTaps;  // the centre tap first
  const T weight = static_cast<T>(blend.weight), keep = static_cast<T>(blend.kept());
  // 2 / size is 1 / (size / 2), one rounding of the same number.
  const Lookups<T> lookups =
      radius > 0.0f ? Lookups<T>(small, dst.width, dst.height, 1, subtexel_bits, {0.0f, radius},
                                 {0.0f, radius})
      : target_step ? Lookups<T>(small, dst.width, dst.height, 1, subtexel_bits,
                                 {0.5f * static_cast<float>(dst.width), 0.0f},
                                 {0.5f * static_cast<float>(dst.height), 0.0f})
                    : Lookups<T>(small, dst.width, dst.height, 1, subtexel_bits);
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        if (active && !active[std::size_t(y) * dst.width + x]) {
          write_zero(dst.pixel(x, y));
          continue;
        }
        T r[3] = {0, 0, 0};
        if (!current.empty() && plain)
          for (int c = 0; c < 3; ++c) r[c] = current.pixel(x, y)[c];
        for (int i = 0; i < taps; ++i) {
          T s[3] = {};  // sample_rgb writes all three; the init only quiets -Wuninitialized
          lookups.sample(small, x, y, kTentOffset[i][0], kTentOffset[i][1], s);
          const T w = taps == 1 ? T(1) : static_cast<T>(kTentWeight[i]);
          for (int c = 0; c < 3; ++c) r[c] = r[c] + s[c] * w;
        }
        if (lerp) {
          const T* d = current.pixel(x, y);
          for (int c = 0; c < 3; ++c) r[c] = d[c] + (r[c] - d[c]) * weight;
        } else if (!plain) {
          const T* d = current.pixel(x, y);
          for (int c = 0; c < 3; ++c)
            r[c] = r[c] * weight + d[c] * keep;  // keep is exactly 1 under add
        }
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}

template <class T>
void upscale_bilinear(BasicView<const T> small, BasicView<T> dst, int subtexel_bits, int threads) {
  const Lookups<T> lookups(small, dst.width, dst.height, 0, subtexel_bits);
  parallel_rows(dst.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < dst.width; ++x) {
        T r[3] = {};  // sample_rgb writes all three; the init only quiets -Wuninitialized
        lookups.sample(small, x, y, 0, 0, r);
        write_rgb1(dst.pixel(x, y), r);
      }
  });
}

template <class T>
bool mip_nothing_bright(BasicView<const T> scene, double threshold, int threads,
                        const LumaRule& luma) {
  if (!(threshold > 0.0)) return false;
  const LumaWeights<double> w = luma_weights<double>(luma.weights);
  const bool linear = luma.space == LumaSpace::linear;
  std::vector<std::uint8_t> bright(scene.height, 0);
  parallel_rows(scene.height, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const T* p = scene.row(y);
      for (int x = 0; x < scene.width && !bright[y]; ++x, p += kChannels) {
        const double r = linear ? p[0] : luma_encode(double(p[0]), luma),
                     g = linear ? p[1] : luma_encode(double(p[1]), luma),
                     b = linear ? p[2] : luma_encode(double(p[2]), luma);
        const double l = w.r * r + w.g * g + w.b * b;
        const double m = std::fabs(r) + std::fabs(g) + std::fabs(b);
        // !(a < b) also catches NaN and Inf.
        bright[y] = !(l + 1e-4 * m < threshold);
      }
    }
  });
  return std::find(bright.begin(), bright.end(), std::uint8_t(1)) == bright.end();
}

template <class T>
std::size_t mip_support(const std::uint8_t* src_mask, int sw, int sh, const std::uint8_t* also,
                        int tw, int th, int reach, int bits, std::uint8_t* out, int threads) {
  // Target texel (x, y) reads source texels inside [xlo(x), xhi(x)] x [ylo(y), yhi(y)] (both
  // texels of every lookup at offsets -reach..reach): a box OR, by prefix counts along each
  // source row, then an OR of the few source rows each target row reads.
  std::vector<int> xlo(tw), xhi(tw), ylo(th), yhi(th);
  auto bounds = [&](int tn, int sn, std::vector<int>& lo, std::vector<int>& hi) {
    for (int x = 0; x < tn; ++x) {
      lo[x] = sn;
      hi[x] = -1;
      for (int o = -reach; o <= reach; ++o) {
        const AxisTap<T> t = axis_lookup(x, tn, sn, o, bits, texture_step(sn), T());
        lo[x] = std::min({lo[x], t.i0, t.i1});
        hi[x] = std::max({hi[x], t.i0, t.i1});
      }
    }
  };
  bounds(tw, sw, xlo, xhi);
  bounds(th, sh, ylo, yhi);
  // rows[r * tw + x]: source row r has a set texel in [xlo(x), xhi(x)].
  std::vector<std::uint8_t> rows(std::size_t(sh) * tw);
  parallel_rows(sh, threads, [&](int r0, int r1) {
    std::vector<int> prefix(sw + 1);
    for (int r = r0; r < r1; ++r) {
      const std::uint8_t* m = src_mask + std::size_t(r) * sw;
      for (int i = 0; i < sw; ++i) prefix[i + 1] = prefix[i] + m[i];
      for (int x = 0; x < tw; ++x) rows[std::size_t(r) * tw + x] = prefix[xhi[x] + 1] > prefix[xlo[x]];
    }
  });
  std::vector<std::size_t> counts(th, 0);
  parallel_rows(th, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      std::uint8_t* o = out + std::size_t(y) * tw;
      if (also) std::copy(also + std::size_t(y) * tw, also + std::size_t(y + 1) * tw, o);
      else std::fill(o, o + tw, std::uint8_t(0));
      for (int r = ylo[y]; r <= yhi[y]; ++r) {
        const std::uint8_t* m = rows.data() + std::size_t(r) * tw;
        for (int x = 0; x < tw; ++x) o[x] |= m[x];
      }
      counts[y] = std::size_t(std::count(o, o + tw, std::uint8_t(1)));
    }
  });
  std::size_t total = 0;
  for (std::size_t n : counts) total += n;
  return total;
}

template void downsample<float>(BasicView<const float>, BasicView<float>,
                                const DownsampleOptions&, int);
template void downsample<double>(BasicView<const double>, BasicView<double>,
                                 const DownsampleOptions&, int);
template void upsample_tent<float>(BasicView<const float>, BasicView<const float>,
                                   BasicView<float>, int, int, const std::uint8_t*, float,
                                   LevelBlend, bool, UpsampleFilter);
template void upsample_tent<double>(BasicView<const double>, BasicView<const double>,
                                    BasicView<double>, int, int, const std::uint8_t*, float,
                                    LevelBlend, bool, UpsampleFilter);
template void upscale_bilinear<float>(BasicView<const float>, BasicView<float>, int, int);
template void upscale_bilinear<double>(BasicView<const double>, BasicView<double>, int, int);
template <class T>
void downsample_gaussian_h(BasicView<const T> src, BasicView<T> h, const DownsampleOptions& opt,
                           int threads) {
  if (opt.filter == DownsampleFilter::separable)
    separable_pass(src, h, opt.kernel_radius, opt.kernel_sigma, opt.kernel_normalise, true, opt.subtexel_bits, threads);
  else
    gaussian_h_pass(src, h, opt, threads);
  store(h, opt.intermediate, opt.rounding, threads);
}

template void downsample_gaussian_h<float>(BasicView<const float>, BasicView<float>,
                                           const DownsampleOptions&, int);
template void downsample_gaussian_h<double>(BasicView<const double>, BasicView<double>,
                                            const DownsampleOptions&, int);
template bool mip_nothing_bright<float>(BasicView<const float>, double, int, const LumaRule&);
template bool mip_nothing_bright<double>(BasicView<const double>, double, int, const LumaRule&);
template std::size_t mip_support<float>(const std::uint8_t*, int, int, const std::uint8_t*, int,
                                        int, int, int, std::uint8_t*, int);
template std::size_t mip_support<double>(const std::uint8_t*, int, int, const std::uint8_t*,
                                         int, int, int, int, std::uint8_t*, int);

}  // namespace bloomref
