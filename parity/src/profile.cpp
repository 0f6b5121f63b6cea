#include "bloomref/parity/profile.h"

#include <fnmatch.h>

#include "bloomref/error.h"

namespace bloomref::parity {

DeviceProfile profile_llvmpipe() {
  DeviceProfile p;
  p.name = "llvmpipe";
  p.source = "measured with `bloomref gl-info` on Mesa 22.3.6 llvmpipe (docs/design.md, GL path)";
  p.subtexel_bits = 0;           // 1024 distinct results in a 1024-sample sweep
  p.half_nearest_even = false;   // writes round toward zero ...
  p.half_toward_zero = true;
  p.half_overflow_inf = false;   // ... and saturate: 65520 and 70000 read back as 65504
  p.half_overflow_saturate = true;
  p.flush_denormals = true;      // 2^-126 * 0.5 computes to 0
  p.fma = true;                  // not observed, but GLSL allows it
  p.division_ulps = 2.5;
  return p;
}

DeviceProfile profile_lavapipe() {
  DeviceProfile p = profile_llvmpipe();  // Mesa's Vulkan driver: llvmpipe's sampler and stores
  p.name = "lavapipe";
  p.source = "measured with `bloomref vulkan-info` on Mesa 22.3.6 lavapipe (docs/design.md, "
             "Vulkan device)";
  p.flush_denormals = false;  // 2^-126 * 0.5 computes to 2^-127 in its compute shaders
  return p;
}

DeviceProfile profile_nvidia_like() {
  DeviceProfile p;
  p.name = "nvidia";
  p.source = "device class: 8-bit fixed-point filtering weights (docs/design.md, GL path)";
  p.subtexel_bits = 8;
  return p;
}

DeviceProfile profile_vulkan() {
  DeviceProfile p;
  p.name = "vulkan";
  p.source = "device class: Vulkan 1.3 minimum limits (subTexelPrecisionBits >= 4), sampled at 8";
  p.subtexel_bits = 8;
  p.subtexel_bits_min = 4;
  return p;
}

DeviceProfile profile_mediump() {
  DeviceProfile p;
  p.name = "mediump";
  p.source = "device class: GLSL ES 3.00 mediump (relative precision 2^-10), 8-bit filtering";
  p.subtexel_bits = 8;
  p.unit_roundoff = 0x1p-11;
  return p;
}

DeviceProfile profile_ldr8() {
  DeviceProfile p = profile_nvidia_like();
  p.name = "ldr8";
  p.source = "8-bit captures: half a code per value, nvidia-like sampling";
  p.capture_code_bits = 8;
  return p;
}

const StageOverride* stage_override(const DeviceProfile& p, const std::string& stage) {
  for (const StageOverride& o : p.overrides)
    if (fnmatch(o.pattern.c_str(), stage.c_str(), 0) == 0) return &o;
  return nullptr;
}

DeviceProfile profile_named(const std::string& name) {
  if (name == "llvmpipe") return profile_llvmpipe();
  if (name == "lavapipe") return profile_lavapipe();
  if (name == "nvidia") return profile_nvidia_like();
  if (name == "vulkan") return profile_vulkan();
  if (name == "mediump") return profile_mediump();
  if (name == "ldr8") return profile_ldr8();
  throw ParamError("--profile '" + name + "' is not one of: " + profile_names());
}

std::string profile_names() { return "llvmpipe, lavapipe, nvidia, vulkan, mediump, ldr8"; }

}  // namespace bloomref::parity
