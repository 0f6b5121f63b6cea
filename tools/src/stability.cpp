// The hostile cases behind `bloomref stability` (stability.h). Expected values are closed forms
// computed here from first principles (the N-fold kernel, -expm1, pow), never from the pipeline.
#include "bloomref/stability.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "bloomref/io.h"
#include "bloomref/kernel.h"
#include "bloomref/mip.h"
#include "bloomref/scenes.h"

namespace bloomref {
namespace {

Image constant(int w, int h, float v) {
  Image img(w, h);
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    float* p = img.data() + i * 4;
    p[0] = p[1] = p[2] = v;
    p[3] = 1;
  }
  return img;
}

// An opaque texel (r, g, b, 1).
void set(Image& img, int x, int y, float r, float g, float b) {
  float* p = img.pixel(x, y);
  p[0] = r; p[1] = g; p[2] = b; p[3] = 1;
}

std::string fmt(double v) {
  std::ostringstream o;
  o.precision(3);
  o << v;
  return o.str();
}

bool is_f16(const StabilityRun& r) { return r.plan.params.storage == Storage::f16; }
bool is_f64(const StabilityRun& r) { return r.plan.params.precision == Precision::f64; }

const Image& stage(const StabilityRun& r, const std::string& name) { return r.trace.find(name)->image; }

std::string bloom_stage(const StabilityRun& r) { return bloom_stage_name(r.plan); }

bool input_finite(const Image& img) {
  for (float v : img.values())
    if (!std::isfinite(v)) return false;
  return true;
}

// The invariant every case shares: finite input never gives NaN, in any stage of any run.
Finding no_nan(const StabilityRun& r, const Image& input) {
  const NonFiniteSummary s = nonfinite_summary(r.trace);
  const bool ok = !input_finite(input) || s.nan == 0;
  return {r.backend, ok,
          "NaN " + std::to_string(s.nan) + ", Inf " + std::to_string(s.inf) +
              (s.first_stage.empty() ? "" : " (first in " + s.first_stage + ")")};
}

// Closed form of a constant field c through the pipeline: every pixel bright when L(c) >
// threshold (the mip chain keeps taps with L >= threshold); the gaussian bloom of a constant
// is c (weights sum to 1), the mip bloom c K (K levels, each up.k adds its down.k).
double constant_output(double c, const BloomParams& p, std::size_t levels) {
  const double l = c;  // grey: L = c (0.2126 + 0.7152 + 0.0722 = 1)
  double bloom = 0;
  if (p.method == Method::gaussian) bloom = l > p.threshold ? c : 0;
  else bloom = l >= p.threshold ? c * static_cast<double>(levels) : 0;
  const double hdr = c + p.strength * bloom;
  const double mapped = -std::expm1(-hdr * p.exposure);
  return std::pow(std::max(mapped, 0.0), 1.0 / p.gamma);
}

// Output of a constant-field case against its closed form: relative error within `f32` for
// float storage, `f16` for half storage (one half ULP per stored stage, a few stages).
std::vector<Finding> check_constant(const Image& input, const std::vector<StabilityRun>& runs,
                                    double c, double f32, double f16) {
  std::vector<Finding> out;
  for (const StabilityRun& r : runs) {
    Finding f = no_nan(r, input);
    const double expect = constant_output(c, r.plan.params, r.plan.levels.size());
    double worst = 0;
    const Image& o = r.trace.final_image();
    for (std::size_t i = 0; i < o.pixel_count(); ++i)
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::fabs(o.data()[i * 4 + k] - expect) / std::max(expect, 1e-30));
    // The f64 run's trace holds its stages rounded to float: 2^-23 relative at most.
    const double tol = is_f64(r) ? 1.2e-7 : is_f16(r) ? f16 : f32;
    f.ok = f.ok && worst <= tol;
    f.detail = "output " + fmt(expect) + " (closed form), worst relative error " + fmt(worst) +
               " (allowed " + fmt(tol) + "); " + f.detail;
    out.push_back(f);
  }
  return out;
}

// The discrete9 response of m passes along one axis: the m-fold convolution of 924..66 / 4070.
std::vector<double> response(int m) {
  const double b[9] = {66, 220, 495, 792, 924, 792, 495, 220, 66};
  std::vector<double> r = {1.0};
  for (int i = 0; i < m; ++i) {
    std::vector<double> n(r.size() + 8, 0.0);
    for (std::size_t j = 0; j < r.size(); ++j)
      for (int k = 0; k < 9; ++k) n[j + k] += r[j] * b[k] / 4070.0;
    r = n;
  }
  return r;
}

}  // namespace

BloomParams stability_params(const StabilityCase& c, Method method) {
  BloomParams p;
  p.method = method;
  c.adjust(p);
  return p;
}

StabilityRun run_stability_cpu(const StabilityCase& c, Method method, const Image& input,
                               Precision precision, Storage storage) {
  BloomParams p = stability_params(c, method);
  p.precision = precision;
  p.storage = storage;
  StabilityRun r;
  r.backend = std::string("cpu-") + (precision == Precision::f64 ? "f64" : to_string(storage));
  r.plan = make_plan(p, input.cview(), c.name);
  r.trace = execute(r.plan, input.cview(), {true});
  return r;
}

StabilityCase corpus_case(const std::string& path) {
  const std::string name = path.substr(path.find_last_of('/') + 1);
  return {name, "corpus image " + name + " (default parameters, --nonfinite zero)",
          "no NaN in any stage (the zero policy removes NaN/Inf input); output in [0, 1]. The "
          "error against f64 is reported, not bounded: a pixel whose luminance is within rounding "
          "of the threshold is bright in one precision and not the other (WideColorGamut.exr), and "
          "f16 cannot hold 1.7e38",
          [path] { return load_image(path).image; },
          [](BloomParams&) {},
          [](const Image&, const std::vector<StabilityRun>& runs) {
            std::vector<Finding> out;
            for (const StabilityRun& r : runs) {
              const NonFiniteSummary n = nonfinite_summary(r.trace);
              bool in_range = true;
              const Image& o = r.trace.final_image();
              for (std::size_t i = 0; i < o.pixel_count(); ++i)
                for (int k = 0; k < 3; ++k) in_range &= o.data()[i * 4 + k] >= 0 && o.data()[i * 4 + k] <= 1;
              const double err = error_against(r, runs[0]).output_max_abs;
              const bool ok = n.nan == 0 && in_range;
              out.push_back({r.backend, ok,
                             "output error vs f64 " + fmt(err) + "; NaN " + std::to_string(n.nan) +
                                 ", Inf " + std::to_string(n.inf) +
                                 (n.first_stage.empty() ? "" : " (first in " + n.first_stage + ")")});
            }
            return out;
          }};
}

NonFiniteSummary nonfinite_summary(const StageTrace& t) {
  NonFiniteSummary s;
  for (const StageResult& r : t.stages) {
    std::uint64_t nan = 0, inf = 0;
    for (std::size_t i = 0; i < r.image.values().size(); ++i) {
      if (i % 4 == 3) continue;
      nan += std::isnan(r.image.values()[i]);
      inf += std::isinf(r.image.values()[i]);
    }
    if ((nan || inf) && s.first_stage.empty()) s.first_stage = r.name;
    s.nan += nan;
    s.inf += inf;
  }
  return s;
}

ErrorSummary error_against(const StabilityRun& run, const StabilityRun& truth) {
  ErrorSummary e;
  const Image& a = run.trace.final_image();
  const Image& b = truth.trace.final_image();
  for (std::size_t i = 0; i < a.values().size(); ++i) {
    if (i % 4 == 3) continue;
    const double x = a.values()[i], y = b.values()[i];
    if (std::isfinite(x) && std::isfinite(y)) e.output_max_abs = std::max(e.output_max_abs, std::fabs(x - y));
  }
  const Image& ba = stage(run, bloom_stage(run));
  const Image& bb = stage(truth, bloom_stage(truth));
  double peak = 0, diff = 0;
  for (std::size_t i = 0; i < bb.values().size(); ++i) {
    if (i % 4 == 3) continue;
    const double x = ba.values()[i], y = bb.values()[i];
    if (!std::isfinite(x) || !std::isfinite(y)) continue;
    peak = std::max(peak, std::fabs(y));
    diff = std::max(diff, std::fabs(x - y));
  }
  e.bloom_max_rel = peak > 0 ? diff / peak : diff;
  return e;
}

namespace {

StabilityCase dynamic_range_case() {
  return {
      "dynamic-range",
      "1e-8 to 1e8 in one image (16 decades across, a checker of +-50% detail)",
      "no NaN; output in [0, 1]; f32 within 1e-5 of the f64 output, f16 within 4 half ULPs (2e-3)",
      [] {
        Image img(256, 64);
        for (int y = 0; y < 64; ++y)
          for (int x = 0; x < 256; ++x) {
            const float v =
                std::pow(10.0f, -8.0f + 16.0f * x / 255.0f) * (((x ^ y) & 4) ? 1.5f : 0.5f);
            set(img, x, y, v, v, v);
          }
        return img;
      },
      [](BloomParams&) {},
      [](const Image& in, const std::vector<StabilityRun>& runs) {
        std::vector<Finding> out;
        for (const StabilityRun& r : runs) {
          Finding f = no_nan(r, in);
          const Image& o = r.trace.final_image();
          for (std::size_t i = 0; i < o.pixel_count(); ++i)
            for (int k = 0; k < 3; ++k) {
              const float v = o.data()[i * 4 + k];
              if (!(v >= 0 && v <= 1)) f.ok = false;
            }
          const double err = error_against(r, runs[0]).output_max_abs;
          f.ok = f.ok && err <= (is_f16(r) ? 2e-3 : 1e-5);
          f.detail = "output error vs f64 " + fmt(err) + "; " + f.detail;
          out.push_back(f);
        }
        return out;
      }};
}

StabilityCase firefly_case(bool mip) {
  return {
      "firefly",
      "one 1e6 pixel beside 1e-3 detail (64x64)",
      mip ? "no NaN; f32: the bloom is finite and largest at the firefly; f16 cannot hold 1e6: "
            "the firefly is stored as Inf (nearest-even) or 65504 (saturating)"
          : "bloom at the firefly = 1e6 x the 10-pass kernel's peak (closed form): 1.2e-7 relative "
            "in f64, 1e-4 in f32; f16 cannot hold 1e6: Inf, or 65504 x the peak (saturating; 11 "
            "half ULPs)",
      [] {
        Image img(64, 64);
        for (int y = 0; y < 64; ++y)
          for (int x = 0; x < 64; ++x) {
            const float v = 1e-3f * (((x + y) & 1) ? 1.5f : 0.5f);
            set(img, x, y, v, v, v);
          }
        set(img, 32, 32, 1e6f, 1e6f, 1e6f);
        return img;
      },
      [](BloomParams&) {},
      [mip](const Image& in, const std::vector<StabilityRun>& runs) {
        std::vector<Finding> out;
        const std::vector<double> r5 = response(5);
        const double expect = 1e6 * r5[r5.size() / 2] * r5[r5.size() / 2];
        for (const StabilityRun& r : runs) {
          Finding f = no_nan(r, in);
          const Image& b = stage(r, bloom_stage(r));
          const double at = b.pixel(32, 32)[1];
          if (is_f16(r)) {
            const std::vector<double> q = response(5);
            const double sat = 65504.0 * q[q.size() / 2] * q[q.size() / 2];
            // Saturated at 65504, then each of 10 passes and the input store may lose one half
            // ULP (2^-10 relative, toward-zero storage).
            f.ok = f.ok &&
                   (std::isinf(at) || (mip ? at > 0 : std::fabs(at - sat) / sat <= 11 * 0x1p-10));
            f.detail = "bloom at the firefly " + fmt(at) + "; " + f.detail;
          } else if (mip) {
            double peak = 0;
            for (std::size_t i = 0; i < b.pixel_count(); ++i)
              peak = std::max(peak, double(b.data()[i * 4 + 1]));
            f.ok = f.ok && std::isfinite(at) && at == peak;
            f.detail = "bloom at the firefly " + fmt(at) + ", peak " + fmt(peak) + "; " + f.detail;
          } else {
            const double rel = std::fabs(at - expect) / expect;
            f.ok = f.ok && rel <= (is_f64(r) ? 1.2e-7 : 1e-4);
            f.detail = "bloom at the firefly " + fmt(at) + " vs " + fmt(expect) + " (relative " +
                       fmt(rel) + "); " + f.detail;
          }
          out.push_back(f);
        }
        return out;
      }};
}

StabilityCase f16_boundaries_case() {
  return {"f16-boundaries",
          "pixels at 65504, 65520, 70000, 2^-14, 2^-24, 2^-26 and 1 (7x1)",
          "stored as f16 the input keeps 65504, 2^-14 and 2^-24 (or flushes the denormal to 0), "
          "turns 65520 and 70000 into Inf (nearest-even) or 65504 (saturating) and 2^-26 into 0; "
          "no NaN anywhere",
          [] {
            Image img(7, 1);
            const float v[7] = {65504.0f, 65520.0f, 70000.0f, 0x1p-14f, 0x1p-24f, 0x1p-26f, 1.0f};
            for (int x = 0; x < 7; ++x) {
              set(img, x, 0, v[x], v[x], v[x]);
            }
            return img;
          },
          [](BloomParams&) {},
          [](const Image& in, const std::vector<StabilityRun>& runs) {
            std::vector<Finding> out;
            for (const StabilityRun& r : runs) {
              Finding f = no_nan(r, in);
              if (is_f16(r)) {
                const Image& s = stage(r, "input");
                auto v = [&](int x) { return s.pixel(x, 0)[0]; };
                const bool over = (std::isinf(v(1)) || v(1) == 65504.0f) &&
                                  (std::isinf(v(2)) || v(2) == 65504.0f);
                const bool ok = v(0) == 65504.0f && over && v(3) == 0x1p-14f &&
                                (v(4) == 0x1p-24f || v(4) == 0.0f) && v(5) == 0.0f && v(6) == 1.0f;
                f.ok = f.ok && ok;
                f.detail = "stored 65504 -> " + fmt(v(0)) + ", 65520 -> " + fmt(v(1)) +
                           ", 70000 -> " + fmt(v(2)) + ", 2^-24 -> " + fmt(v(4)) + ", 2^-26 -> " +
                           fmt(v(5)) + "; " + f.detail;
              }
              out.push_back(f);
            }
            return out;
          }};
}

StabilityCase f16_sum_overflow_case() {
  return {
      "f16-sum-overflow",
      "a 32x32 block of 40000 (each fits f16) on black, 64x64",
      "sums past 65504 (composite; the mip chain's levels) are stored as Inf or 65504 in f16; no "
      "NaN; the output is 1 on the block",
      [] {
        Image img = constant(64, 64, 0.0f);
        for (int y = 16; y < 48; ++y)
          for (int x = 16; x < 48; ++x) set(img, x, y, 40000.0f, 40000.0f, 40000.0f);
        return img;
      },
      [](BloomParams&) {},
      [](const Image& in, const std::vector<StabilityRun>& runs) {
        std::vector<Finding> out;
        for (const StabilityRun& r : runs) {
          Finding f = no_nan(r, in);
          const float centre = r.trace.final_image().pixel(32, 32)[0];
          const float hdr = stage(r, "composite").pixel(32, 32)[0];
          f.ok = f.ok && centre == 1.0f;
          f.detail =
              "composite at the centre " + fmt(hdr) + ", output " + fmt(centre) + "; " + f.detail;
          out.push_back(f);
        }
        return out;
      }};
}

StabilityCase nonfinite_case(NonFinite policy, bool mip) {
  const std::string pn = to_string(policy);
  std::string expectation =
      policy == NonFinite::error ? "the image is refused (exit 2), nothing runs"
      : policy == NonFinite::propagate
          ? (mip ? "NaN/Inf are kept in the input stage; the pyramid may spread them over the image"
                 : "NaN/Inf stay within the blur's footprint of the bad pixels (41 texels per "
                   "axis, +1 for GL filtering)")
          : "no NaN in any stage; the output is finite (Inf may appear "
            "where the tone map of a large negative value overflows, or an f16 sum passes 65504)";
  StabilityCase c{"nonfinite-" + pn,
                  "NaN, +Inf and -Inf pixels in a 48x48 scene under --nonfinite " + pn,
                  expectation,
                  [] {
                    Image img = constant(48, 48, 0.5f);
                    for (int y = 20; y < 28; ++y)
                      for (int x = 20; x < 28; ++x) set(img, x, y, 4.0f, 4.0f, 4.0f);
                    set(img, 10, 10, NAN, NAN, NAN);
                    set(img, 24, 24, INFINITY, INFINITY, INFINITY);
                    set(img, 40, 12, -INFINITY, -INFINITY, -INFINITY);
                    return img;
                  },
                  [policy](BloomParams& p) { p.nonfinite = policy; },
                  [policy, mip](const Image&, const std::vector<StabilityRun>& runs) {
                    std::vector<Finding> out;
                    for (const StabilityRun& r : runs) {
                      const NonFiniteSummary s = nonfinite_summary(r.trace);
                      Finding f{r.backend, true,
                                "NaN " + std::to_string(s.nan) + ", Inf " + std::to_string(s.inf)};
                      if (policy == NonFinite::zero || policy == NonFinite::clamp) {
                        bool finite_out = true;
                        for (float v : r.trace.final_image().values())
                          finite_out &= std::isfinite(v);
                        f.ok = s.nan == 0 && finite_out;
                      } else if (!mip) {
                        // Non-finite output only within 20 (+1) texels of a bad pixel per axis.
                        const Image& o = r.trace.final_image();
                        const int bad[3][2] = {{10, 10}, {24, 24}, {40, 12}};
                        int outside = 0;
                        for (int y = 0; y < o.height(); ++y)
                          for (int x = 0; x < o.width(); ++x) {
                            if (std::isfinite(o.pixel(x, y)[0])) continue;
                            bool near = false;
                            for (const auto& b : bad)
                              near |= std::abs(x - b[0]) <= 21 && std::abs(y - b[1]) <= 21;
                            outside += !near;
                          }
                        f.ok = outside == 0;
                        f.detail += ", non-finite outputs outside the footprint: " +
                                    std::to_string(outside);
                      } else {
                        const Image& i = stage(r, "input");
                        f.ok = std::isnan(i.pixel(10, 10)[0]) && std::isinf(i.pixel(24, 24)[0]);
                      }
                      out.push_back(f);
                    }
                    return out;
                  },
                  policy == NonFinite::error};
  return c;
}

// A constant field under the parameters `adjust` sets, against its closed form.
StabilityCase constant_case(std::string name, std::string desc, int w, int h, float c,
                            std::function<void(BloomParams&)> adjust) {
  return {
      std::move(name),
      std::move(desc),
      "output = (1 - exp(-(c + s bloom) e))^(1/gamma) with bloom = c (gaussian) or c K (mip, "
      "K levels): 1.2e-7 relative in f64 (its trace is stored in float), 2e-6 in f32, 4e-3 in f16",
      [=] { return constant(w, h, c); },
      std::move(adjust),
      [c](const Image& in, const std::vector<StabilityRun>& runs) {
        return check_constant(in, runs, c, 2e-6, 4e-3);
      }};
}

std::vector<StabilityCase> constant_cases() {
  std::vector<StabilityCase> cases;
  cases.push_back(constant_case("exposure-1e-6", "constant 5 (48x32), --exposure 1e-6", 48, 32,
                                5.0f, [](BloomParams& p) { p.exposure = 1e-6f; }));
  cases.push_back(constant_case("exposure-1e6", "constant 5 (48x32), --exposure 1e6", 48, 32, 5.0f,
                                [](BloomParams& p) { p.exposure = 1e6f; }));
  cases.push_back(constant_case("threshold-0",
                                "constant 0.25 (48x32), --threshold 0: every pixel bright", 48, 32,
                                0.25f, [](BloomParams& p) { p.threshold = 0.0f; }));
  cases.push_back(constant_case("threshold-negative", "constant 0.25 (48x32), --threshold -1", 48,
                                32, 0.25f, [](BloomParams& p) { p.threshold = -1.0f; }));
  cases.push_back(constant_case("gamma-1",
                                "constant 2 (48x32), --gamma 1: the output is the tone map", 48, 32,
                                2.0f, [](BloomParams& p) { p.gamma = 1.0f; }));
  for (auto [w, h] : {std::pair{1, 1}, {1, 7}, {7, 1}, {3, 5}, {4097, 3}})
    cases.push_back(constant_case("size-" + std::to_string(w) + "x" + std::to_string(h),
                                  "constant 2 at " + std::to_string(w) + "x" + std::to_string(h), w,
                                  h, 2.0f, [](BloomParams&) {}));
  return cases;
}

StabilityCase passes_case(int passes) {
  const double n = passes;
  return {"passes-" + std::to_string(passes),
          "constant 3 (32x32) through " + std::to_string(passes) + " blur passes: energy drift",
          "bloom = 3 (the weights sum to 1): f64 1.2e-7 relative (float trace); f32 within N (1e-7 "
          "+ 9 2^-24); f16 "
          "within N half ULPs (toward-zero storage loses up to one ULP per pass)",
          [] { return constant(32, 32, 3.0f); },
          [passes](BloomParams& p) { p.passes = passes; },
          [n](const Image& in, const std::vector<StabilityRun>& runs) {
            std::vector<Finding> out;
            for (const StabilityRun& r : runs) {
              Finding f = no_nan(r, in);
              const Image& b = stage(r, bloom_stage(r));
              double worst = 0;
              for (std::size_t i = 0; i < b.pixel_count(); ++i)
                worst = std::max(worst, std::fabs(b.data()[i * 4] - 3.0) / 3.0);
              const double tol = is_f64(r)   ? 1.2e-7
                                 : is_f16(r) ? std::max(1.0, n) * std::ldexp(1.0, -10) + 1e-12
                                             : std::max(1.0, n) * (1e-7 + 9 * std::ldexp(1.0, -24));
              f.ok = f.ok && worst <= tol;
              f.detail =
                  "bloom drift " + fmt(worst) + " relative (allowed " + fmt(tol) + "); " + f.detail;
              out.push_back(f);
            }
            return out;
          }};
}

StabilityCase threshold_tie_case() {
  return {"threshold-tie",
          "the threshold-tie scene: luminance exactly 1, one float above and below",
          "exactly the band one float above the threshold is bright (1024 pixels) in every run",
          [] { return make_scene("threshold-tie"); },
          [](BloomParams&) {},
          [](const Image& in, const std::vector<StabilityRun>& runs) {
            std::vector<Finding> out;
            for (const StabilityRun& r : runs) {
              Finding f = no_nan(r, in);
              const Image& b = stage(r, "bright");
              std::size_t n = 0;
              for (std::size_t i = 0; i < b.pixel_count(); ++i) n += b.data()[i * 4] != 0;
              f.ok = f.ok && n == 1024;
              f.detail = std::to_string(n) + " bright pixels; " + f.detail;
              out.push_back(f);
            }
            return out;
          }};
}

StabilityCase karis_negative_case() {
  return {"karis-negative",
          "negative colours with luminance -0.86 and exactly -1 (32x32), --karis, "
          "--threshold -2 (they pass the threshold)",
          "Karis weights 1 / (1 + max(L, 0)) stay finite: no NaN or Inf in any stage",
          [] {
            Image img(32, 32);
            for (int y = 0; y < 32; ++y)
              for (int x = 0; x < 32; ++x) {
                if ((x + y) % 2)
                  set(img, x, y, -1.3f, -0.81f, -0.08f);
                else
                  set(img, x, y, -1.0f, -1.0f, -1.0f);
              }
            return img;
          },
          [](BloomParams& p) {
            p.karis = true;
            p.threshold = -2.0f;
          },
          [](const Image&, const std::vector<StabilityRun>& runs) {
            std::vector<Finding> out;
            for (const StabilityRun& r : runs) {
              const NonFiniteSummary s = nonfinite_summary(r.trace);
              out.push_back({r.backend, s.nan == 0 && s.inf == 0,
                             "NaN " + std::to_string(s.nan) + ", Inf " + std::to_string(s.inf)});
            }
            return out;
          }};
}

}  // namespace

std::vector<StabilityCase> stability_cases(Method method) {
  const bool mip = method == Method::mip;
  std::vector<StabilityCase> cases = {dynamic_range_case(), firefly_case(mip),
                                      f16_boundaries_case(), f16_sum_overflow_case()};
  for (NonFinite policy :
       {NonFinite::zero, NonFinite::clamp, NonFinite::propagate, NonFinite::error})
    cases.push_back(nonfinite_case(policy, mip));
  for (StabilityCase& c : constant_cases()) cases.push_back(std::move(c));
  if (!mip) {
    for (int passes : {0, 1, 100}) cases.push_back(passes_case(passes));
    cases.push_back(threshold_tie_case());
  } else {
    cases.push_back(karis_negative_case());
  }
  return cases;
}

}  // namespace bloomref
