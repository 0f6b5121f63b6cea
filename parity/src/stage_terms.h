// One stage's isolated oracle and bounds, kind by kind, as rows of bands (internal to parity):
// what compare_captured judges each stage with. Row layout: StageBounds' (RGBA rows of the
// stage's width, packed, alpha unused).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "bloomref/half.h"
#include "bloomref/parity/compare.h"
#include "bloomref/plan.h"
#include "holding.h"
#include "tolerance.h"

namespace bloomref::parity::detail {

// Rows of a band, band-local: a function of the band's isolated bound.
using BandRows = std::function<void(int y0, int y1, const float* bound, float* out)>;

// Rows of an input's end-to-end bound as a stage reads them: the image kept, or, for the input
// stage (a function of the scene, which is held anyway), made again.
struct BoundRows {
  const Image* image = nullptr;
  std::shared_ptr<const StageBounds> made;
  // Rows [y0, y1) in StageBounds' layout: in the image, or made into `scratch`.
  const float* rows(int y0, int y1, int w, std::vector<float>& scratch) const {
    if (image) return image->cview().row(y0);
    if (scratch.size() < std::size_t(y1 - y0) * w * kChannels) scratch.resize(std::size_t(y1 - y0) * w * kChannels);
    made->rows(y0, y1, scratch.data(), nullptr);
    return scratch.data();
  }
};

// One stage's isolated oracle and bounds (stage_terms): the bound, what inputs without capture
// carry into it (empty: nothing), and its end-to-end bound; each as band rows given the band's
// isolated bound.
struct StageTerms {
  Image oracle;  // unrounded
  std::unique_ptr<StageBounds> bound;
  BandRows inherited, end_to_end;
};

// The float after x toward +infinity (next_up) or -infinity (next_down): std::nextafter's value
// (NaN and the infinity it moves toward unchanged; either zero to the smallest denormal of that
// direction), inline: the envelopes round every value of a band outward with it.
inline float next_up(float x) {
  std::uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  // Away from zero above it, toward zero below it; either zero to the smallest denormal. As
  // selects, not branches: loops over rows vectorise.
  std::uint32_t u = b < 0x80000000u ? b + 1 : b - 1;
  u = (b & 0x7fffffffu) == 0 ? 1u : u;
  float r;
  std::memcpy(&r, &u, sizeof r);
  return x < INFINITY ? r : x;
}
inline float next_down(float x) { return -next_up(-x); }

// Scratch rows of a band, per thread (reused band after band).
struct BandScratch {
  std::vector<float> bound, rounding, inherited, e2e, judged, codes, codes_e2e, oracle_e2e, kept;
  std::vector<float> envelope;  // a blur pass's envelope rows (high, then low)
  std::vector<float> read[2];  // end-to-end bounds of the inputs made again (BoundRows)
  static float* rows(std::vector<float>& v, std::size_t n) {
    if (v.size() < n) v.resize(n);
    return v.data();
  }
};

BandScratch& band_scratch();

// a + b in float, value by value (the bounds' sums: each a float image before).
void add_rows(float* a, const float* b, std::size_t n);

// The override of a stage's bound in the profile (bound x scale + absolute), over n texels.
void override_rows(const StageOverride* over, float* b, std::size_t n);

// Rows [y0, y0 + n / width) of an image from band rows: RGB, alpha 0 (as the bound images
// always had).
void put_rows(Image& img, int y0, const float* rows, std::size_t n);

/// A bound on how far x^(1/gamma) moves over [m - e, m + e] (the end-to-end bound carried
/// through the output stage's gamma).
float through_output(double m, double e, double gamma);

// An 8-bit capture: the oracle value clamped to [0, 1] (what the capture could hold), in
// place, and half a code of the capture's encoding at that value.
float capture_code(const CapturedStage& cap, float& o);

// capture_code over n RGBA texels: the oracle clamped in place, the codes into `codes`.
void capture_codes(const CapturedStage& cap, float* oracle, float* codes, std::size_t n);

// A stage of the oracle from its inputs, unrounded, as the CPU executor computes it: the same
// functions (the fast blur and finishing stages give the reference's bits). Its buffer comes
// from `pool`.
Image oracle_stage(const Plan& plan, const StageSpec& spec, ConstImageView sanitized,
                   const std::vector<ConstImageView>& in, int subtexel_bits, ImagePool& pool);

// What a stage's terms are made from: the images of the comparison, by stage name.
struct TermInputs {
  const Plan& plan;
  const DeviceProfile& profile;
  BoundContext ctx;
  ConstImageView sanitized;  // the scene after the non-finite policy, unrounded
  ImagePool& pool;
  std::function<ConstImageView(const std::string&)> isolated;  // as the isolated oracle reads it
  std::function<const Image*(const std::string&)> carried;     // error without capture, or null
  std::function<ConstImageView(const std::string&)> full;      // the oracle's full run
  std::function<BoundRows(const std::string&)> end_to_end;     // its end-to-end bound
};

// The isolated oracle and bounds of `spec`, whose inputs are `in` (stage_inputs).
StageTerms stage_terms(const StageSpec& spec, const std::vector<std::string>& in,
                       const TermInputs& at);

}  // namespace bloomref::parity::detail
