// bloomref parity — a device precision profile: what a GL implementation may do differently
// from the CPU oracle and still be right. Every tolerance term comes from one of these fields
// or from the GLSL 4.50 specification's precision table (section 4.7.1): division 2.5 ULP,
// exp/exp2 (3 + 2|x|) ULP, log/log2 3 ULP outside [0.5, 2] and 2^-21 absolute inside,
// pow as exp2(y * log2(x)).
#pragma once

#include <string>
#include <vector>

namespace bloomref::parity {

/// Image-level gates beside the per-value bounds (compare.h): each value may be within its
/// bound while the image as a whole is not right (a uniform offset just under the bound, a
/// sampling error spread over a region). Each value's excess ratio is its error beyond the
/// rounding it is allowed (the stage's storage and arithmetic terms, a capture's codes; with
/// f16 storage what stages without capture carry) over the rest of its bound (what sampling
/// may change: coordinates, a threshold's band, Karis weights; and what stages without capture
/// carry), at most 4; the gates bound its mean. Rounding is left out because an honest device's
/// rounding is as uniform as its image (a constant scene's tone map errs by the same 0.3 of its
/// bound everywhere on llvmpipe), while the sampling terms are far from tight. A stage whose
/// bound is all rounding (composite, tonemap, output judged from captures) has nothing to gate.
/// 0 turns a gate off.
struct ImageGates {
  double mean = 0.25;          ///< mean excess ratio over the image
  double window = 0.5;         ///< the same over each window_size x window_size block
  int window_size = 8;
  double over_fraction = 0.01; ///< fraction of values over their bound (each within the WARN tier)
  /// The gain gates (compare.h, StageComparison::gain_ratio): a stage fails when a total error
  /// exceeds this many times its derived budget. 1: the budget itself; more gives a device room
  /// its profile does not describe.
  double gain = 1.0;
};

/// A per-stage change of the tolerance: stages matching `pattern` (a shell pattern: "blur.*")
/// get bound * scale + absolute, and their own gates.
struct StageOverride {
  std::string pattern;
  double scale = 1.0, absolute = 0.0;
  bool has_gates = false;
  ImageGates gates;
};

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
  /// Relative rounding of one shader operation: 2^-24 for highp (IEEE binary32); 2^-11 for
  /// GLSL ES mediump (GLSL ES 3.00, 4.5.2: relative precision 2^-10, i.e. half an ULP of 2^-10).
  double unit_roundoff = 0x1p-24;
  /// The coarsest bilinear weight precision the device may use (0: subtexel_bits). Vulkan
  /// requires subTexelPrecisionBits >= 4 (Vulkan 1.3, Table 53 "Required Limits"); the oracle
  /// samples with subtexel_bits and the bound allows one quantum of 2^-subtexel_bits_min.
  int subtexel_bits_min = 0;
  /// Every capture holds 8-bit codes (0: as each file says): PNG screenshots saved as EXR.
  int capture_code_bits = 0;
  ImageGates gates;
  std::vector<StageOverride> overrides;  ///< the first matching pattern applies
};

/// Mesa llvmpipe, from the facts `bloomref gl-info` measured (docs/design.md, "What llvmpipe
/// does where GL leaves it open"): float bilinear weights, half writes toward zero saturating
/// at 65504, shader arithmetic flushes denormals, no FMA contraction observed (allowed anyway:
/// a driver update may fuse).
DeviceProfile profile_llvmpipe();

/// Mesa lavapipe (Vulkan), from the facts `bloomref vulkan-info` measured: llvmpipe's sampler
/// and stores (the same code; tests/cli/test_vulkan_cli.py holds the two probes to it), but its
/// compute shaders keep denormals.
DeviceProfile profile_lavapipe();

/// NVIDIA-like hardware: 8-bit fixed-point bilinear weights, either half rounding, FMA.
DeviceProfile profile_nvidia_like();

/// Vulkan-class hardware: 4 to 8 sub-texel bits (the oracle samples at 8), either half
/// rounding, FMA, flushed denormals.
DeviceProfile profile_vulkan();

/// Mobile GLSL ES mediump: every operation to 2^-11 relative, 8-bit filtering, either half
/// rounding.
DeviceProfile profile_mediump();

/// 8-bit captures (PNG screenshots, however saved): nvidia-like sampling, every captured value
/// allowed half a code.
DeviceProfile profile_ldr8();

/// The override of `stage` (the first whose pattern matches), or nullptr.
const StageOverride* stage_override(const DeviceProfile& p, const std::string& stage);

/// A profile by name (profile_names()); throws ParamError otherwise.
DeviceProfile profile_named(const std::string& name);

/// The names profile_named accepts, comma-separated.
std::string profile_names();

}  // namespace bloomref::parity
