// Test helpers for a user's shaders run through gpu/user_pipeline.h: each stage of the trace
// against bloomref's CPU stages (reference/include/bloomref/stages.h) recomputed from the trace's
// own previous stage (isolated) or from the scene (the full CPU run, end to end).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/kernel.h"
#include "bloomref/plan.h"
#include "bloomref/stages.h"

namespace bloomref::test {

struct StageError {
  std::string stage;
  double max_abs = 0;             ///< largest |gl - cpu| over finite RGB values
  double max_ratio = 0;           ///< largest |gl - cpu| / (abs_tol + rel_tol * |cpu|)
  int x = 0, y = 0, channel = 0;  ///< where max_ratio is
  double gl = 0, cpu = 0;
  std::size_t nan_gl = 0, nan_cpu = 0;        ///< non-finite RGB values on each side
  int abs_x = 0, abs_y = 0, abs_channel = 0;  ///< where max_abs is
};

/// Compares RGB of `gl` with `cpu`; ratios against abs_tol + rel_tol * |cpu| + extra (per value,
/// RGBA layout, optional).
inline StageError stage_error(const std::string& stage, const Image& gl, const Image& cpu,
                              double abs_tol, double rel_tol, const Image* extra = nullptr) {
  StageError e;
  e.stage = stage;
  for (int y = 0; y < gl.height(); ++y)
    for (int x = 0; x < gl.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double g = gl.pixel(x, y)[c], o = cpu.pixel(x, y)[c];
        e.nan_gl += !std::isfinite(g);
        e.nan_cpu += !std::isfinite(o);
        if (!std::isfinite(g) || !std::isfinite(o)) continue;
        const double d = std::fabs(g - o);
        const double bound = abs_tol + rel_tol * std::fabs(o) + (extra ? extra->pixel(x, y)[c] : 0);
        const double r = d == 0 ? 0 : d / bound;
        if (d > e.max_abs) e.max_abs = d, e.abs_x = x, e.abs_y = y, e.abs_channel = c;
        if (r > e.max_ratio) {
          e.max_ratio = r;
          e.x = x, e.y = y, e.channel = c, e.gl = g, e.cpu = o;
        }
      }
  return e;
}

/// How far, in texels, a lookup may land from where the CPU puts it: the interpolated texture
/// coordinate, the added offset and the sampler's scaling by the size n each round in float
/// near 1 (2^-24 each, times n in texels); 16 such roundings is 2^-20 n.
inline double lookup_error_texels(int n) {
  return std::ldexp(double(n), -20);
}

/// Per value: the largest difference between two adjacent texels within rx columns and ry rows
/// of it, times lookup_error_texels along that axis: what lookups landing that far off can change
/// in a weighted sum whose weights add to 1. Both axes count: a horizontal pass's lookups also
/// land off in t (measured on llvmpipe: its interpolated TexCoords are within one float ULP of
/// (y + 0.5) / h, so a pass along x reads ~2^-24 h of the rows above or below; next to a row of
/// 400s that is 0.02 where the CPU gives 0).
inline Image lookup_term(const Image& src, int rx, int ry) {
  const int w = src.width(), h = src.height();
  const double ex = lookup_error_texels(w), ey = lookup_error_texels(h);
  Image out(w, h, 0.0f);
  auto at = [&](int i, int j, int c) {
    return double(src.pixel(std::clamp(i, 0, w - 1), std::clamp(j, 0, h - 1))[c]);
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        double m = 0;
        for (int j = y - ry - 1; j <= y + ry; ++j)
          for (int i = x - rx - 1; i <= x + rx; ++i) {
            const double v = at(i, j, c);
            m = std::max(
                {m, ex * std::fabs(at(i + 1, j, c) - v), ey * std::fabs(at(i, j + 1, c) - v)});
          }
        out.pixel(x, y)[c] = std::isfinite(m) ? static_cast<float>(m) : 0.0f;
      }
  return out;
}

/// One binary16 ULP relative (either rounding of a write), or 0 for float storage.
inline double rel_store(Storage s) {
  return s == Storage::f16 ? 1.0 / 1024 : 0.0;
}

/// Largest |value| over RGB (finite values).
inline double max_magnitude(const Image& img) {
  double m = 0;
  for (std::size_t i = 0; i < img.values().size(); ++i)
    if (i % 4 != 3 && std::isfinite(img.values()[i]))
      m = std::max(m, std::fabs(double(img.values()[i])));
  return m;
}

/// What the CPU stages give for a LearnOpenGL-style final pass (composite, tone map and gamma in
/// one draw, so nothing is stored between them): pow(max(1 - exp(-(scene + bloom) * exposure),
/// 0), 1 / gamma), stored as the target stores it.
inline Image cpu_final(const Image& scene, const Image& bloom, float exposure, float gamma,
                       Storage storage, HalfRounding rounding) {
  Image hdr(scene.width(), scene.height()), mapped(hdr.width(), hdr.height()),
      out(hdr.width(), hdr.height());
  composite(scene.cview(), bloom.cview(), hdr.view(), 1.0f, 1);
  tonemap(hdr.cview(), mapped.view(), exposure, 1);
  encode_output(mapped.cview(), out.view(), gamma, 1);
  store(out.view(), storage, rounding, 1);
  return out;
}

/// Tolerances of a stage (see the callers' comments for their derivation).
struct Tolerance {
  double abs_of_max;  ///< times the largest magnitude of the stage's input
  double abs;         ///< absolute
  double rel;         ///< times |cpu|
};

/// Isolated errors of every stage of `t`: bright from the scene, blur.k from the trace's
/// blur.(k-1) (or bright), output from the trace's input and last blur.
inline std::vector<StageError> isolated_errors(const Image& scene, const StageTrace& t,
                                               const gpu::UserPipelineOptions& opt,
                                               HalfRounding rounding, const Tolerance& blur_tol,
                                               const Tolerance& out_tol, float gamma = 2.2f) {
  const Storage storage = gpu::storage_of(opt.format);
  const int w = scene.width(), h = scene.height();
  std::vector<StageError> out;
  Image sanitized(w, h);
  sanitize(scene.cview(), sanitized.view(), opt.nonfinite, storage, 1);
  Image bright(w, h);
  extract_bright(sanitized.cview(), bright.view(), opt.threshold, 1);
  store(bright.view(), storage, rounding, 1);
  // A user's bright pass looks the scene up at interpolated coordinates (lookup_term); the
  // oracle's bright image is uploaded as it is, and then meets this bound with error 0.
  const Image bright_look = lookup_term(sanitized, 1, 1);
  out.push_back(
      stage_error("bright", t.find("bright")->image, bright, 0, rel_store(storage), &bright_look));
  const Image* prev = &t.find("bright")->image;
  for (int k = 1; k <= opt.passes; ++k) {
    const std::string name = "blur." + std::to_string(k);
    Image b(w, h);
    BlurPassOptions o;
    o.axis = k % 2 ? Axis::horizontal : Axis::vertical;
    o.kernel = &kernel_discrete9();
    blur_pass(prev->cview(), b.view(), o, 1);
    store(b.view(), storage, rounding, 1);
    const double m = max_magnitude(*prev);
    const bool hor = o.axis == Axis::horizontal;
    const Image look = lookup_term(*prev, hor ? 5 : 1, hor ? 1 : 5);
    out.push_back(stage_error(name, t.find(name)->image, b, blur_tol.abs_of_max * m + blur_tol.abs,
                              blur_tol.rel, &look));
    prev = &t.find(name)->image;
  }
  const Image& scene_in = t.find("input")->image;
  const Image none(w, h, 0.0f);
  const Image expect =
      cpu_final(scene_in, opt.bloom ? *prev : none, opt.exposure, gamma, storage, rounding);
  // The lookups of the scene and the bloom may land off the texel centre (lookup_term), and
  // GLSL's exp is within (3 + 2|x|) ULP (GLSL 4.50, 4.7.1): both go through the tone map and
  // gamma as an interval, as gamma's slope is unbounded near 0 (1 - exp(-0) one ULP of 1 off
  // gives pow(2^-24, 1 / 2.2) = 0.00052).
  const Image ls = lookup_term(scene_in, 1, 1), lb = lookup_term(*prev, 1, 1);
  Image extra(w, h, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const double hdr = double(scene_in.pixel(x, y)[c]) + (opt.bloom ? prev->pixel(x, y)[c] : 0);
        const double d = ls.pixel(x, y)[c] + (opt.bloom ? lb.pixel(x, y)[c] : 0);
        auto mapped = [&](double v) { return -std::expm1(-v * opt.exposure); };
        const double arg = std::fabs(hdr * opt.exposure);
        const double exp_err = (3 + 2 * arg) * std::ldexp(std::exp(-(hdr - d) * opt.exposure), -23);
        const double lo = std::max(mapped(hdr - d) - exp_err, 0.0);
        const double hi = std::max(mapped(hdr + d) + exp_err, 0.0);
        const double e = std::pow(hi, 1.0 / gamma) - std::pow(lo, 1.0 / gamma);
        extra.pixel(x, y)[c] = std::isfinite(e) ? static_cast<float>(e) : 0.0f;
      }
  out.push_back(
      stage_error("output", t.find("output")->image, expect, out_tol.abs, out_tol.rel, &extra));
  return out;
}

/// The full CPU run of the same pipeline (gaussian, discrete9, f32 precision, full plan).
inline StageTrace cpu_trace(const Image& scene, const gpu::UserPipelineOptions& opt,
                            HalfRounding rounding) {
  BloomParams p;
  p.passes = opt.passes;
  p.exposure = opt.exposure;
  p.threshold = opt.threshold;
  p.nonfinite = opt.nonfinite;
  p.storage = gpu::storage_of(opt.format);
  p.plan = PlanMode::full;
  p.threads = 1;
  ExecuteOptions eo;
  eo.keep_all = true;
  eo.half_rounding = rounding;
  return execute(make_plan(p, scene.cview()), scene.cview(), eo);
}

}  // namespace bloomref::test
