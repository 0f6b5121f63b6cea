#include "bloomref/parity/profile.h"

#include "bloomref/error.h"

namespace bloomref::parity {

DeviceProfile profile_llvmpipe() {
  DeviceProfile p;
  p.name = "llvmpipe";
  p.source = "measured with `bloomref gl-info` on Mesa 22.3.6 llvmpipe (README, GL facts)";
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

DeviceProfile profile_nvidia_like() {
  DeviceProfile p;
  p.name = "nvidia";
  p.source = "device class: 8-bit fixed-point filtering weights (DESIGN.md, GL facts)";
  p.subtexel_bits = 8;
  return p;
}

DeviceProfile profile_named(const std::string& name) {
  if (name == "llvmpipe") return profile_llvmpipe();
  if (name == "nvidia") return profile_nvidia_like();
  throw ParamError("--profile '" + name + "' is not one of: " + profile_names());
}

std::string profile_names() { return "llvmpipe, nvidia"; }

}  // namespace bloomref::parity
