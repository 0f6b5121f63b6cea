// bloomref parity — a device precision profile: what a GL implementation may do differently
// from the CPU oracle and still be right. Every tolerance term comes from one of these fields
// or from the GLSL 4.50 specification's precision table (section 4.7.1): division 2.5 ULP,
// exp/exp2 (3 + 2|x|) ULP, log/log2 3 ULP outside [0.5, 2] and 2^-21 absolute inside,
// pow as exp2(y * log2(x)).
#pragma once

#include <string>

namespace bloomref::parity {

struct DeviceProfile {
  std::string name;
  std::string source;          ///< where the fields come from (measured, or the device class)
  int subtexel_bits = 0;       ///< bilinear weight bits: 0 = float weights
  bool half_nearest_even = true;   ///< accepted float->half write roundings
  bool half_toward_zero = true;
  bool half_overflow_inf = true;   ///< beyond 65504 a half write may give Inf ...
  bool half_overflow_saturate = true;  ///< ... or 65504
  bool flush_denormals = true;  ///< shader arithmetic may flush results below 2^-126 to 0
  bool fma = true;              ///< a * b + c may be fused
  double division_ulps = 2.5;   ///< GLSL: 1 / x and x / y to 2.5 ULP
  /// The luminance is computed `precise` (source order, no fusion, correctly rounded + and *,
  /// GLSL 4.00+), so it equals the CPU's bit for bit and the threshold has no rounding band.
  bool precise_luminance = true;
};

/// Mesa llvmpipe, from the facts `bloomref gl-info` measured (README, "GL facts"): float
/// bilinear weights, half writes toward zero saturating at 65504, shader arithmetic flushes
/// denormals, no FMA contraction observed (allowed anyway: a driver update may fuse).
DeviceProfile profile_llvmpipe();

/// NVIDIA-like hardware: 8-bit fixed-point bilinear weights, either half rounding, FMA.
DeviceProfile profile_nvidia_like();

/// A profile by name (profile_names()); throws ParamError otherwise.
DeviceProfile profile_named(const std::string& name);

/// The names profile_named accepts, comma-separated.
std::string profile_names();

}  // namespace bloomref::parity
