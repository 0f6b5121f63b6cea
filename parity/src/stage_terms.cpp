// The terms of each kind of stage (stage_terms.h), and the row operations a band shares.
#include "stage_terms.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "bloomref/engine/fast_stages.h"
#include "bloomref/mip.h"
#include "bloomref/stages.h"

namespace bloomref::parity::detail {

BandScratch& band_scratch() {
  thread_local BandScratch s;
  return s;
}

void add_rows(float* a, const float* b, std::size_t n) {
  for (std::size_t i = 0; i < n * kChannels; ++i) a[i] += b[i];
}

void override_rows(const StageOverride* over, float* b, std::size_t n) {
  if (over && (over->scale != 1.0 || over->absolute != 0.0))
    for (std::size_t i = 0; i < n * kChannels; ++i)
      b[i] = static_cast<float>(b[i] * over->scale + over->absolute);
}

void put_rows(Image& img, int y0, const float* rows, std::size_t n) {
  float* d = img.pixel(0, y0);
  for (std::size_t t = 0; t < n; ++t) {
    float* o = d + t * kChannels;
    const float* r = rows + t * kChannels;
    o[0] = r[0];
    o[1] = r[1];
    o[2] = r[2];
    o[3] = 0.0f;
  }
}

namespace {

// 1 - exp(-h k) has slope k exp(-h k), largest at the low end of h +- e.
float through_tonemap(double h, double e, double exposure) {
  return std::isfinite(h) && std::isfinite(e)
             ? static_cast<float>(exposure * std::exp(-(h - e) * exposure) * e)
             : INFINITY;
}

}  // namespace

// Gamma's slope is unbounded near black: there, bound by the interval's image. Where e is at
// most 2^-10 of m, by the mean value theorem instead, with one pow for two: the width of the
// image of [m - e, m + e] under x^g is 2e g xi^(g-1) for some xi inside, and the slope is
// largest at the low end for g < 1 (the high end for g > 1). That is at most
// ((m + e) / (m - e))^|g - 1| - 1, about 0.1%, more than the width itself.
float through_output(double m, double e, double gamma) {
  const double g = 1.0 / gamma;
  if (!std::isfinite(m) || !std::isfinite(e)) return INFINITY;
  if (e >= 0 && e <= std::ldexp(m, -10))
    return static_cast<float>(2 * e * g * std::pow(g < 1 ? m - e : m + e, g - 1));
  const double hi = std::max(m + e, 0.0), lo = std::max(m - e, 0.0);
  if (g > 0 && g <= 1 && hi >= 0x1p-60 && hi <= 0x1p60 && (lo == 0 || lo >= 0x1p-60)) {
    // One value per texel (most of an image is dark, beyond the mean value bound): powf, much
    // faster than pow, with each end moved outward by 2^-18 of itself. That covers powf's
    // error (under 1 ULP, 2^-23), the ends' rounding to float (g 2^-24) and g's (|ln x| g 2^-24,
    // under 2^-18.6 for x within 2^-60 and 2^60): 2^-18.5 at most, and the results are normal
    // floats. The width grows by at most 2^-17 m^g over 2 g e m^(g-1): under 1% where e is
    // 2^-10 of m, less beyond.
    const float gf = static_cast<float>(g);
    const double top = std::pow(static_cast<float>(hi), gf) * (1 + 0x1p-18);
    const double bottom = lo == 0 ? 0.0 : std::pow(static_cast<float>(lo), gf) * (1 - 0x1p-18);
    return static_cast<float>(top - bottom);
  }
  return static_cast<float>(std::pow(hi, g) - std::pow(lo, g));
}

namespace {

double srgb_decode(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}
double srgb_encode(double v) {
  return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
}

}  // namespace

float capture_code(const CapturedStage& cap, float& o) {
  const double h = 0.5 / ((1 << cap.code_bits) - 1);
  if (!std::isnan(o)) o = std::clamp(o, 0.0f, 1.0f);
  double step = h;
  if (cap.srgb && std::isfinite(o)) {
    const double e = srgb_encode(o);
    step = std::max(srgb_decode(std::min(e + h, 1.0)) - o, o - srgb_decode(std::max(e - h, 0.0)));
  }
  return static_cast<float>(step * (1 + 1e-6));  // the decode's own rounding
}

void capture_codes(const CapturedStage& cap, float* oracle, float* codes, std::size_t n) {
  for (std::size_t i = 0; i < n * kChannels; ++i)
    if (i % kChannels != 3) codes[i] = capture_code(cap, oracle[i]);
}

namespace {

Image copy_of(ConstImageView v, ImagePool& pool) {
  Image out = pool.take(v.width, v.height);
  for (int y = 0; y < v.height; ++y)
    std::copy(v.row(y), v.row(y) + std::size_t(v.width) * kChannels, out.view().row(y));
  return out;
}

}  // namespace

Image oracle_stage(const Plan& plan, const StageSpec& spec, ConstImageView sanitized,
                   const std::vector<ConstImageView>& in, int subtexel_bits, ImagePool& pool) {
  const BloomParams& p = plan.params;
  const int threads = p.threads;
  Image out;
  switch (spec.kind) {
    case StageKind::input:
      return copy_of(sanitized, pool);
    case StageKind::bright:
      out = pool.take(sanitized.width, sanitized.height);
      extract_bright(sanitized, out.view(), p.threshold, threads, false, nullptr, nullptr,
                     luma_rule(p));
      break;
    case StageKind::blur:
      out = pool.take(in[0].width, in[0].height);
      blur_pass_fast(in[0], out.view(), {spec.axis, &kernel_for(p.kernel), subtexel_bits}, threads);
      break;
    case StageKind::down: {
      const LevelSize& l = plan.levels[spec.pass - 1];
      out = pool.take(l.width, l.height);
      downsample(in[0], out.view(),
                 downsample_options(p, spec.pass, sanitized.width, sanitized.height, subtexel_bits),
                 threads);
      break;
    }
    case StageKind::up:
      if (p.level_combine == LevelCombine::sum) {
        out = pool.take(plan.levels[0].width, plan.levels[0].height);
        sum_levels(in, out.view(), p.level_factors, p.level_radius, p.level_strength,
                   subtexel_bits, threads);
        break;
      }
      [[fallthrough]];
    case StageKind::bloom: {
      const bool up = spec.kind == StageKind::up;
      out = up ? pool.take(in[1].width, in[1].height)
               : pool.take(sanitized.width, sanitized.height);
      if (!up && p.bloom_upscale == BloomUpscale::bilinear)
        upscale_bilinear(in[0], out.view(), subtexel_bits, threads);
      else
        upsample_tent(in[0], up ? in[1] : ConstImageView{}, out.view(), subtexel_bits, threads,
                      nullptr, p.upsample_radius,
                      up ? level_blend(p, spec.pass, int(plan.levels.size())) : LevelBlend{},
                      p.texel_step == TexelStep::target,
                      up ? p.upsample : UpsampleFilter::tent);
      break;
    }
    case StageKind::composite:
      out = pool.take(in[0].width, in[0].height);
      if (p.composite_mode == CompositeMode::mix)
        composite_mix(in[0], in[1], out.view(), p.strength, threads);
      else
        composite(in[0], in[1], out.view(), p.strength, threads);
      break;
    case StageKind::tonemap:
      out = pool.take(in[0].width, in[0].height);
      tonemap_fast(in[0], out.view(), p.exposure, threads);
      break;
    case StageKind::output:
      out = pool.take(in[0].width, in[0].height);
      encode_output_fast(in[0], out.view(), p.gamma, threads);
      break;
  }
  return out;
}

namespace {

// The isolated oracle of a stage, from what the isolated oracle reads.
StageTerms with_oracle(const StageSpec& spec, const std::vector<ConstImageView>& cin,
                       const TermInputs& at) {
  StageTerms t;
  t.oracle = oracle_stage(at.plan, spec, at.sanitized, cin, at.profile.subtexel_bits, at.pool);
  // An 8-bit level clamps every value above 1 (most of an HDR level): compared as stored, so
  // that what the clamp removes is not reported as an error within its bound (tolerance.cpp).
  if (stage_storage(at.plan.params, spec) == Storage::rgba8)
    store(t.oracle.view(), Storage::rgba8, HalfRounding::nearest_even, at.ctx.threads);
  return t;
}

// Whether a stage reading `in` reads an 8-bit stage (the scene, a pass, a level), whose
// lookups may be filtered in 8-bit fixed point.
bool reads_8bit(const Plan& plan, const std::vector<std::string>& in) {
  for (const std::string& n : in)
    if (const StageSpec* s = find_stage(plan, n); s && stage_storage(plan.params, *s) == Storage::rgba8)
      return true;
  return false;
}

std::vector<ConstImageView> isolated_inputs(const std::vector<std::string>& in,
                                            const TermInputs& at) {
  std::vector<ConstImageView> cin;
  for (const std::string& n : in) cin.push_back(at.isolated(n));
  return cin;
}

// A per-value function f(value of `at`, value of the rows) of an image's rows (an input's
// end-to-end bound, or the error it carries), plus the isolated bound when `plus_bound`.
template <class F>
BandRows through(BoundRows rows, ConstImageView at, F f, bool plus_bound) {
  return [=](int y0, int y1, const float* b, float* out) {
    const int w = at.width;
    const float* e = rows.rows(y0, y1, w, band_scratch().read[0]);
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          const std::size_t i = (std::size_t(y - y0) * w + x) * kChannels + c;
          const float v = f(at.pixel(x, y)[c], e[i]);
          out[i] = plus_bound ? v + b[i] : v;
        }
  };
}

// Input, bright, tonemap and output: bounds of the value at the same texel; the end-to-end
// bound through the tone map's and gamma's slopes.
StageTerms point_terms(const StageSpec& spec, const std::vector<std::string>& in,
                       const TermInputs& at) {
  const BloomParams& p = at.plan.params;
  const std::vector<ConstImageView> cin = isolated_inputs(in, at);
  StageTerms t = with_oracle(spec, cin, at);
  const ConstImageView o = t.oracle.cview();
  if (spec.kind == StageKind::input || spec.kind == StageKind::bright) {
    t.bound = spec.kind == StageKind::input ? input_bounds(o, at.ctx)
                                            : bright_bounds(at.sanitized, p.threshold, at.ctx, luma_rule(p));
    t.end_to_end = [w = o.width](int y0, int y1, const float* b, float* out) {
      std::copy(b, b + std::size_t(y1 - y0) * w * kChannels, out);
    };
    return t;
  }
  const bool tm = spec.kind == StageKind::tonemap;
  t.bound = tm ? tonemap_bounds(cin[0], o, p.exposure, at.ctx)
               : output_bounds(cin[0], o, p.gamma, at.ctx);
  const double k = tm ? double(p.exposure) : double(p.gamma);
  auto f = [tm, k](float h, float e) { return tm ? through_tonemap(h, e, k) : through_output(h, e, k); };
  t.end_to_end = through(at.end_to_end(in[0]), at.full(in[0]), f, true);
  if (const Image* ce = at.carried(in[0])) t.inherited = through(BoundRows{ce, nullptr}, cin[0], f, false);
  return t;
}

// composite: scene + strength * bloom; both inputs' end-to-end bounds and carried errors add,
// the bloom's scaled.
StageTerms composite_terms(const StageSpec& spec, const std::vector<std::string>& in,
                           const TermInputs& at) {
  const float strength = at.plan.params.strength;
  const std::vector<ConstImageView> cin = isolated_inputs(in, at);
  StageTerms t = with_oracle(spec, cin, at);
  const int w = t.oracle.width();
  t.bound = composite_bounds(cin[0], cin[1], t.oracle.cview(), strength, at.ctx);
  const BoundRows e0 = at.end_to_end(in[0]), e1 = at.end_to_end(in[1]);
  t.end_to_end = [=](int y0, int y1, const float* b, float* out) {
    BandScratch& s = band_scratch();
    const float *a = e0.rows(y0, y1, w, s.read[0]), *d = e1.rows(y0, y1, w, s.read[1]);
    for (std::size_t i = 0; i < std::size_t(y1 - y0) * w * kChannels; ++i)
      out[i] = a[i] + static_cast<float>(double(strength) * d[i]) + b[i];
  };
  const Image *es = at.carried(in[0]), *eb = at.carried(in[1]);
  if (es || eb)
    t.inherited = [=](int y0, int y1, const float*, float* out) {
      for (int y = y0; y < y1; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 3; ++c) {
            float v = 0.0f;
            if (es) v += es->pixel(x, y)[c];
            if (eb) v += static_cast<float>(double(strength) * eb->pixel(x, y)[c]);
            out[(std::size_t(y - y0) * w + x) * kChannels + c] = v;
          }
    };
  return t;
}

// blur.k: the bounds of the pass; the end-to-end bound and the carried error propagated
// through it.
StageTerms blur_terms(const StageSpec& spec, const std::vector<std::string>& in,
                      const TermInputs& at) {
  const Kernel& kernel = kernel_for(at.plan.params.kernel);
  const ConstImageView src = at.isolated(in[0]);
  StageTerms t = with_oracle(spec, {src}, at);
  t.bound = blur_bounds(src, t.oracle.cview(), spec.axis, kernel, at.ctx);
  const int w = src.width;
  auto e = std::make_shared<BlurPropagation>(at.end_to_end(in[0]).image->cview(), spec.axis, kernel);
  t.end_to_end = [e, w](int y0, int y1, const float* b, float* out) {
    e->rows(y0, y1, out);
    add_rows(out, b, std::size_t(y1 - y0) * w);
  };
  if (const Image* ce = at.carried(in[0])) {
    auto c = std::make_shared<BlurPropagation>(ce->cview(), spec.axis, kernel);
    t.inherited = [c](int y0, int y1, const float*, float* out) { c->rows(y0, y1, out); };
  }
  return t;
}

// down.k, up.k, bloom: every tap's window on the level it reads (up.1 under LevelCombine::sum:
// every blurred level's lookup). The carried error enters each tap (and the threshold's band):
// the bound with it, less the bound without, is what it adds. The end-to-end bound is the same
// bound on the full run with the inputs' end-to-end bounds.
StageTerms mip_terms(const StageSpec& spec, const std::vector<std::string>& in,
                     const TermInputs& at) {
  const BloomParams& p = at.plan.params;
  const bool down = spec.kind == StageKind::down, up = spec.kind == StageKind::up;
  const bool sum = up && p.level_combine == LevelCombine::sum;
  const std::vector<ConstImageView> cin = isolated_inputs(in, at);
  StageTerms t = with_oracle(spec, cin, at);
  const ConstImageView o = t.oracle.cview(), none{};
  const BoundContext& ctx = at.ctx;
  // The bound on inputs `a` with errors `e` (null: none) into `out`.
  auto bounds = [&](const std::vector<ConstImageView>& a, ConstImageView out,
                    const std::vector<const Image*>& e) -> std::unique_ptr<StageBounds> {
    if (sum) return sum_bounds(a, out, e, p, ctx);
    if (down)
      return down_bounds(a[0], out, e[0],
                         downsample_options(p, spec.pass, at.sanitized.width, at.sanitized.height,
                                            at.profile.subtexel_bits),
                         ctx);
    return up_bounds(a[0], up ? a[1] : none, out, e[0], up ? e[1] : nullptr,
                     up ? level_blend(p, spec.pass, int(at.plan.levels.size())) : LevelBlend{},
                     ctx, up ? p.upsample : UpsampleFilter::tent);
  };
  std::vector<const Image*> carried, e2e;
  std::vector<ConstImageView> full;
  bool any_carried = false;
  for (const std::string& n : in) {
    carried.push_back(at.carried(n));
    any_carried = any_carried || carried.back();
    full.push_back(at.full(n));
    e2e.push_back(at.end_to_end(n).image);
  }
  t.bound = bounds(cin, o, std::vector<const Image*>(in.size(), nullptr));
  const int w = o.width;
  if (any_carried) {
    std::shared_ptr<StageBounds> with = bounds(cin, o, carried);
    t.inherited = [with, w](int y0, int y1, const float* b, float* out) {
      with->rows(y0, y1, out, nullptr);
      for (std::size_t i = 0; i < std::size_t(y1 - y0) * w * kChannels; ++i)
        out[i] += static_cast<float>(-1.0 * b[i]);
    };
  }
  std::shared_ptr<StageBounds> e = bounds(full, at.full(spec.name), e2e);
  t.end_to_end = [e](int y0, int y1, const float*, float* out) { e->rows(y0, y1, out, nullptr); };
  return t;
}

}  // namespace

StageTerms stage_terms(const StageSpec& spec, const std::vector<std::string>& in,
                       const TermInputs& at) {
  // Lookups of a stage stored in 8 bits (the scene, a pass, a level) are filtered as 8-bit
  // textures are: every bound of a stage that reads one says so.
  TermInputs here = at;
  here.ctx.unorm8_reads = reads_8bit(at.plan, in);
  switch (spec.kind) {
    case StageKind::blur: return blur_terms(spec, in, here);
    case StageKind::down:
    case StageKind::up:
    case StageKind::bloom: return mip_terms(spec, in, here);
    case StageKind::composite: return composite_terms(spec, in, here);
    default: return point_terms(spec, in, here);
  }
}

}  // namespace bloomref::parity::detail
