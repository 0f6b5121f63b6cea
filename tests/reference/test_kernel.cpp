// The kernels' constants against the rationals they come from (seed 004, seed 002, seed 000).
#include <catch2/catch.hpp>

#include "bloomref/kernel.h"

using namespace bloomref;

TEST_CASE("discrete9 constants are 924, 792, 495, 220, 66 over 4070 to 10 digits", "[kernel]") {
  const Kernel& k = kernel_discrete9();
  const double exact[] = {924.0 / 4070, 792.0 / 4070, 495.0 / 4070, 220.0 / 4070, 66.0 / 4070};
  const double printed[] = {0.2270270270, 0.1945945946, 0.1216216216, 0.0540540541, 0.0162162162};
  for (int i = 0; i < 5; ++i) {
    CHECK(std::fabs(printed[i] - exact[i]) <= 0.5e-10);            // 10-digit rounding
    CHECK(k.weights_f32[i] == static_cast<float>(printed[i]));       // as the shader holds them
    CHECK(k.weights_f64[i] == Approx(exact[i]).epsilon(1e-15));
  }
  // Hand sum: 0.2270270270 + 2 * (0.1945945946 + 0.1216216216 + 0.0540540541 + 0.0162162162)
  //         = 0.2270270270 + 2 * 0.3864864865 = 1.0000000000.
  double f64 = k.weights_f64[0], f32 = k.weights_f32[0];
  for (int i = 1; i < 5; ++i) {
    f64 += 2 * k.weights_f64[i];
    f32 += 2.0 * k.weights_f32[i];
  }
  CHECK(f64 == Approx(1.0).epsilon(1e-15));
  // Each float constant is within half an ulp (< 2^-25 relative) of its decimal: the 9 taps
  // lose at most 9 * 2^-25 * max(w) < 1e-7 of the energy per pass.
  CHECK(std::fabs(f32 - 1.0) < 1e-7);
}

TEST_CASE("linear5 merges discrete9's taps 1+2 and 3+4 (rastergrid)", "[kernel]") {
  const Kernel& k = kernel_linear5();
  CHECK(k.weights_f64[1] == Approx((792.0 + 495.0) / 4070).epsilon(1e-15));
  CHECK(k.weights_f64[2] == Approx((220.0 + 66.0) / 4070).epsilon(1e-15));
  // offset = (1 * 792 + 2 * 495) / 1287 = 1782 / 1287; (3 * 220 + 4 * 66) / 286 = 924 / 286.
  CHECK(k.offsets_f64[1] == Approx(1782.0 / 1287).epsilon(1e-15));
  CHECK(k.offsets_f64[2] == Approx(924.0 / 286).epsilon(1e-15));
  CHECK(std::fabs(1.3846153846 - 1782.0 / 1287) <= 0.5e-10);
  CHECK(std::fabs(3.2307692308 - 924.0 / 286) <= 0.5e-10);
  // 0.2270270270 + 2 * (0.3162162162 + 0.0702702703) = 1.0000000000
  CHECK(k.weights_f64[0] + 2 * (k.weights_f64[1] + k.weights_f64[2]) == Approx(1.0).epsilon(1e-15));
}

TEST_CASE("seed 000's 6-digit constants sum to 0.9999994", "[kernel]") {
  const Kernel& k = kernel_discrete9_seed000();
  // 0.227027 + 2 * (0.1945946 + 0.1216216 + 0.054054 + 0.016216) = 0.227027 + 0.7729724
  double s = k.weights_f64[0];
  for (int i = 1; i < 5; ++i) s += 2 * k.weights_f64[i];
  CHECK(s == Approx(0.9999994).epsilon(1e-15));
  CHECK(k.taps() == 9);
  CHECK(kernel_linear5().taps() == 5);
}
