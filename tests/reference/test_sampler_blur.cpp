// The GL sampler and the blur against hand calculations and an independent naive convolution.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <vector>

#include "bloomref/kernel.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"
#include "test_util.h"

using namespace bloomref;

namespace {

// The discrete9 weights as integers over 4070 (binomial row 12, outer terms dropped).
const std::vector<double> kBinomial = {66, 220, 495, 792, 924, 792, 495, 220, 66};

std::vector<double> convolve(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> c(a.size() + b.size() - 1, 0.0);
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t j = 0; j < b.size(); ++j) c[i + j] += a[i] * b[j];
  return c;
}

// The 1-D response of m passes along one axis: the m-fold convolution of the kernel.
std::vector<double> response(int m) {
  std::vector<double> w(kBinomial.size());
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = kBinomial[i] / 4070.0;
  std::vector<double> r = {1.0};
  for (int i = 0; i < m; ++i) r = convolve(r, w);
  return r;
}

template <class T>
BasicImage<T> run_passes(BasicImage<T> img, int passes, const Kernel& k, int first_axis = 0) {
  BasicImage<T> tmp(img.width(), img.height());
  for (int p = 0; p < passes; ++p) {
    BlurPassOptions o{(p + first_axis) % 2 == 0 ? Axis::horizontal : Axis::vertical, &k, 0};
    blur_pass(img.cview(), tmp.view(), o, 1);
    std::swap(img, tmp);
  }
  return img;
}

// Naive clamp-to-edge 1-D blur with integer taps (independent of the sampler).
std::vector<double> naive_clamped(const std::vector<double>& src, const std::vector<double>& w) {
  const int n = static_cast<int>(src.size()), r = static_cast<int>(w.size() / 2);
  std::vector<double> out(n, 0.0);
  for (int x = 0; x < n; ++x)
    for (int k = -r; k <= r; ++k) out[x] += w[k + r] * src[std::min(std::max(x + k, 0), n - 1)];
  return out;
}

double max_abs_diff_to(const Image& a, const ImageF64& b) {
  double m = 0;
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x)
      for (int c = 0; c < 3; ++c)
        m = std::max(m, std::fabs(double(a.pixel(x, y)[c]) - b.pixel(x, y)[c]));
  return m;
}

}  // namespace

TEST_CASE("GL_LINEAR axis lookups: texel centres, clamp-to-edge, sub-texel bits", "[sampler]") {
  // Power-of-two size: the centre of texel 2 is exact.
  AxisTap<float> t = gl_axis_tap(texel_centre(2, 8), 8, 0);
  CHECK(t.i0 == 2);
  CHECK(t.w1 == 0.0f);
  // s = 0: u = -0.5, floor -1, a = 0.5; both texels clamp to 0 (GL_CLAMP_TO_EDGE).
  t = gl_axis_tap(0.0f, 5, 0);
  CHECK((t.i0 == 0 && t.i1 == 0 && t.w0 == 0.5f && t.w1 == 0.5f));
  // s = 1: u = n - 0.5; texel n - 1 and its clamped neighbour.
  t = gl_axis_tap(1.0f, 4, 0);
  CHECK((t.i0 == 3 && t.i1 == 3 && t.w1 == 0.5f));
  // Far outside: clamps, no overflow.
  t = gl_axis_tap(-1e30f, 4, 0);
  CHECK((t.i0 == 0 && t.i1 == 0));
  // s = 0.45 on 4 texels: u = 0.45f * 4 - 0.5 = 1.29999995 (0.45f = 0.449999988); with 8-bit
  // weights a = round(0.29999995 * 256) / 256 = 77 / 256.
  t = gl_axis_tap(0.45f, 4, 8);
  CHECK((t.i0 == 1 && t.i1 == 2));
  CHECK(t.w1 == 77.0f / 256.0f);
  t = gl_axis_tap(0.45f, 4, 0);
  CHECK(t.w1 == 0.45f * 4.0f - 0.5f - 1.0f);
  // Exact lookups in texel units.
  const AxisTap<double> e = exact_axis_tap(1.25, 4);
  CHECK((e.i0 == 1 && e.i1 == 2 && e.w1 == 0.25));
}

TEST_CASE("impulse response of N passes is the N-fold convolution of the kernel", "[blur]") {
  const int n = 41, c = 20;  // 10 passes reach 20 texels: the support just fits
  for (int passes : {1, 2, 3, 4, 10}) {
    ImageF64 img(n, n, 0.0);
    img.pixel(c, c)[0] = img.pixel(c, c)[1] = img.pixel(c, c)[2] = 1.0;
    const ImageF64 out = run_passes(img, passes, kernel_discrete9());
    const std::vector<double> rx = response((passes + 1) / 2), ry = response(passes / 2);
    const int hx = static_cast<int>(rx.size() / 2), hy = static_cast<int>(ry.size() / 2);
    double worst = 0;
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const int dx = x - c + hx, dy = y - c + hy;
        const bool in = dx >= 0 && dx < int(rx.size()) && dy >= 0 && dy < int(ry.size());
        const double expect = in ? rx[dx] * ry[dy] : 0.0;
        worst = std::max(worst, std::fabs(out.pixel(x, y)[1] - expect));
      }
    INFO("passes " << passes);
    CHECK(worst < 1e-15);

    // f32 through GL float coordinates: 41 is not a power of two, so taps land up to
    // ~41 * 2^-23 texels off centre; the response still matches to 1e-5 of its peak.
    Image f(n, n, 0.0f);
    f.pixel(c, c)[0] = f.pixel(c, c)[1] = f.pixel(c, c)[2] = 1.0f;
    const Image of = run_passes(f, passes, kernel_discrete9());
    const double peak = rx[hx] * ry[hy];
    CHECK(max_abs_diff_to(of, out) < 1e-5 * peak + 1e-12);
  }
}

TEST_CASE("a constant field stays constant within the weight sum", "[blur]") {
  // f64: the exact weights sum to 1, so 10 passes keep 2 to rounding.
  ImageF64 d(37, 23, 2.0);
  const ImageF64 od = run_passes(d, 10, kernel_discrete9());
  Image f = test::constant_image(37, 23, 2.0f);
  const Image of = run_passes(f, 10, kernel_discrete9());
  double worst_d = 0, worst_f = 0;
  for (std::size_t i = 0; i < od.pixel_count(); ++i) {
    worst_d = std::max(worst_d, std::fabs(od.data()[i * 4] - 2.0));
    worst_f = std::max(worst_f, std::fabs(of.data()[i * 4] - 2.0));
  }
  CHECK(worst_d < 1e-14);
  // f32: each pass loses at most |sum of float weights - 1| < 1e-7 plus 9 roundings of a value
  // near 2 (9 * 2^-23): 10 passes stay within 10 * 2 * (1e-7 + 9 * 2^-24) = 2.3e-5.
  CHECK(worst_f < 2.3e-5);

  // Seed 000's 6-digit weights lose 6e-7 per pass: 10 passes of 1 give 0.9999994^10.
  ImageF64 one(9, 9, 1.0);
  const ImageF64 o6 = run_passes(one, 10, kernel_discrete9_seed000());
  CHECK(o6.pixel(4, 4)[0] == Approx(0.9999940000161998).epsilon(1e-14));
}

TEST_CASE("clamp-to-edge on 1x1, 1xN and Nx1 images", "[blur]") {
  const std::vector<double> w = [] {
    std::vector<double> v;
    for (double b : kBinomial) v.push_back(b / 4070.0);
    return v;
  }();
  // 1x1: every tap reads the one texel; any number of passes keeps it (weights sum to 1).
  ImageF64 single(1, 1, 3.0);
  CHECK(run_passes(single, 10, kernel_discrete9()).pixel(0, 0)[0] == Approx(3.0).epsilon(1e-14));
  Image single_f = test::constant_image(1, 1, 3.0f);
  CHECK(run_passes(single_f, 10, kernel_discrete9()).pixel(0, 0)[0] ==
        Approx(3.0).epsilon(1e-6));

  // Nx1 and 1xN with an impulse at the first texel: the blurred axis follows the naive
  // clamped convolution; the other axis has one texel and changes nothing.
  for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()}) {
    const int n = 7;
    std::vector<double> src(n, 0.0);
    src[0] = 1.0;
    src[5] = 0.25;
    std::vector<double> expect = naive_clamped(naive_clamped(src, w), w);
    ImageF64 row(n, 1, 0.0), col(1, n, 0.0);
    for (int i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) row.pixel(i, 0)[c] = col.pixel(0, i)[c] = src[i];
    const ImageF64 orow = run_passes(row, 4, *k, 0), ocol = run_passes(col, 4, *k, 1);
    for (int i = 0; i < n; ++i) {
      INFO(k->name << " texel " << i);
      CHECK(orow.pixel(i, 0)[0] == Approx(expect[i]).epsilon(1e-6).margin(1e-15));
      CHECK(ocol.pixel(0, i)[2] == Approx(expect[i]).epsilon(1e-6).margin(1e-15));
    }
  }
}

TEST_CASE("hot pixel in a corner: one pass gives v * (924+792+495+220+66)/4070", "[blur]") {
  // At x = W-1 the four + taps clamp onto the pixel itself, the - taps read black.
  Image img(8, 5, 0.0f);
  float* p = img.pixel(7, 4);
  p[0] = p[1] = p[2] = 50.0f;
  Image out(8, 5);
  BlurPassOptions o{Axis::horizontal, &kernel_discrete9(), 0};
  blur_pass(img.cview(), out.view(), o, 1);
  CHECK(out.pixel(7, 4)[0] == Approx(50.0 * 2497.0 / 4070.0).epsilon(1e-6));
  // The texel 3 to the left sees the hot pixel through tap +3 and +4 (clamped): 220 + 66.
  CHECK(out.pixel(4, 4)[0] == Approx(50.0 * 286.0 / 4070.0).epsilon(1e-6));
  CHECK(out.pixel(2, 4)[0] == 0.0f);
  CHECK(out.pixel(7, 3)[0] == 0.0f);
  CHECK(out.pixel(7, 4)[3] == 1.0f);
}

TEST_CASE("linear5 equals discrete9 with exact sampling", "[blur]") {
  ImageF64 img(50, 30, 0.0);
  std::uint32_t s = 7;
  for (double& v : img.values()) {
    s = s * 1664525u + 1013904223u;
    v = (s >> 8) / 16777216.0 * 10.0;
  }
  for (int passes : {1, 2, 10}) {
    const ImageF64 a = run_passes(img, passes, kernel_discrete9());
    const ImageF64 b = run_passes(img, passes, kernel_linear5());
    double worst = 0;
    for (std::size_t i = 0; i < a.pixel_count(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double x = a.data()[i * 4 + c], y = b.data()[i * 4 + c];
        worst = std::max(worst, std::fabs(x - y) / std::max(std::fabs(x), 1e-300));
      }
    INFO("passes " << passes);
    CHECK(worst < 1e-6);
  }
}

TEST_CASE("blur_pass equals the seeds' shader loop written per pixel with texture()", "[blur]") {
  // The shader, literally: uv = (x + 0.5) / size; d = 1 / size; r = texture(uv) * w0;
  // r += texture(uv + d * i) * wi; r += texture(uv - d * i) * wi. Odd sizes make some lookups
  // fall between rows (the row coordinate rounds off the texel centre), exercising both paths.
  // Hostile values (-0, denormals, 1e38, +-Inf, NaN) go through both paths too; a NaN result
  // must be NaN in both (which NaN is not specified: stages.h), every other value the same bits.
  for (bool hostile : {false, true})
  for (auto [w, h] : {std::pair{37, 23}, {1000, 3}, {3, 999}, {1, 5}}) {
    Image img(w, h);
    std::uint32_t s = 99;
    const float odd[] = {-0.0f, 1e-40f, 1e38f, INFINITY, -INFINITY, NAN, -3.5f};
    for (float& v : img.values()) {
      s = s * 1664525u + 1013904223u;
      v = static_cast<float>(s >> 8) / 16777216.0f * 4.0f;
      if (hostile && (s >> 28) == 0) v = odd[(s >> 8) % 7];
    }
    for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()})
      for (int bits : {0, 8})
        for (Axis axis : {Axis::horizontal, Axis::vertical}) {
          Image out(w, h);
          blur_pass(img.cview(), out.view(), BlurPassOptions{axis, k, bits}, 2);
          int mismatches = 0;
          const bool hz = axis == Axis::horizontal;
          const float d = 1.0f / static_cast<float>(hz ? w : h);
          for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
              const float u = texel_centre(x, w), v = texel_centre(y, h);
              float r[3], t[3];
              gl_texture_rgb(img.cview(), u, v, bits, t);
              for (int c = 0; c < 3; ++c) r[c] = t[c] * k->weights_f32[0];
              for (std::size_t i = 1; i < k->weights_f32.size(); ++i)
                for (float sign : {1.0f, -1.0f}) {
                  const float o = sign * (d * k->offsets_f32[i]);
                  gl_texture_rgb(img.cview(), hz ? u + o : u, hz ? v : v + o, bits, t);
                  for (int c = 0; c < 3; ++c) r[c] = r[c] + t[c] * k->weights_f32[i];
                }
              for (int c = 0; c < 3; ++c) {
                const float o = out.pixel(x, y)[c];
                mismatches += std::isnan(r[c]) ? !std::isnan(o)
                                                : std::memcmp(&r[c], &o, sizeof o) != 0;
              }
            }
          INFO((hostile ? "hostile " : "") << w << "x" << h << " " << k->name << " bits " << bits << (hz ? " H" : " V"));
          CHECK(mismatches == 0);
        }
  }
}
