// The gain gates and the sensitivity statement (docs/check.md, "Gain gates", "Sensitivity"):
// the signed budgets against hand-computed values; a device that uses every freedom a profile
// gives it, written out here, passes under that profile and fails under a stricter one; wrong
// blooms planted by code written here (gains, a shift, a wider kernel) fail wherever the
// verdict's stated sensitivity says they are seen, and clean captures keep passing.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "bloomref/parity/compare.h"
#include "energy.h"
#include "test_util.h"

using namespace bloomref;
using parity::Verdict;

namespace {

// LearnOpenGL's weights (seed 004), 924, 792, 495, 220, 66 over 4070.
const double kD9[5] = {924.0 / 4070, 792.0 / 4070, 495.0 / 4070, 220.0 / 4070, 66.0 / 4070};

parity::DeviceProfile quiet_profile(int bits, int bits_min) {
  parity::DeviceProfile p = parity::profile_nvidia_like();
  p.subtexel_bits = bits;
  p.subtexel_bits_min = bits_min;
  return p;
}

// Sparse lights on a dark ground, and a broad bright region: the two kinds of bloom input.
Image lights_scene(int w, int h) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = img.pixel(x, y);
      p[0] = 0.02f + 0.01f * x / w, p[1] = 0.03f, p[2] = 0.04f + 0.01f * y / h, p[3] = 1;
    }
  const int at[][2] = {{7, 9}, {30, 5}, {50, 30}, {19, 40}, {61, 17}, {41, 44}};
  const float rgb[][3] = {{9, 3, 1}, {2, 8, 12}, {15, 1, 2}, {4, 4, 4}, {1, 6, 2}, {20, 10, 5}};
  for (int i = 0; i < 6; ++i) {
    float* p = img.pixel(at[i][0] % w, at[i][1] % h);
    p[0] = rgb[i][0], p[1] = rgb[i][1], p[2] = rgb[i][2];
  }
  return img;
}

// A crop of a corpus image around its brightest texel (within the image), or an empty image
// without a corpus.
Image corpus_crop(const std::string& name, int w, int h) {
  if (test::corpus_dir().empty()) return Image();
  const LoadedImage l = load_image(test::corpus_dir() + "/" + name);
  const ConstImageView v = l.image.cview();
  int bx = 0, by = 0;
  float best = -1;
  for (int y = 0; y < v.height; ++y)
    for (int x = 0; x < v.width; ++x) {
      const float* p = v.pixel(x, y);
      const float lum = 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
      if (std::isfinite(lum) && lum > best) best = lum, bx = x, by = y;
    }
  const int x0 = std::clamp(bx - w / 2, 0, std::max(0, v.width - w));
  const int y0 = std::clamp(by - h / 2, 0, std::max(0, v.height - h));
  Image out(std::min(w, v.width), std::min(h, v.height));
  for (int y = 0; y < out.height(); ++y)
    for (int x = 0; x < out.width(); ++x) {
      const float* p = v.pixel(x0 + x, y0 + y);
      float* o = out.pixel(x, y);
      for (int c = 0; c < 3; ++c) o[c] = std::isfinite(p[c]) ? p[c] : 0.0f;
      o[3] = 1;
    }
  return out;
}

BloomParams params(int passes) {
  BloomParams p;
  p.passes = passes;
  p.threads = 2;
  p.plan = PlanMode::full;
  return p;
}

std::map<std::string, Image> reference_trace(const BloomParams& p, const Image& scene,
                                             const parity::DeviceProfile& profile) {
  return test::run_stages(p, scene, profile.subtexel_bits);
}

// composite, tonemap and output from `scene` and `bloom`, in double (the specification's
// formulas, docs/design.md's "Specification"), rounded to float once.
void finish(const BloomParams& p, const Image& scene, const Image& bloom,
            std::map<std::string, Image>& out) {
  Image comp(scene.width(), scene.height()), tm(comp.width(), comp.height()),
      o(comp.width(), comp.height());
  for (int y = 0; y < comp.height(); ++y)
    for (int x = 0; x < comp.width(); ++x)
      for (int c = 0; c < 4; ++c) {
        const double h = double(scene.pixel(x, y)[c]) + p.strength * double(bloom.pixel(x, y)[c]);
        const double m = -std::expm1(-h * p.exposure);
        comp.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(h);
        tm.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(m);
        o.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(std::pow(std::max(m, 0.0), 1 / p.gamma));
      }
  out["composite"] = std::move(comp);
  out["tonemap"] = std::move(tm);
  out["output"] = std::move(o);
}

Image scaled(const Image& a, double g) {
  Image out = a;
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x)
      for (int c = 0; c < 3; ++c) out.pixel(x, y)[c] = static_cast<float>(a.pixel(x, y)[c] * g);
  return out;
}

Image shifted(const Image& a, int s) {
  Image out = a;
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x)
      for (int c = 0; c < 3; ++c)
        out.pixel(x, y)[c] = a.pixel(std::clamp(x - s, 0, a.width() - 1), y)[c];
  return out;
}

// One 9-tap pass with weights w (centre first) on texel centres, clamp-to-edge, in double.
Image pass9(const Image& src, const std::vector<double>& w, bool vertical) {
  Image out(src.width(), src.height());
  for (int y = 0; y < src.height(); ++y)
    for (int x = 0; x < src.width(); ++x)
      for (int c = 0; c < 4; ++c) {
        double r = 0;
        for (int i = -4; i <= 4; ++i) {
          const int xx = vertical ? x : std::clamp(x + i, 0, src.width() - 1);
          const int yy = vertical ? std::clamp(y + i, 0, src.height() - 1) : y;
          r += w[std::size_t(std::abs(i))] * src.pixel(xx, yy)[c];
        }
        out.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(r);
      }
  return out;
}

// The captures of a bloom with one change, made here: every blur stage times g, moved by
// `shift` texels, or blurred with `wide` (a 9-tap kernel) instead; then the finishing stages.
std::map<std::string, Image> planted(const BloomParams& p, const std::map<std::string, Image>& ref,
                                     double g, int shift, const std::vector<double>& wide) {
  std::map<std::string, Image> out = ref;
  Image prev = ref.at("bright");
  for (int k = 1; k <= p.passes; ++k) {
    const std::string n = "blur." + std::to_string(k);
    if (!wide.empty()) prev = pass9(prev, wide, k % 2 == 0), out[n] = prev;
    else out[n] = shifted(scaled(ref.at(n), g), shift);
  }
  finish(p, ref.at("input"), out.at("blur." + std::to_string(p.passes)), out);
  return out;
}

// composite's tone map and gamma in double, as finish() makes them, from a given composite.
void finish_from_composite(const BloomParams& p, std::map<std::string, Image>& out) {
  const Image& comp = out.at("composite");
  Image tm(comp.width(), comp.height()), o(comp.width(), comp.height());
  for (int y = 0; y < comp.height(); ++y)
    for (int x = 0; x < comp.width(); ++x)
      for (int c = 0; c < 4; ++c) {
        const double m = -std::expm1(-double(comp.pixel(x, y)[c]) * p.exposure);
        tm.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(m);
        o.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(std::pow(std::max(m, 0.0), 1 / p.gamma));
      }
  out["tonemap"] = std::move(tm);
  out["output"] = std::move(o);
}

// The captures of a bloom with one change entering at `stage`, made here: that stage's image
// times g and moved `shift` texels right, or (a blur pass, `wide` given) that pass blurred with
// `wide` instead of discrete9; the stages after it made again from it in double: the later
// passes with discrete9's weights on texel centres (pass9), then the finishing stages. The
// bright pass reads the scene, not the input stage, so a change of the input reaches only the
// composite.
std::map<std::string, Image> planted_at(const BloomParams& p, const std::map<std::string, Image>& ref,
                                        const std::string& stage, double g, int shift,
                                        const std::vector<double>& wide = {}) {
  std::map<std::string, Image> out = ref;
  const std::vector<double> d9(kD9, kD9 + 5);
  int k = 0;  // the first pass made again
  if (stage == "input") {
    out[stage] = shifted(scaled(ref.at(stage), g), shift);
    k = p.passes + 1;
  } else if (stage == "bright") {
    out[stage] = shifted(scaled(ref.at(stage), g), shift);
    k = 1;
  } else if (stage.rfind("blur.", 0) == 0) {
    const int at = std::stoi(stage.substr(5));
    out[stage] = wide.empty() ? shifted(scaled(ref.at(stage), g), shift)
                              : pass9(at == 1 ? ref.at("bright") : ref.at("blur." + std::to_string(at - 1)),
                                      wide, at % 2 == 0);
    k = at + 1;
  }
  if (k > 0) {
    for (; k <= p.passes; ++k)
      out["blur." + std::to_string(k)] =
          pass9(k == 1 ? out.at("bright") : out.at("blur." + std::to_string(k - 1)), d9, k % 2 == 0);
    finish(p, out.at("input"), out.at("blur." + std::to_string(p.passes)), out);
    return out;
  }
  out[stage] = shifted(scaled(ref.at(stage), g), shift);
  if (stage == "composite") finish_from_composite(p, out);
  if (stage == "tonemap") {
    Image& o = out["output"];
    const Image& tm = out.at("tonemap");
    for (int y = 0; y < o.height(); ++y)
      for (int x = 0; x < o.width(); ++x)
        for (int c = 0; c < 3; ++c)
          o.pixel(x, y)[c] = static_cast<float>(std::pow(std::max(double(tm.pixel(x, y)[c]), 0.0), 1 / p.gamma));
  }
  return out;
}

std::vector<double> gaussian9(double sigma) {
  std::vector<double> w;
  double total = 0;
  for (int i = 0; i <= 4; ++i) {
    w.push_back(std::exp(-0.5 * i * i / (sigma * sigma)));
    total += i ? 2 * w.back() : w.back();
  }
  for (double& v : w) v /= total;
  return w;
}

// 8-bit codes of [0, 1] (linear), as a PNG capture holds them.
Image codes8(const Image& a) {
  Image out = a;
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x)
      for (int c = 0; c < 3; ++c)
        out.pixel(x, y)[c] =
            static_cast<float>(std::round(std::clamp(double(a.pixel(x, y)[c]), 0.0, 1.0) * 255) / 255);
  return out;
}

parity::ParityResult judge(const BloomParams& p, const Image& scene,
                           const std::map<std::string, Image>& stages,
                           const std::vector<std::string>& names,
                           const parity::DeviceProfile& profile) {
  const Plan plan = parity::plan_for_device(p, scene.cview(), profile);
  parity::CapturedStages captured;
  std::map<std::string, Image> held;
  for (const std::string& n : names) {
    held[n] = profile.capture_code_bits ? codes8(stages.at(n)) : stages.at(n);
    captured[n] = {held[n].cview(), profile.capture_code_bits};
  }
  return parity::check_with_oracle(plan, scene.cview(), captured, profile);
}

bool fails(const parity::ParityResult& r) { return r.verdict == Verdict::fail; }

std::string describe(const parity::ParityResult& r) {
  std::string s;
  for (std::size_t i = 0; i < r.isolated.size(); ++i)
    s += r.isolated[i].stage + " " + parity::to_string(r.isolated[i].verdict) + " (" +
         r.isolated[i].reason + "; e2e " + parity::to_string(r.end_to_end[i].verdict) + ") ";
  return s;
}

// Calls f(scene name, scene, profile name, profile, the reference trace, capture set, its
// names in words) for every scene, profile and capture set. ldr8 judges every capture as 8-bit
// codes of [0, 1]: an HDR stage so captured is clamped, and the next stage recomputed from it is
// not the device's, so under it only the output alone (a display stage) is a capture of a
// float device.
template <class F>
void each_capture_set(const std::vector<std::pair<std::string, Image>>& scenes, const BloomParams& p,
                      const std::vector<std::vector<std::string>>& sets, F f) {
  for (const auto& [scene_name, scene] : scenes)
    for (const char* prof : {"nvidia", "vulkan", "mediump", "ldr8"}) {
      const parity::DeviceProfile profile = parity::profile_named(prof);
      const std::map<std::string, Image> ref = reference_trace(p, scene, profile);
      for (const auto& names : sets) {
        if (profile.capture_code_bits && names != std::vector<std::string>{"output"}) continue;
        std::string set;
        for (const std::string& n : names) set += n + " ";
        f(scene_name, scene, prof, profile, ref, names, set);
      }
    }
}

}  // namespace

TEST_CASE("a lookup's shift: one quantum below on a centre, none above, off the grid both ways",
          "[gain]") {
  using parity::detail::lookup_shift;
  const parity::DeviceProfile v = quiet_profile(8, 4);
  const double noise = 100 * v.unit_roundoff * (2 * v.division_ulps + 4);
  const auto centre = lookup_shift(100, v, 0.0);
  CHECK(centre.minus == Approx(1.0 / 16 + noise).epsilon(1e-12));
  CHECK(centre.plus == Approx(noise).epsilon(1e-12));
  const auto half = lookup_shift(100, v, 0.5);  // on both grids too
  CHECK(half.minus == Approx(1.0 / 16 + noise).epsilon(1e-12));
  const auto off = lookup_shift(100, v, 0.3846153846);  // linear5's first offset
  CHECK(off.minus == Approx(1.0 / 16 + 1.0 / 512 + 2 * noise).epsilon(1e-12));
  CHECK(off.plus == Approx(1.0 / 32 + 1.0 / 512 + 2 * noise).epsilon(1e-12));
  const auto flt = lookup_shift(100, quiet_profile(0, 0), 0.0);  // float weights
  CHECK(flt.minus == Approx(2 * noise).epsilon(1e-12));
  CHECK(flt.plus == Approx(2 * noise).epsilon(1e-12));
}

TEST_CASE("a pass's signed deviation on one lit texel, by hand", "[gain]") {
  // One row (height 1: no neighbour across), texel 6 of 13 lit with 1. With the device's
  // lookups up to c- below their centre and c+ above: the lookup centred on 6 loses c- (down),
  // those centred on 5 and 7 gain c+ and c- of it (up). Every output sums its taps, weights
  // adding to 1 over the outputs that read each texel away from the edges: the totals are
  // up = c+ + c-, down = c-.
  Image img(13, 1, 0.0f);
  img.pixel(6, 0)[0] = 1.0f;
  const parity::DeviceProfile v = quiet_profile(8, 4);
  // By hand: on a centre a 4-bit truncation moves a lookup 1/16 below; above, only the
  // coordinates' float error, 13 texels x 2^-24 x (2 x 2.5 + 4) (GLSL's 2.5-ULP divisions).
  const double noise = 13 * std::ldexp(1.0, -24) * 9;
  const struct { double minus, plus; } s{1.0 / 16 + noise, noise};
  parity::detail::BlurDeviation dev(img.cview(), Axis::horizontal, kernel_discrete9(), v);
  REQUIRE(dev.usable());
  std::vector<float> up(13 * 4), down(13 * 4);
  dev.rows(0, 1, up.data(), down.data());
  double su = 0, sd = 0;
  for (int x = 0; x < 13; ++x) su += up[std::size_t(x) * 4], sd += down[std::size_t(x) * 4];
  CHECK(su == Approx(s.plus + s.minus).epsilon(1e-5));
  CHECK(sd == Approx(s.minus).epsilon(1e-5));
  // Output 6 reads texel 6 through its centre tap (w0 of the loss) and texel 5 and 7 through
  // its +-1 taps (w1 each of what moves toward 6).
  CHECK(down[6 * 4] == Approx(kD9[0] * s.minus).epsilon(1e-5));
  CHECK(up[6 * 4] == Approx(kD9[1] * (s.plus + s.minus)).epsilon(1e-5));
}

TEST_CASE("with float weights the oracle moves too: a device on the other side stays in budget",
          "[gain]") {
  // One row, texel 6 of 13 lit with 1, float weights (llvmpipe's profile): the oracle's own
  // coordinates may put its lookup on 7 up to c right of the centre, picking up c of texel 6,
  // while the device's lookup on 7 sits c left of it and picks up nothing. Measured on
  // StarField.exr through a user's shader: GL 0 where the oracle had 6.7e-11 from such a leak,
  // 37x a tile budget that counted only the device's side. Both sides, by hand: every lookup
  // may differ from the oracle's by its rise and its fall together.
  Image img(13, 1, 0.0f);
  img.pixel(6, 0)[0] = 1.0f;
  const parity::DeviceProfile v = quiet_profile(0, 0);
  const double c = 2 * 13 * std::ldexp(1.0, -24) * 9;  // the shift each way, as lookup_shift
  parity::detail::BlurDeviation dev(img.cview(), Axis::horizontal, kernel_discrete9(), v);
  REQUIRE(dev.usable());
  std::vector<float> up(13 * 4), down(13 * 4);
  dev.rows(0, 1, up.data(), down.data());
  // Output 7 reads texels 5, 6 and 7 (taps -2, -1, 0): the lookups on 5 and 7 may pick up c of
  // the lit texel (their rise), the one on 6 lose c (its fall); either may be the oracle's
  // and the other the device's, so each side's budget is the three together.
  const double w0 = kD9[0], w1 = kD9[1], w2 = kD9[2];
  CHECK(down[7 * 4] == Approx((w0 + w1 + w2) * c).epsilon(1e-4));
  CHECK(up[7 * 4] == Approx(down[7 * 4]).epsilon(1e-6));
  // The device's shortfall at 7 when the oracle leaked c of texel 6 into its centre tap and
  // the device leaked none: within the budget's down.
  CHECK(w0 * c <= down[7 * 4]);
}

TEST_CASE("clamp-to-edge gives the texels near an edge more or less than their weight",
          "[gain]") {
  // discrete9 on 20 texels: texel 0 is read by output 0's taps -4..0, output 1's -4..-1, ...,
  // output 4's -4: weights sum to w0 + 2w1 + 3w2 + 4w3 + 5w4 (centre and the taps on one side).
  const std::vector<double> e = parity::detail::edge_weight_excess(20, kernel_discrete9());
  const double w0 = kD9[0] + 2 * kD9[1] + 3 * kD9[2] + 4 * kD9[3] + 5 * kD9[4];
  CHECK(e[0] == Approx(std::fabs(w0 - 1)).epsilon(1e-9));
  CHECK(e[19] == Approx(e[0]).epsilon(1e-9));
  // Texel 1 is read once by each tap except those that clamp onto texel 0: it lacks the -1
  // tap of output 0 and the taps of outputs that lie beyond the edge (w2 + w3 + w4 of them).
  CHECK(e[1] == Approx(kD9[2] + kD9[3] + kD9[4]).epsilon(1e-9));
  for (int t = 4; t < 16; ++t) CHECK(e[std::size_t(t)] == 0.0);
}

TEST_CASE("a device that uses every freedom of its profile passes, a stricter profile fails it",
          "[gain]") {
  // The device: discrete9 passes whose lookups on texel centres move one 4-bit quantum toward
  // the lower neighbour on either axis exactly where that adds energy (truncated fractions,
  // as a Vulkan device with subTexelPrecisionBits 4 may have them) -- the worst a 4-bit device
  // can do to the bloom's total, written out here.
  // Four passes with each captured, and ten with the last alone (the budget carried through
  // nine passes without capture, where the error the device's lookups move grows). Its mirror
  // takes the darker lookup wherever that removes energy. Each pass is the highest (lowest)
  // value any 4-bit device could write there, so with passes left uncaptured it is the
  // envelope itself: the envelope gate must hold it, and barely (the envelope is tight).
  const int passes = GENERATE(4, 10);
  const bool toward_light = GENERATE(true, false);
  const BloomParams p = params(passes);
  const Image scene = lights_scene(64, 48);
  const parity::DeviceProfile vulkan = parity::profile_vulkan();
  std::map<std::string, Image> dev = reference_trace(p, scene, vulkan);
  const double q = 1.0 / 16;
  Image prev = dev.at("bright");
  double bright_total = 0, bloom_total = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) bright_total += prev.pixel(x, y)[1];
  for (int k = 1; k <= p.passes; ++k) {
    const bool vertical = k % 2 == 0;
    Image out(64, 48);
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x)
        for (int c = 0; c < 4; ++c) {
          double r = 0;
          for (int i = -4; i <= 4; ++i) {
            const int tx = vertical ? x : std::clamp(x + i, 0, 63);
            const int ty = vertical ? std::clamp(y + i, 0, 47) : y;
            const double t = prev.pixel(tx, ty)[c];
            const double a = prev.pixel(std::max(tx - 1, 0), ty)[c];
            const double b = prev.pixel(tx, std::max(ty - 1, 0))[c];
            const double ab = prev.pixel(std::max(tx - 1, 0), std::max(ty - 1, 0))[c];
            double best = t;
            for (int fa = 0; fa < 2; ++fa)
              for (int fb = 0; fb < 2; ++fb) {
                const double wa = fa * q, wb = fb * q;
                const double v = (1 - wa) * (1 - wb) * t + wa * (1 - wb) * a + (1 - wa) * wb * b + wa * wb * ab;
                best = toward_light ? std::max(best, v) : std::min(best, v);
              }
            r += kD9[std::abs(i)] * best;
          }
          out.pixel(x, y)[c] = c == 3 ? 1.0f : static_cast<float>(r);
        }
    dev["blur." + std::to_string(k)] = out;
    prev = out;
  }
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) bloom_total += prev.pixel(x, y)[1];
  INFO("the device's bloom holds " << bloom_total / bright_total << " of the bright image's total");
  // The freedom is real: more than 2% more (less) energy.
  if (toward_light) CHECK(bloom_total / bright_total > 1.02);
  else CHECK(bloom_total / bright_total < 0.98);
  finish(p, dev.at("input"), prev, dev);
  std::vector<std::string> all = {"input", "bright"};
  for (int k = 1; k <= passes; ++k) all.push_back("blur." + std::to_string(k));
  for (const char* s : {"composite", "tonemap", "output"}) all.push_back(s);
  const std::string last = "blur." + std::to_string(passes);
  for (const auto& names : {all, std::vector<std::string>{last, "output"},
                            std::vector<std::string>{"blur.2", last}, std::vector<std::string>{last},
                            std::vector<std::string>{"output"}, std::vector<std::string>{"bright", "output"}}) {
    const parity::ParityResult r = judge(p, scene, dev, names, vulkan);
    INFO(describe(r));
    CHECK_FALSE(fails(r));
    for (const auto& s : r.isolated) {
      CHECK(s.gain_ratio <= 1.0);
      CHECK(s.envelope_outside <= 0.0);  // -1: no envelope (the pass before it captured)
      CHECK(s.envelope_ratio <= 1.0);
      // Where nine passes are left uncaptured the device is the envelope's edge: its total
      // error is nearly all the envelope allows.
      if (s.stage == last && names.size() <= 2 && passes == 10) CHECK(s.envelope_ratio > 0.9);
      // The output of the bloom at the envelope's edge, from nine passes and the bright pass
      // without capture, has an envelope of its own (composite, tone map, gamma), and lies in it.
      if (s.stage == "output" && names.size() <= 2 && names.front() != last) CHECK(s.envelope_ratio >= 0);
    }
  }
  // nvidia allows an 8-bit quantum: 1/16 of a texel is far beyond it.
  const parity::ParityResult strict = judge(p, scene, dev, {last, "output"},
                                            parity::profile_nvidia_like());
  INFO(describe(strict));
  CHECK(fails(strict));
}

TEST_CASE("planted wrong blooms fail wherever the stated sensitivity says they are seen",
          "[gain][sensitivity]") {
  std::vector<std::pair<std::string, Image>> scenes = {{"lights", lights_scene(64, 48)}};
  for (const char* name : {"GoldenGate.exr", "StageEnvLatLong.exr"}) {
    Image crop = corpus_crop(name, 96, 64);
    if (!crop.empty()) scenes.emplace_back(name, std::move(crop));
  }
  const BloomParams p = params(6);
  const std::vector<std::vector<std::string>> sets = {
      {"input", "bright", "blur.1", "blur.2", "blur.3", "blur.4", "blur.5", "blur.6", "composite",
       "tonemap", "output"},
      {"blur.6", "output"},
      {"output"},
      {"bright", "output"},
      {"blur.2", "blur.4", "blur.6", "output"}};
  int seen_small = 0, weak = 0;
  each_capture_set(scenes, p, sets, [&](const std::string& scene_name, const Image& scene,
                                        const char* prof, const parity::DeviceProfile& profile,
                                        const std::map<std::string, Image>& ref,
                                        const std::vector<std::string>& names, const std::string& set) {
    INFO(scene_name << ", profile " << prof << ", captures " << set);
    // Clean captures pass.
    const parity::ParityResult clean = judge(p, scene, ref, names, profile);
    INFO("clean: " << describe(clean));
    REQUIRE_FALSE(fails(clean));
    std::map<std::string, int> codes;
    for (const std::string& n : names) codes[n] = profile.capture_code_bits;
    const Plan plan = parity::plan_for_device(p, scene.cview(), profile);
    const parity::Sensitivity s =
        parity::sensitivity(plan, scene.cview(), names, codes, profile, {}, 1.05, true);
    INFO("sensitivity: gain " << s.gain << " (" << s.gain_stage << "), shift " << s.shift
                              << ", spread " << s.spread);
    std::printf("%-20s %-8s %-70s gain %-5g (%s) shift %g spread %g\n", scene_name.c_str(), prof,
                set.c_str(), s.gain, s.gain_stage.c_str(), s.shift, s.spread);
    seen_small += s.gain > 0 && s.gain <= 1.05;
    weak += s.gain == 0 || s.gain > 1.05;
    for (double g : {1.02, 1.05, 1.1, 1.5, 2.0}) {
      const parity::ParityResult r = judge(p, scene, planted(p, ref, g, 0, {}), names, profile);
      INFO("gain " << g << ": " << describe(r));
      if (s.gain > 0 && g >= s.gain * (1 - 1e-9)) CHECK(fails(r));
    }
    // The ladder's step below the stated gain does not fail the planted run (the
    // statement is the smallest), checked with this file's planting.
    const auto& ladder = parity::Sensitivity::gain_ladder();
    const auto at = std::find(ladder.begin(), ladder.end(), s.gain);
    if (s.gain > 0 && at != ladder.begin()) {
      const parity::ParityResult below = judge(p, scene, planted(p, ref, *(at - 1), 0, {}), names, profile);
      INFO("gain below " << *(at - 1) << ": " << describe(below));
      CHECK_FALSE(fails(below));
    }
    if (s.shift == 1) {
      const parity::ParityResult r = judge(p, scene, planted(p, ref, 1.0, 1, {}), names, profile);
      INFO("shift 1: " << describe(r));
      CHECK(fails(r));
    }
    if (s.spread > 0 && s.spread <= 1.1) {
      // discrete9's sigma: sqrt(2 (w1 + 4 w2 + 9 w3 + 16 w4)).
      const double sigma = std::sqrt(2 * (kD9[1] + 4 * kD9[2] + 9 * kD9[3] + 16 * kD9[4]));
      const parity::ParityResult r =
          judge(p, scene, planted(p, ref, 1.0, 0, gaussian9(sigma * 1.1)), names, profile);
      INFO("spread 1.1: " << describe(r));
      CHECK(fails(r));
    }
  });
  // Both kinds of statement occur: verdicts that see 5% and weak ones.
  CHECK(seen_small > 0);
  CHECK(weak > 0);
}

TEST_CASE("an error entering at one stage fails wherever that stage's stated sensitivity says",
          "[gain][sensitivity]") {
  std::vector<std::pair<std::string, Image>> scenes = {{"lights", lights_scene(64, 48)}};
  Image crop = corpus_crop("GoldenGate.exr", 96, 64);
  if (!crop.empty()) scenes.emplace_back("GoldenGate.exr", std::move(crop));
  const BloomParams p = params(6);
  const std::vector<std::vector<std::string>> sets = {
      {"input", "bright", "blur.1", "blur.2", "blur.3", "blur.4", "blur.5", "blur.6", "composite",
       "tonemap", "output"},
      {"blur.6", "output"},
      {"blur.2", "blur.4", "blur.6", "output"},
      {"output"}};
  // discrete9's sigma: sqrt(2 (w1 + 4 w2 + 9 w3 + 16 w4)).
  const double sigma = std::sqrt(2 * (kD9[1] + 4 * kD9[2] + 9 * kD9[3] + 16 * kD9[4]));
  int seen_small = 0, weak = 0, checked = 0;
  each_capture_set(scenes, p, sets, [&](const std::string& scene_name, const Image& scene,
                                        const char* prof, const parity::DeviceProfile& profile,
                                        const std::map<std::string, Image>& ref,
                                        const std::vector<std::string>& names, const std::string& set) {
    INFO(scene_name << ", profile " << prof << ", captures " << set);
    REQUIRE_FALSE(fails(judge(p, scene, ref, names, profile)));
    std::map<std::string, int> codes;
    for (const std::string& n : names) codes[n] = profile.capture_code_bits;
    const Plan plan = parity::plan_for_device(p, scene.cview(), profile);
    const parity::Sensitivity s =
        parity::sensitivity(plan, scene.cview(), names, codes, profile, {}, 1.05, true, true);
    REQUIRE(s.stages.size() == names.size());
    for (const parity::StageSensitivity& st : s.stages) {
      INFO("entering at " << st.stage << ": gain " << st.gain << " (" << st.gain_stage
                          << "), shift " << st.shift << ", spread " << st.spread);
      std::printf("%-16s %-8s %-60s %-10s gain %-5g (%s) shift %g spread %g\n", scene_name.c_str(),
                  prof, set.c_str(), st.stage.c_str(), st.gain, st.gain_stage.c_str(), st.shift,
                  st.spread);
      seen_small += st.gain > 0 && st.gain <= 1.05;
      weak += st.gain == 0 || st.gain > 1.05;
      for (double g : {1.02, 1.05, 1.1, 1.5, 2.0})
        if (st.gain > 0 && g >= st.gain * (1 - 1e-9)) {
          const parity::ParityResult r = judge(p, scene, planted_at(p, ref, st.stage, g, 0), names, profile);
          INFO("gain " << g << ": " << describe(r));
          CHECK(fails(r));
          ++checked;
        }
      const auto& ladder = parity::Sensitivity::gain_ladder();
      const auto at = std::find(ladder.begin(), ladder.end(), st.gain);
      if (st.gain > 0 && at != ladder.begin()) {
        const parity::ParityResult below =
            judge(p, scene, planted_at(p, ref, st.stage, *(at - 1), 0), names, profile);
        INFO("gain below " << *(at - 1) << ": " << describe(below));
        CHECK_FALSE(fails(below));
      }
      if (st.shift == 1) {
        const parity::ParityResult r = judge(p, scene, planted_at(p, ref, st.stage, 1.0, 1), names, profile);
        INFO("shift 1: " << describe(r));
        CHECK(fails(r));
        ++checked;
      }
      CHECK(st.spread_measured == (st.stage.rfind("blur.", 0) == 0));
      if (st.spread > 0 && st.spread <= 1.1) {
        const parity::ParityResult r =
            judge(p, scene, planted_at(p, ref, st.stage, 1.0, 0, gaussian9(sigma * 1.1)), names, profile);
        INFO("spread 1.1: " << describe(r));
        CHECK(fails(r));
        ++checked;
      }
    }
  });
  // Both kinds of statement occur, and the planted errors were judged.
  CHECK(seen_small > 0);
  CHECK(weak > 0);
  CHECK(checked > 50);
}
