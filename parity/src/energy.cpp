// The gain gates' budgets (energy.h).
#include "energy.h"

#include <algorithm>
#include <cmath>

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
    return {qd + noise, noise};
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
    : src_(src), axis_(axis) {
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

void BlurDeviation::rows(int y0, int y1, float* up, float* down) const {
  const bool hz = axis_ == Axis::horizontal;
  const int w = src_.width, h = src_.height;
  const int n_along = hz ? w : h;
  // Taps on texel centres (every tap of discrete9) share one deviation per texel: made once
  // for the texels the band's taps reach, then summed with the taps' weights.
  int reach = 0;
  bool centred = true;
  for (double o : offsets_) {
    centred = centred && o == std::floor(o);
    reach = std::max(reach, static_cast<int>(std::ceil(std::fabs(o))));
  }
  // Accumulate in double: the weighted sums of positive terms, rounded up at the end.
  const std::size_t row = std::size_t(w) * kChannels;
  std::vector<double> acc_up(std::size_t(y1 - y0) * row, 0.0), acc_dn(acc_up.size(), 0.0);
  if (centred) {
    const int r0 = hz ? y0 : std::max(0, y0 - reach), r1 = hz ? y1 : std::min(h, y1 + reach);
    std::vector<float> gu(std::size_t(r1 - r0) * row), gd(gu.size());
    for (int y = r0; y < r1; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t at = std::size_t(y - r0) * row + std::size_t(x) * kChannels;
        deviation(x, y, hz ? x : y, along_, &gu[at], &gd[at]);
      }
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t out = std::size_t(y - y0) * row + std::size_t(x) * kChannels;
        for (std::size_t k = 0; k < offsets_.size(); ++k) {
          const int a = clampi((hz ? x : y) + static_cast<int>(offsets_[k]), n_along);
          const int tx = hz ? a : x, ty = hz ? y : a;
          const std::size_t at = std::size_t(ty - r0) * row + std::size_t(tx) * kChannels;
          for (int c = 0; c < 3; ++c) {
            acc_up[out + c] += weights_[k] * gu[at + c];
            acc_dn[out + c] += weights_[k] * gd[at + c];
          }
        }
      }
  } else {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t out = std::size_t(y - y0) * row + std::size_t(x) * kChannels;
        for (std::size_t k = 0; k < offsets_.size(); ++k) {
          float u[3], d[3];
          deviation(x, y, (hz ? x : y) + offsets_[k], tap_shift_[k], u, d);
          for (int c = 0; c < 3; ++c) {
            acc_up[out + c] += weights_[k] * u[c];
            acc_dn[out + c] += weights_[k] * d[c];
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
