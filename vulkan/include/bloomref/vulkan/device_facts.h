// bloomref Vulkan — facts about the device measured by running a compute probe on it, as
// gpu/device_facts.h measures a GL device: how a store to an RGBA16F storage image rounds, how
// precise the linear sampler's weights are, whether a * b + c is fused and denormals kept.
#pragma once

#include <string>

#include "bloomref/vulkan/context.h"

namespace bloomref::vulkan {

struct DeviceFacts {
  /// float -> half on an imageStore to an RGBA16F storage image: "nearest-even", "toward-zero"
  /// or "other".
  std::string half_rounding;
  float half_of_65520 = 0, half_of_70000 = 0;  ///< what the ties above 65504 become
  bool half_denormals_kept = false;  ///< 2^-20 stored to RGBA16F reads back as 2^-20
  bool f32_denormals_kept = false;   ///< 2^-140 stored to RGBA32F reads back as 2^-140
  bool shader_denormals_kept = false;  ///< 2^-126 * 0.5 computed in the shader is not flushed
  /// Distinct linear-sampler results across one texel span in a 1024-sample sweep between
  /// texels holding 0 and 1: about 1024 means float weights; 2^b + 1 means b-bit fixed point.
  int bilinear_distinct = 0;
  int subtexel_bits = 0;  ///< 0 = float weights, else the b above
  bool fma_contracted = false;  ///< a * b + c in the shader was fused
};

DeviceFacts measure_device_facts(Context& ctx);

}  // namespace bloomref::vulkan
