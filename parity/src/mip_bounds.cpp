// Bounds of the mip chain's stages (down.k, up.k, bloom): every lookup is a 2-D GL_LINEAR fetch
// whose coordinates may be off by the coordinate error on both axes, so each tap contributes
// its weight times (delta_x + delta_y) x the range of the 4x4 texels it may touch, plus the
// rounding of the lerps and sums. The first level thresholds each tap: a tap whose luminance is
// within its own error of the threshold may be kept or dropped (its whole value). The Karis
// average divides by 1 + max(L, 0): its weights move by at most dL / (1 + max(L, 0)). `error` images, when given, are the end-to-end bounds of
// the inputs and are added to each tap's perturbation.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

#include "bloomref/mip.h"
#include "bloomref/parallel.h"
#include "tolerance.h"

namespace bloomref::parity::detail {
namespace {

// Range, magnitude and (for error images) maximum over the 4x4 texels [b-1, b+2]^2.
struct Window2D {
  Image range, magnitude;
};

Window2D window4x4(ConstImageView src, int threads) {
  const int w = src.width, h = src.height;
  Window2D out{Image(w, h, 0.0f), Image(w, h, 0.0f)};
  parallel_rows(h, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          float mn = INFINITY, mx = -INFINITY, ma = 0;
          for (int dy = -1; dy <= 2; ++dy)
            for (int dx = -1; dx <= 2; ++dx) {
              const float t = src.pixel(std::clamp(x + dx, 0, w - 1), std::clamp(y + dy, 0, h - 1))[c];
              if (!std::isfinite(t)) {
                ma = INFINITY;  // NaN/Inf in the footprint (tolerance.cpp, window_stats)
                continue;
              }
              mn = std::min(mn, t);
              mx = std::max(mx, t);
              ma = std::max(ma, std::fabs(t));
            }
          out.range.pixel(x, y)[c] = mx >= mn ? mx - mn : 0.0f;
          out.magnitude.pixel(x, y)[c] = ma;
        }
  });
  return out;
}

// The base texel of a lookup for target texel x of a tw-wide target on a sw-wide source at
// offset o: floor of its exact texel-space position, clamped.
int base_texel(int x, int tw, int sw, double o) {
  const double u = (x + 0.5) * sw / tw - 0.5 + o;
  return std::clamp(static_cast<int>(std::floor(u)), 0, sw - 1);
}

// One lookup of a stage whose taps are not seed 003's: offset in source texels, weight.
struct Tap {
  double ox, oy, weight;
};

// The bound of a sum of GL_LINEAR lookups of `src` (taps) into a tw x th target, per value:
// each tap's weight times (the coordinates' error x its window's range + the input error in
// it), and the lerps' and the sum's rounding on its window's magnitude (`ops` roundings per
// tap). The coordinate error `delta` is in texels (both axes together).
Values taps_terms(const Window2D& win, const Window2D* ewin, const std::vector<Tap>& taps,
                  int x, int y, int tw, int th, int sw, int sh, int c, double delta, double U,
                  int ops, double read8) {
  double coord = 0, arith = 0, input = 0;
  for (const Tap& t : taps) {
    const int bx = base_texel(x, tw, sw, t.ox), by = base_texel(y, th, sh, t.oy);
    const double w = std::fabs(t.weight);
    coord += w * (delta * win.range.pixel(bx, by)[c] + read8);
    arith += w * ops * U * win.magnitude.pixel(bx, by)[c];
    if (ewin) input += w * ewin->magnitude.pixel(bx, by)[c];
  }
  return Values{coord, arith, input, 0.0, 0.0};
}

}  // namespace

std::unique_ptr<StageBounds> gaussian_down_bounds(ConstImageView src, ConstImageView oracle,
                                                  const Image* error,
                                                  const DownsampleOptions& opt, BoundContext ctx);

std::unique_ptr<StageBounds> down_bounds(ConstImageView src, ConstImageView oracle,
                                         const Image* error, const DownsampleOptions& opt,
                                         BoundContext ctx) {
  if (!opt.first && (opt.filter == DownsampleFilter::gaussian ||
                     opt.filter == DownsampleFilter::separable))
    return gaussian_down_bounds(src, oracle, error, opt, ctx);
  const bool first = opt.first && opt.threshold_taps;  // the taps are thresholded
  const float threshold = opt.threshold;
  const LumaWeights<float> lw = luma_weights<float>(opt.luma.weights);
  const bool encoded = opt.luma.space != LumaSpace::linear;
  const bool karis = opt.first && opt.karis;
  const bool group_linear = karis && opt.karis_form == KarisForm::group_linear;
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  auto win = std::make_shared<Window2D>(window4x4(src, ctx.threads));
  auto ewin = error ? std::make_shared<Window2D>(window4x4(error->cview(), ctx.threads)) : nullptr;
  const double delta = coordinate_error(src.width, *ctx.profile) +
                       coordinate_error(src.height, *ctx.profile);
  const int tw = oracle.width, th = oracle.height;
  const bool use_karis = karis;
  const double read8 = ctx.unorm8_reads ? unorm8_read_term : 0.0;
  // The value before the soft threshold (Prefilter::soft_knee): the stage without it.
  std::shared_ptr<Image> before;
  const bool scaled = opt.soft_knee || opt.smoothstep;  // the first level times a factor
  if (scaled) {
    DownsampleOptions o = opt;
    o.soft_knee = false;
    o.smoothstep = false;
    before = std::make_shared<Image>(tw, th);
    downsample(src, before->view(), o, ctx.threads);
  }
  // One bilinear lookup (FirstDownsample::bilinear) or seed 003's 13 taps.
  static const std::vector<MipTap> kCentre = {{0, 0, 1.0f}};
  const bool single = opt.first && opt.first_filter == FirstDownsample::bilinear;
  const bool box = opt.first ? opt.first_filter == FirstDownsample::box4
                             : opt.filter == DownsampleFilter::box4;
  // Every term but storage, of one channel, before any soft threshold (a clamp, min(C, r), moves
  // no value further than r moves).
  auto pre = [=](int x, int y, int c) {
        const auto& taps = single ? kCentre : box ? box4_taps() : downsample_taps();
        double coord = 0, arith = 0, thresh = 0;
        double dq[13], lum_err[13], qmax[13], lum[13], qs[13][3];
        for (std::size_t i = 0; i < taps.size(); ++i) {
          const int bx = base_texel(x, tw, src.width, taps[i].ox);
          const int by = base_texel(y, th, src.height, taps[i].oy);
          const double r = win->range.pixel(bx, by)[c], m = win->magnitude.pixel(bx, by)[c];
          const double e = ewin ? ewin->magnitude.pixel(bx, by)[c] : 0.0;
          coord += taps[i].weight * (delta * r + e + read8);
          arith += taps[i].weight * (3 + 2 * 13 + (use_karis ? 10 : 0)) * U * m;
          // This tap's value and its error on every channel (for luminance and Karis).
          float q[3];
          mip_lookup(src, x, y, tw, th, taps[i].ox, taps[i].oy, ctx.profile->subtexel_bits, q);
          double dmax = 0;
          qmax[i] = 0;
          for (int k = 0; k < 3; ++k) {
            const double rk = win->range.pixel(bx, by)[k];
            const double ek = ewin ? ewin->magnitude.pixel(bx, by)[k] : 0.0;
            dmax = std::max(dmax, delta * rk + ek + read8 + 3 * U * win->magnitude.pixel(bx, by)[k]);
            qmax[i] = std::max(qmax[i], std::fabs(double(q[k])));
            qs[i][k] = q[k];
          }
          dq[i] = dmax;
          lum[i] = luminance(q[0], q[1], q[2], lw);
          lum_err[i] = dmax + 4 * U * std::fabs(lum[i]);  // the weights sum to 1
          // The threshold's luminance: this one, or under an encoded --luma-space that of the
          // encoded tap, its band carried through the encode.
          double tl = lum[i], tl_err = lum_err[i];
          if (first && encoded) {
            const double v[3] = {q[0], q[1], q[2]}, d[3] = {dmax, dmax, dmax};
            tl = threshold_luminance(q[0], q[1], q[2], opt.luma);
            tl_err = encoded_threshold_band(v, d, opt.luma, *ctx.profile);
          }
          if (first && std::fabs(tl - threshold) <= tl_err)
            thresh += taps[i].weight * qmax[i];
        }
        double kterm = 0;
        if (group_linear) {
          // Bevy's form: G = s_g (sum of the group's taps), times w = 1 / (1 + L(G) / 4). G moves
          // by dG <= s_g (sum of its taps' errors), L(G) by dL <= dG plus its rounding; w by at
          // most (dL / 4) w_max^2 (the slope's largest, at the low end of L), and G w by
          // dG w_max + (|G| + dG) dw. No bound where 1 + L / 4 may reach 0 (negative input).
          const auto& groups = karis_groups();
          const auto& gw = karis_group_weights();
          for (std::size_t g = 0; g < groups.size(); ++g) {
            const double scale = gw[g] / 4.0;
            double dG = 0, G[3] = {0, 0, 0};
            for (int i : groups[g]) {
              dG += scale * dq[i];
              for (int k = 0; k < 3; ++k) G[k] += scale * qs[i][k];
            }
            const double L = 0.2126 * G[0] + 0.7152 * G[1] + 0.0722 * G[2];
            const double dL = dG + 4 * U * (std::fabs(G[0]) + std::fabs(G[1]) + std::fabs(G[2]));
            const double low = 1 + (L - dL) / 4;
            if (!(low > 0)) {
              kterm = INFINITY;
              break;
            }
            const double w_max = 1 / low;
            kterm += dG * w_max + (std::fabs(G[c]) + dG) * (dL / 4) * w_max * w_max * (1 + 4 * U);
          }
          coord = 0;  // the Karis term carries the taps' own errors (dG)
        } else if (use_karis) {
          const auto& groups = karis_groups();
          const auto& gw = karis_group_weights();
          for (std::size_t g = 0; g < groups.size(); ++g) {
            double lo = INFINITY, hi = -INFINITY, rel = 0, dmax = 0;
            for (int i : groups[g]) {
              const double denom = 1 + std::max(lum[i] - lum_err[i], 0.0);  // w uses max(L, 0)
              rel = std::max(rel, denom > 0 ? lum_err[i] / denom + 6 * U : INFINITY);
              lo = std::min(lo, -qmax[i]);
              hi = std::max(hi, qmax[i]);
              dmax = std::max(dmax, dq[i]);
            }
            // Normalised weights move by at most 2 rel in total; the taps by dmax.
            kterm += gw[g] * (dmax + 2 * rel * (hi - lo));
          }
          coord = 0;  // the Karis term carries the taps' own errors (dmax)
        }
        return Values{coord, arith, thresh, kterm, 0.0};
  };
  auto storage = [=](int x, int y, int c) {
    return storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile, c) +
           denormal_floor(*ctx.profile);
  };
  if (!scaled)
    return make_bounds(
        {"coordinate rounding (x local range)", "filter and sum rounding",
         "threshold within the tap's error (kept or dropped)",
         "Karis weights (dL / (1 + L) x group range)", "storage and denormals"},
        [=](int x, int y, int c) {
          Values v = pre(x, y, c);
          v[4] = storage(x, y, c);
          return v;
        },
        tw, ctx.threads);
  // out_c = r_c h(b), b the largest channel, h = g(b) / max(b, 1e-5) in [0, 1] with g
  // 1-Lipschitz and g <= b: |dh| <= min(1, 2 Eb / max(b - Eb, 1e-5)), Eb the largest channel's
  // error. So out_c moves by at most E_c (its own error, times h <= 1) + |r_c| |dh|, plus the
  // product's and the factor's rounding. The three channels' terms at once: each needs Eb.
  // Prefilter::smoothstep: h = smoothstep(e0, e1, L) is monotone in L, so a luminance off by at
  // most dL (its weights times the channels' errors, on linear colour) moves it by at most
  // h(L + dL) - h(L - dL): nothing where the whole interval lies above the ramp (most of a
  // bright scene), up to 1 across it. An encoded luminance: any h.
  const LumaWeights<double> lwd = luma_weights<double>(opt.luma.weights);
  const double width = double(opt.threshold + opt.smooth_width) - double(opt.threshold);
  return make_bounds(
      {"coordinate rounding (x local range)", "filter and sum rounding",
       opt.smoothstep ? "smoothstep: the luminance's error through its slope"
                      : "soft threshold: the brightness's error through its slope",
       "Karis weights (dL / (1 + L) x group range)", "storage and denormals"},
      [=](int x, int y) {
        std::array<Values, 3> v;
        double eb = 0;
        for (int k = 0; k < 3; ++k) {
          v[std::size_t(k)] = pre(x, y, k);
          const Values& t = v[std::size_t(k)];
          const double e = t[0] + t[1] + t[2] + t[3];
          eb = std::isnan(e) ? INFINITY : std::max(eb, e);  // NaN: no bound on the slope's move
        }
        const float* r = before->pixel(x, y);
        const double b = std::max({double(r[0]), double(r[1]), double(r[2])});
        double dh = std::isfinite(eb) ? std::min(1.0, 2 * eb / std::max(b - eb, 1e-5)) : 1.0;
        if (opt.smoothstep) {
          double dl = 0, mag = 0;
          const double lw[3] = {lwd.r, lwd.g, lwd.b};
          for (int k = 0; k < 3; ++k) {
            const Values& t = v[std::size_t(k)];
            dl += lw[k] * (t[0] + t[1] + t[2] + t[3]);
            mag += lw[k] * std::fabs(double(r[k]));
          }
          dl += 4 * U * mag;  // the dot product's own rounding
          const bool linear = opt.luma.space == LumaSpace::linear;
          const double l = lwd.r * r[0] + lwd.g * r[1] + lwd.b * r[2];
          if (linear && std::isfinite(dl) && std::isfinite(l) && width > 0) {
            auto h = [&](double x) { return smoothstep_factor(x, opt.threshold, opt.smooth_width); };
            // The shader's own arithmetic of h: a few roundings of its products, where it is not
            // exactly 0 or 1.
            const double hl = h(l - dl), hh = h(l + dl);
            dh = std::min(1.0, hh - hl + ((hl > 0 && hl < 1) || (hh > 0 && hh < 1) ? 16 * U : 0.0));
          } else {
            dh = 1.0;
          }
        }
        for (int k = 0; k < 3; ++k) {
          Values& t = v[std::size_t(k)];
          const double rk = std::fabs(double(r[k]));
          t[1] += 12 * U * rk;
          t[2] += rk * dh;
          t[4] = storage(x, y, k);
        }
        return v;
      },
      tw, ctx.threads);
}

// Unity's Gaussian pyramid level (DownsampleFilter::gaussian): the horizontal pass's bound per
// texel (its taps two source texels apart, plus its storage), then the vertical pass's taps on
// the stored horizontal pass, each carrying the largest horizontal error in its window.
std::unique_ptr<StageBounds> gaussian_down_bounds(ConstImageView src, ConstImageView oracle,
                                                  const Image* error,
                                                  const DownsampleOptions& opt, BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;
  const int tw = oracle.width, th = oracle.height, sw = src.width, sh = src.height;
  std::vector<Tap> htaps, vtaps;
  if (opt.filter == DownsampleFilter::separable) {
    // three.js's: taps one texel of the level apart along x (sw / tw source texels), then along
    // y on the stored horizontal pass; each pair's sum rounded before its product.
    const std::vector<float> c = separable_coefficients(opt.kernel_radius, opt.kernel_sigma, opt.kernel_normalise);
    const double sx = double(sw) / tw;
    for (int i = 1 - opt.kernel_radius; i < opt.kernel_radius; ++i) {
      const double w = c[std::size_t(std::abs(i))];
      htaps.push_back({i * sx, 0.0, w});
      vtaps.push_back({0.0, double(i), w});
    }
  } else {
    for (const GaussianTap& t : gaussian_down_h_taps()) htaps.push_back({2.0 * t.offset, 0.0, t.weight});
    for (const GaussianTap& t : gaussian_down_v_taps()) vtaps.push_back({0.0, t.offset, t.weight});
  }
  const int hops = 3 + 2 * int(htaps.size()), vops = 3 + 2 * int(vtaps.size());
  // The step's product with the offset and the lookup's two more roundings: 2 more per axis.
  const double dh = coordinate_error(sw, *ctx.profile) + coordinate_error(sh, *ctx.profile) +
                    2 * (sw + sh) * U;
  const double dv = coordinate_error(tw, *ctx.profile) + coordinate_error(th, *ctx.profile) +
                    2 * (tw + th) * U;
  const Window2D win = window4x4(src, ctx.threads);
  // The horizontal pass reads the level above; the vertical one the horizontal pass, stored as
  // the levels are.
  const double read8 = ctx.unorm8_reads ? unorm8_read_term : 0.0;
  const double read8h = opt.intermediate == Storage::rgba8 ? unorm8_read_term : 0.0;
  std::unique_ptr<Window2D> ewin;
  if (error) ewin = std::make_unique<Window2D>(window4x4(error->cview(), ctx.threads));
  Image h(tw, th);
  downsample_gaussian_h(src, h.view(), opt, ctx.threads);
  // The horizontal pass's whole bound, stored: E_h.
  Image eh(tw, th, 0.0f);
  parallel_rows(th, ctx.threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < tw; ++x)
        for (int c = 0; c < 3; ++c) {
          const Values v = taps_terms(win, ewin.get(), htaps, x, y, tw, th, sw, sh, c, dh, U,
                                      hops, read8);
          eh.pixel(x, y)[c] = static_cast<float>(
              (v[0] + v[1] + v[2]) * (1 + 4 * U) +
              storage_term(h.pixel(x, y)[c], opt.intermediate, *ctx.profile, c) +
              denormal_floor(*ctx.profile));
        }
  });
  auto hwin = std::make_shared<Window2D>(window4x4(h.cview(), ctx.threads));
  auto ehwin = std::make_shared<Window2D>(window4x4(eh.cview(), ctx.threads));
  return make_bounds(
      {"coordinate rounding (x local range)", "filter and sum rounding",
       "the horizontal pass's error, stored (through the vertical taps)", "storage and denormals"},
      [=](int x, int y, int c) {
        const Values v = taps_terms(*hwin, ehwin.get(), vtaps, x, y, tw, th, tw, th, c, dv, U,
                                    vops, read8h);
        return Values{v[0], v[1], v[2],
                      storage_term(oracle.pixel(x, y)[c], ctx.storage, *ctx.profile, c) +
                          denormal_floor(*ctx.profile),
                      0.0};
      },
      tw, ctx.threads);
}

std::unique_ptr<StageBounds> up_bounds(ConstImageView small, ConstImageView current,
                                       ConstImageView oracle, const Image* small_error,
                                       const Image* current_error, LevelBlend blend,
                                       BoundContext ctx, UpsampleFilter filter) {
  // A blended level (level_blend): the tent's terms scaled by C, the current level's by what
  // the blend keeps of it, and the blend's two products and sum rounded.
  const bool plain = current.empty() || blend.plain();
  const bool lerp = !plain && blend.combine == LevelCombine::lerp;
  const double tent_w = plain ? 1.0 : std::fabs(double(blend.weight));
  const double keep = plain ? 1.0 : std::fabs(double(blend.kept()));
  const double U = ctx.profile->unit_roundoff;  // one operation's rounding
  auto win = std::make_shared<Window2D>(window4x4(small, ctx.threads));
  auto ewin = small_error ? std::make_shared<Window2D>(window4x4(small_error->cview(), ctx.threads))
                          : nullptr;
  const double delta = coordinate_error(small.width, *ctx.profile) +
                       coordinate_error(small.height, *ctx.profile);
  const int tw = oracle.width, th = oracle.height;
  const double read8 = ctx.unorm8_reads ? unorm8_read_term : 0.0;
  // Unity's upsample reads the current level with a lookup at its own texel centres (not through
  // the blend unit): a coordinate off by its error mixes in a fraction of the neighbours.
  std::shared_ptr<Window2D> cwin;
  double cdelta = 0;
  if (lerp) {
    cwin = std::make_shared<Window2D>(window4x4(current, ctx.threads));
    cdelta = coordinate_error(tw, *ctx.profile) + coordinate_error(th, *ctx.profile);
  }
  return make_bounds(
      {"coordinate rounding (x local range)", "filter and sum rounding",
       "current level's own error", "storage and denormals"},
      [=](int x, int y, int c) {
        static const std::vector<MipTap> kCentre = {{0, 0, 1.0f}};
        double coord = 0, arith = 0, tent_mag = 0;
        for (const MipTap& t : filter == UpsampleFilter::bilinear ? kCentre : tent_taps()) {
          const int bx = base_texel(x, tw, small.width, t.ox);
          const int by = base_texel(y, th, small.height, t.oy);
          coord += t.weight * (delta * win->range.pixel(bx, by)[c] + read8 +
                               (ewin ? ewin->magnitude.pixel(bx, by)[c] : 0.0));
          arith += t.weight * (3 + 2 * 9) * U * win->magnitude.pixel(bx, by)[c];
          tent_mag += t.weight * win->magnitude.pixel(bx, by)[c];
        }
        const double cur = current.empty() ? 0.0 : std::fabs(current.pixel(x, y)[c]);
        coord *= tent_w;
        if (cwin) coord += keep * (cdelta * cwin->range.pixel(x, y)[c] + read8);
        // Blended into an 8-bit level (not Unity's lerp, which is a lookup).
        if (ctx.unorm8_reads && !current.empty() && !lerp) coord += unorm8_blend_term;
        arith = arith * tent_w + 9 * U * cur;
        if (!plain) arith += 4 * U * (std::fabs(oracle.pixel(x, y)[c]) + keep * cur);
        // lerp: t - d, times C, plus d; or a GPU's other forms of it (d (1 - C) + t C, a fused
        // multiply-add): a few roundings of |t| and |d| each.
        if (lerp) arith += 4 * U * (tent_mag + cur);
        const double ecur = keep * (current_error ? current_error->pixel(x, y)[c] : 0.0);
        const double v = oracle.pixel(x, y)[c];
        return Values{coord, arith, ecur,
                      storage_term(v, ctx.storage, *ctx.profile, c) + denormal_floor(*ctx.profile), 0};
      },
      tw, ctx.threads);
}

std::unique_ptr<StageBounds> sum_bounds(const std::vector<ConstImageView>& levels,
                                        ConstImageView oracle,
                                        const std::vector<const Image*>& errors,
                                        const BloomParams& p, BoundContext ctx) {
  const double U = ctx.profile->unit_roundoff;
  const int tw = oracle.width, th = oracle.height;
  const double read8 = ctx.unorm8_reads ? unorm8_read_term : 0.0;
  struct Level {
    std::shared_ptr<Window2D> win, ewin;
    double delta, factor, factor_err;
    int w, h;
  };
  std::vector<Level> ls;
  for (std::size_t i = 0; i < levels.size(); ++i) {
    Level l;
    l.win = std::make_shared<Window2D>(window4x4(levels[i], ctx.threads));
    if (i < errors.size() && errors[i])
      l.ewin = std::make_shared<Window2D>(window4x4(errors[i]->cview(), ctx.threads));
    l.delta = coordinate_error(levels[i].width, *ctx.profile) +
              coordinate_error(levels[i].height, *ctx.profile);
    const float f = p.level_factors[i];
    l.factor = std::fabs(double(sum_factor(f, p.level_radius)));
    // mix(f, 1.2 - f, r) in another of its forms (f + (m - f) r, a fused multiply-add): a few
    // roundings of f and 1.2 - f.
    l.factor_err = 6 * U * (std::fabs(double(f)) + std::fabs(1.2 - double(f)));
    l.w = levels[i].width;
    l.h = levels[i].height;
    ls.push_back(l);
  }
  const double s = std::fabs(double(p.level_strength));
  const int n = static_cast<int>(levels.size());
  return make_bounds(
      {"coordinate rounding (x local range)", "product and sum rounding", "the levels' own error",
       "storage and denormals"},
      [=](int x, int y, int c) {
        double coord = 0, arith = 0, input = 0;
        for (const Level& l : ls) {
          const int bx = base_texel(x, tw, l.w, 0), by = base_texel(y, th, l.h, 0);
          const double m = l.win->magnitude.pixel(bx, by)[c];
          coord += l.factor * (l.delta * l.win->range.pixel(bx, by)[c] + read8);
          // the lerps (3), the product, the sum (n terms) and the factor's own error
          arith += (l.factor * (4 + n) * U + l.factor_err) * m;
          if (l.ewin) input += l.factor * l.ewin->magnitude.pixel(bx, by)[c];
        }
        const double v = oracle.pixel(x, y)[c];
        return Values{s * coord, s * arith + 2 * U * std::fabs(v), s * input,
                      storage_term(v, ctx.storage, *ctx.profile, c) + denormal_floor(*ctx.profile),
                      0};
      },
      tw, ctx.threads);
}

}  // namespace bloomref::parity::detail
