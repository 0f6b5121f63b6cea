#include "bloomref/kernel.h"

#include <cmath>

namespace bloomref {

int Kernel::radius_texels() const {
  // A tap at offset o may, through float coordinate rounding, touch the texel beyond ceil(o).
  return static_cast<int>(std::ceil(offsets_f64.back())) + 1;
}

const Kernel& kernel_discrete9() {
  // Seed 004 (FS_blur.glsl) and docs/design.md ("Specification"): binomial row 12 without its two outer terms,
  // 924, 792, 495, 220, 66 over 4070, printed to 10 digits.
  static const Kernel k{"discrete9",
                        {0.0f, 1.0f, 2.0f, 3.0f, 4.0f},
                        {0.2270270270f, 0.1945945946f, 0.1216216216f, 0.0540540541f,
                         0.0162162162f},
                        {0.0, 1.0, 2.0, 3.0, 4.0},
                        {924.0 / 4070, 792.0 / 4070, 495.0 / 4070, 220.0 / 4070, 66.0 / 4070}};
  return k;
}

const Kernel& kernel_linear5() {
  // Seed 002 (rastergrid, "Efficient Gaussian blur with linear sampling"): taps 1+2 and 3+4 of
  // discrete9 merged: weight 792+495 at 1 + 495/1287, weight 220+66 at 3 + 66/286.
  static const Kernel k{"linear5",
                        {0.0f, 1.3846153846f, 3.2307692308f},
                        {0.2270270270f, 0.3162162162f, 0.0702702703f},
                        {0.0, 1.0 + 495.0 / 1287, 3.0 + 66.0 / 286},
                        {924.0 / 4070, 1287.0 / 4070, 286.0 / 4070}};
  return k;
}

const Kernel& kernel_discrete9_seed000() {
  // Seed 000 (LearnOpenGL's blur shader as printed): 6-digit weights summing to 0.9999994.
  static const Kernel k{"discrete9_seed000",
                        {0.0f, 1.0f, 2.0f, 3.0f, 4.0f},
                        {0.227027f, 0.1945946f, 0.1216216f, 0.054054f, 0.016216f},
                        {0.0, 1.0, 2.0, 3.0, 4.0},
                        {0.227027, 0.1945946, 0.1216216, 0.054054, 0.016216}};
  return k;
}

const Kernel& kernel_for(KernelName name) {
  return name == KernelName::linear5 ? kernel_linear5() : kernel_discrete9();
}

}  // namespace bloomref
