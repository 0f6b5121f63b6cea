// The gain gates' budgets (energy.h).
#include "energy.h"

#include "bloomref/engine/fast_stages.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace bloomref::parity::detail {

AxisShift lookup_shift(int n, const DeviceProfile& p, double fraction) {
  // The coordinates' float error, as coordinate_error (tolerance.h) counts it.
  const double coords = n * p.unit_roundoff * (2 * p.division_ulps + 4);
  const int device_bits = p.subtexel_bits_min > 0 ? p.subtexel_bits_min : p.subtexel_bits;
  const double qd = device_bits > 0 ? std::ldexp(1.0, -device_bits) : 0.0;
  const double qo = p.subtexel_bits > 0 ? std::ldexp(1.0, -p.subtexel_bits) : 0.0;
  // A fraction on both grids (a texel centre, 1/2, 1/4 ...): the oracle's rounding gives it
  // exactly (with float weights, up to its own coordinates' error); the device's truncation may
  // give one quantum below it once its coordinate errs low, its rounding the fraction itself.
  auto on = [fraction](double q) { return q == 0 || std::floor(fraction / q) * q == fraction; };
  if (fraction >= 0 && on(qd) && on(qo)) {
    const double noise = qo == 0 ? 2 * coords : coords;
    return {qd + noise, noise, qo > 0};
  }
  // Elsewhere the oracle rounds its fraction to the nearest quantum (within qo / 2 either way)
  // and the device truncates (up to qd below) or rounds (qd / 2 either way).
  return {qd + qo / 2 + 2 * coords, qd / 2 + qo / 2 + 2 * coords};
}

void SignedBudget::add(const SignedBudget& b, double scale) {
  for (int c = 0; c < 3; ++c) {
    up[c] += scale * b.up[c];
    down[c] += scale * b.down[c];
  }
}

void SignedBudget::add_both(const std::array<double, 3>& v, double scale) {
  for (int c = 0; c < 3; ++c) {
    up[c] += scale * v[c];
    down[c] += scale * v[c];
  }
}

SignedBudget SignedBudget::infinite() {
  SignedBudget b;
  b.up.fill(INFINITY);
  b.down.fill(INFINITY);
  return b;
}

namespace {

// Every tap of a kernel: the centre, then +o and -o for each further offset, exact.
void kernel_taps(const Kernel& k, std::vector<double>& offsets, std::vector<double>& weights) {
  for (std::size_t i = 0; i < k.weights_f64.size(); ++i) {
    const double o = k.offsets_f64[i], w = k.weights_f64[i];
    offsets.push_back(o);
    weights.push_back(w);
    if (i > 0) {
      offsets.push_back(-o);
      weights.push_back(w);
    }
  }
}

inline int clampi(int v, int n) { return v < 0 ? 0 : v >= n ? n - 1 : v; }

// The shifts to try on an axis for a lookup whose fraction is f (0: on a texel centre): the
// ends of the range and the texel line inside it, where the interpolant bends.
int shift_candidates(double f, const AxisShift& s, double out[4]) {
  int n = 0;
  out[n++] = -s.minus;
  out[n++] = 0.0;
  out[n++] = s.plus;
  if (f > 0 && -f > -s.minus) out[n++] = -f;
  if (f > 0 && 1 - f < s.plus) out[n++] = 1 - f;
  return n;
}

// Bilinear lookup (clamp-to-edge) of channel values at texel-centre coordinates (x, y).
inline void lookup(ConstImageView img, double x, double y, double out[3]) {
  const double fx = std::floor(x), fy = std::floor(y);
  const double a = x - fx, b = y - fy;
  const int x0 = clampi(static_cast<int>(fx), img.width), x1 = clampi(static_cast<int>(fx) + 1, img.width);
  const int y0 = clampi(static_cast<int>(fy), img.height), y1 = clampi(static_cast<int>(fy) + 1, img.height);
  const float *p00 = img.pixel(x0, y0), *p10 = img.pixel(x1, y0), *p01 = img.pixel(x0, y1),
              *p11 = img.pixel(x1, y1);
  for (int c = 0; c < 3; ++c)
    out[c] = (1 - b) * ((1 - a) * p00[c] + a * p10[c]) + b * ((1 - a) * p01[c] + a * p11[c]);
}

}  // namespace

BlurDeviation::BlurDeviation(ConstImageView src, Axis axis, const Kernel& k,
                             const DeviceProfile& p)
    : src_(src), axis_(axis), kernel_(&k) {
  kernel_taps(k, offsets_, weights_);
  const bool hz = axis == Axis::horizontal;
  const int n_along = hz ? src.width : src.height;
  along_ = lookup_shift(n_along, p, 0.0);
  across_ = lookup_shift(hz ? src.height : src.width, p, 0.0);
  for (double o : offsets_) tap_shift_.push_back(lookup_shift(n_along, p, o - std::floor(o)));
  // Beyond a texel, the candidates would have to include more texel lines: not derived here.
  usable_ = across_.most() < 1.0;
  for (const AxisShift& a : tap_shift_) usable_ = usable_ && a.most() < 1.0;
}

double BlurDeviation::shift_sum() const {
  double most = across_.minus + across_.plus;
  for (const AxisShift& a : tap_shift_) most = std::max(most, a.minus + a.plus);
  return most;
}

// The deviation of one tap's lookup at along-axis coordinate u (texel centres at integers) on
// the output's row or column: max and min over the shift rectangle of lookup - lookup at u.
void BlurDeviation::deviation(int x, int y, double u, const AxisShift& along, float* up,
                              float* down) const {
  const bool hz = axis_ == Axis::horizontal;
  const double f = u - std::floor(u);
  double da[5], db[5];
  const int na = shift_candidates(f, along, da), nb = shift_candidates(0.0, across_, db);
  const double bx = hz ? u : x, by = hz ? y : u;
  double base[3];
  lookup(src_, bx, by, base);
  double hi[3] = {0, 0, 0}, lo[3] = {0, 0, 0};
  for (int i = 0; i < na; ++i)
    for (int j = 0; j < nb; ++j) {
      if (da[i] == 0 && db[j] == 0) continue;
      double v[3];
      lookup(src_, bx + (hz ? da[i] : db[j]), by + (hz ? db[j] : da[i]), v);
      for (int c = 0; c < 3; ++c) {
        const double d = v[c] - base[c];
        hi[c] = std::max(hi[c], d);
        lo[c] = std::min(lo[c], d);
        if (std::isnan(d)) hi[c] = lo[c] = NAN;
      }
    }
  for (int c = 0; c < 3; ++c) {
    up[c] = static_cast<float>(hi[c]);
    down[c] = static_cast<float>(-lo[c]);
  }
}

// deviation() for every texel centre of row y at once: the lookup's change when it moves by
// (dx, dy) within the shifts (at most one texel: one neighbour per axis, on the side of the
// move) is dx (Tx - T) + dy (Ty - T) + dx dy (Txy - Tx - Ty + T), written out for the eight
// corners and edge midpoints of the rectangle.
std::pair<int, int> BlurDeviation::centred_row(int y, float* up, float* down) const {
  const bool hz = axis_ == Axis::horizontal;
  const AxisShift& sx = hz ? along_ : across_;
  const AxisShift& sy = hz ? across_ : along_;
  const int w = src_.width, h = src_.height;
  const double dxs[3] = {-sx.minus, 0.0, sx.plus}, dys[3] = {-sy.minus, 0.0, sy.plus};
  const float* rows[3] = {src_.row(std::max(y - 1, 0)), src_.row(y), src_.row(std::min(y + 1, h - 1))};
  // A texel whose 3x3 neighbourhood holds its own value throughout has no deviation: runs of
  // them (the dark ground of a bloom) are filled with 0 without the corners' arithmetic.
  auto same3 = [&rows](int x) {
    const float* c = rows[1] + std::size_t(x) * kChannels;
    for (int r = 0; r < 3; ++r)
      if (std::memcmp(rows[r] + std::size_t(x) * kChannels, c, 3 * sizeof(float)) != 0) return false;
    return true;
  };
  int lo = w, hi = 0;
  for (int x = 0; x < w; ++x) {
    const std::size_t base = std::size_t(x) * kChannels;
    if (x > 0 && x + 1 < w && same3(x - 1) && same3(x) && same3(x + 1) &&
        std::memcmp(rows[1] + base - kChannels, rows[1] + base, 3 * sizeof(float)) == 0 &&
        std::memcmp(rows[1] + base + kChannels, rows[1] + base, 3 * sizeof(float)) == 0 &&
        std::isfinite(rows[1][base]) && std::isfinite(rows[1][base + 1]) &&
        std::isfinite(rows[1][base + 2])) {
      for (int c = 0; c < 3; ++c) up[base + c] = down[base + c] = 0.0f;
      continue;
    }
    lo = std::min(lo, x);
    hi = x + 1;
    const int xs[3] = {std::max(x - 1, 0), x, std::min(x + 1, w - 1)};
    for (int c = 0; c < 3; ++c) {
      const double t = rows[1][std::size_t(x) * kChannels + c];
      double rise = 0, fall = 0;
      bool nan = std::isnan(t);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          if (i == 1 && j == 1) continue;
          const double a = std::fabs(dxs[i]), b = std::fabs(dys[j]);
          const int nx = xs[i == 1 ? 1 : i], ny = j == 1 ? 1 : j;
          const double tx = rows[1][std::size_t(nx) * kChannels + c];
          const double ty = rows[ny][std::size_t(x) * kChannels + c];
          const double txy = rows[ny][std::size_t(nx) * kChannels + c];
          const double d = a * (tx - t) + b * (ty - t) + a * b * (txy - tx - ty + t);
          nan = nan || std::isnan(d);
          rise = std::max(rise, d);
          fall = std::min(fall, d);
        }
      const std::size_t at = std::size_t(x) * kChannels + c;
      up[at] = nan ? NAN : static_cast<float>(rise);
      down[at] = nan ? NAN : static_cast<float>(-fall);
    }
  }
  return {lo, hi};
}

void BlurDeviation::rows(int y0, int y1, float* up, float* down) const {
  const bool hz = axis_ == Axis::horizontal;
  const int w = src_.width, h = src_.height;
  // Taps on texel centres (every tap of discrete9) share one deviation per texel: made once
  // for the texels the band's taps reach, then summed with the taps' weights.
  int reach = 0;
  bool centred = true;
  for (double o : offsets_) {
    centred = centred && o == std::floor(o);
    reach = std::max(reach, static_cast<int>(std::ceil(std::fabs(o))));
  }
  const std::size_t row = std::size_t(w) * kChannels;
  if (centred) {
    const int r0 = hz ? y0 : std::max(0, y0 - reach), r1 = hz ? y1 : std::min(h, y1 + reach);
    // Scratch reused band after band on each thread (a band's rows are a few MB: fresh
    // allocations would be fresh pages every time).
    thread_local std::vector<float> gu, gd, bu, bd;
    const std::size_t band = std::size_t(r1 - r0) * row;
    for (std::vector<float>* v : {&gu, &gd, &bu, &bd})
      if (v->size() < band) v->resize(band);
    // Per row of deviations, the columns [lo, hi) outside which it is 0 (lo == hi: all 0).
    std::vector<std::pair<int, int>> span(std::size_t(r1 - r0));
    for (int y = r0; y < r1; ++y)
      span[std::size_t(y - r0)] =
          centred_row(y, &gu[std::size_t(y - r0) * row], &gd[std::size_t(y - r0) * row]);
    // The taps' weighted sums are the pass's own blur of the deviations (taps on texel
    // centres, clamp-to-edge: the fast engine's, with fractions rounded to 8 bits, so exactly
    // on the centres). Its float sums of non-negative terms are within 2^-18 of the exact
    // ones: rounded up by that below. NaN and Inf pass through.
    if (std::all_of(span.begin(), span.end(), [](const std::pair<int, int>& p) { return p.first >= p.second; })) {
      std::fill(up, up + std::size_t(y1 - y0) * row, 0.0f);
      std::fill(down, down + std::size_t(y1 - y0) * row, 0.0f);
      return;
    }
    const int n = r1 - r0;
    const ConstImageView su{w, n, w, gu.data()}, sd{w, n, w, gd.data()};
    const Kernel* k = kernel_;
    blur_pass_fast(su, ImageView{w, n, w, bu.data()}, {axis_, k, 8}, 1);
    blur_pass_fast(sd, ImageView{w, n, w, bd.data()}, {axis_, k, 8}, 1);
    const std::size_t from = std::size_t(y0 - r0) * row, count = std::size_t(y1 - y0) * row;
    const bool exact = along_.exact_reference && across_.exact_reference;
    for (std::size_t i = 0; i < count; ++i) {
      const double u = bu[from + i] * (1 + 0x1p-18), d = bd[from + i] * (1 + 0x1p-18);
      up[i] = static_cast<float>(exact ? u : (u + d) * (1 + 0x1p-23));
      down[i] = static_cast<float>(exact ? d : (u + d) * (1 + 0x1p-23));
    }
    return;
  }
  // Elsewhere each tap's deviation is its own, accumulated in double (sums of non-negative
  // terms), rounded up at the end.
  std::vector<double> acc_up(std::size_t(y1 - y0) * row, 0.0), acc_dn(acc_up.size(), 0.0);
  {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t out = std::size_t(y - y0) * row + std::size_t(x) * kChannels;
        for (std::size_t k = 0; k < offsets_.size(); ++k) {
          float u[3], d[3];
          deviation(x, y, (hz ? x : y) + offsets_[k], tap_shift_[k], u, d);
          const bool exact = tap_shift_[k].exact_reference && across_.exact_reference;
          for (int c = 0; c < 3; ++c) {
            acc_up[out + c] += weights_[k] * (exact ? u[c] : double(u[c]) + d[c]);
            acc_dn[out + c] += weights_[k] * (exact ? d[c] : double(u[c]) + d[c]);
          }
        }
      }
  }
  // Rounded up to float: each value a little above its double (one float ULP and more).
  for (std::size_t i = 0; i < acc_up.size(); ++i) {
    up[i] = static_cast<float>(acc_up[i] * (1 + 0x1p-20));
    down[i] = static_cast<float>(acc_dn[i] * (1 + 0x1p-20));
  }
}

std::vector<double> edge_weight_excess(int n, const Kernel& k) {
  std::vector<double> offsets, weights;
  kernel_taps(k, offsets, weights);
  std::vector<double> W(std::size_t(n), 0.0);
  for (int a = 0; a < n; ++a)
    for (std::size_t i = 0; i < offsets.size(); ++i) {
      const double u = a + offsets[i], fu = std::floor(u), f = u - fu;
      W[std::size_t(clampi(static_cast<int>(fu), n))] += weights[i] * (1 - f);
      W[std::size_t(clampi(static_cast<int>(fu) + 1, n))] += weights[i] * f;
    }
  // The kernel's weights are rationals rounded to double: within 1e-12 of 1 is 1.
  for (double& v : W) v = std::fabs(v - 1) > 1e-12 ? std::fabs(v - 1) : 0.0;
  return W;
}

std::array<double, 3> edge_leak(ConstImageView e, Axis axis, const std::vector<double>& excess) {
  std::array<double, 3> out{};
  std::vector<int> at;
  for (std::size_t i = 0; i < excess.size(); ++i)
    if (excess[i] > 0) at.push_back(static_cast<int>(i));
  const bool hz = axis == Axis::horizontal;
  for (int y = 0; y < e.height; ++y) {
    if (hz) {
      for (int x : at)
        for (int c = 0; c < 3; ++c) out[std::size_t(c)] += excess[std::size_t(x)] * e.pixel(x, y)[c];
    } else if (excess[std::size_t(y)] > 0) {
      for (int x = 0; x < e.width; ++x)
        for (int c = 0; c < 3; ++c) out[std::size_t(c)] += excess[std::size_t(y)] * e.pixel(x, y)[c];
    }
  }
  return out;
}

}  // namespace bloomref::parity::detail
