// bloomref — the separable blur kernels.
//
// A kernel is a centre tap plus symmetric pairs at +-offset[i] texels, applied in the seeds'
// order: r = T(uv) * w0; for i: r += T(uv + o_i d) * w_i; r += T(uv - o_i d) * w_i.
//  * discrete9 — LearnOpenGL's 9 taps (seed 004's 10-digit constants; binomial row 12 with the
//    two outer terms dropped: 924, 792, 495, 220, 66 over 4070).
//  * linear5 — rastergrid's "Efficient Gaussian blur with linear sampling" (seed 002): pairs of
//    discrete taps merged into one bilinear fetch, offsets 1 + 495/1287 and 3 + 66/286.
//  * discrete9_seed000 — the 6-digit constants printed in seed 000 (sum 0.9999994), kept to
//    measure what they lose per pass; not offered on the command line.
#pragma once

#include <string>
#include <vector>

#include "bloomref/params.h"

namespace bloomref {

struct Kernel {
  std::string name;
  std::vector<float> offsets_f32;   ///< as the shader's uniform array holds them
  std::vector<float> weights_f32;   ///< as the shader's uniform array holds them
  std::vector<double> offsets_f64;  ///< exact (the rationals the constants round)
  std::vector<double> weights_f64;  ///< exact
  int taps() const { return 2 * static_cast<int>(weights_f32.size()) - 1; }
  int radius_texels() const;  ///< farthest texel any tap can touch
};

const Kernel& kernel_discrete9();
const Kernel& kernel_linear5();
const Kernel& kernel_discrete9_seed000();
const Kernel& kernel_for(KernelName name);

}  // namespace bloomref
