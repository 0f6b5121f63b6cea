// bloomref GPU — facts about the GL device, measured rather than assumed (docs/design.md, "Specification": "GL does
// not pin how a render-target write rounds float to half ... measure"). The tolerance model
// builds its device profile from them.
#pragma once

#include <string>
#include <vector>

#include "bloomref/gpu/context.h"

namespace bloomref::gpu {

struct DeviceFacts {
  std::string renderer;
  /// float -> half on a RGBA16F render-target write: "nearest-even", "toward-zero" or "other".
  std::string half_rounding;
  /// What 65520 (the tie above 65504) and 70000 become when written to RGBA16F.
  float half_of_65520 = 0, half_of_70000 = 0;
  bool half_denormals_kept = false;  ///< 2^-20 written to RGBA16F reads back as 2^-20
  bool f32_denormals_kept = false;   ///< 2^-140 written to RGBA32F reads back as 2^-140
  bool shader_denormals_kept = false;  ///< 2^-126 * 0.5 computed in a shader is not flushed
  /// Distinct GL_LINEAR results across one texel span in a 1024-sample sweep between texels
  /// holding 0 and 1: 1024 means float weights; 2^b + 1 means b-bit fixed point.
  int bilinear_distinct = 0;
  int subtexel_bits = 0;       ///< 0 = float weights, else the b above
  bool fma_contracted = false;  ///< a * b + c in a shader was fused
  /// GL_LINEAR reads of an RGBA16F texture: texels holding the half denormal 2^-20 read as it
  /// at every weight ("kept"), as 0 ("flushed"), or otherwise ("other").
  std::string half_denormal_texels;
  /// Between texels 0 and 2^-24 (denormals), and between 1 and 1 + 2^-10 (normals): values in
  /// between ("float": the filter's result is not rounded to halves), only the two ("half"),
  /// or others ("other").
  std::string half_filter_denormals, half_filter_normals;
  std::vector<std::string> notes;
};

DeviceFacts measure_device_facts(GlContext& ctx);

/// The facts above from a sweep's samples: "kept" when every sample is `value`, "flushed" when
/// every one is 0, else "other".
std::string classify_equal(const std::vector<float>& samples, float value);
/// "float" when a sample lies strictly between lo and hi, "half" when every one is lo or hi,
/// else "other".
std::string classify_between(const std::vector<float>& samples, float lo, float hi);

}  // namespace bloomref::gpu
