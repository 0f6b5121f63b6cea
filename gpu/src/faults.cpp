#include "bloomref/error.h"
#include "bloomref/gpu/gl_executor.h"

namespace bloomref::gpu {

std::string to_string(ShaderKind k) { return k == ShaderKind::compute ? "compute" : "fragment"; }

ShaderKind parse_shader_kind(const std::string& s) {
  if (s == "fragment") return ShaderKind::fragment;
  if (s == "compute") return ShaderKind::compute;
  throw ParamError("--gl-shaders '" + s + "' is not one of: fragment, compute");
}

const std::vector<FaultInfo>& fault_list() {
  static const std::vector<FaultInfo> list = {
      {Fault::vertical_offsets_x, "vertical-offsets-x", "blur.2",
       "the vertical blur pass offsets along x (the bug in seed 001's blur shader)"},
      {Fault::half_texel_shift, "half-texel-shift", "blur.1",
       "blur lookups shifted by half a texel"},
      {Fault::repeat_wrap, "repeat-wrap", "blur.1", "GL_REPEAT instead of GL_CLAMP_TO_EDGE"},
      {Fault::threshold_ge, "threshold-ge", "bright", ">= instead of > at the threshold"},
      {Fault::weight_1pct, "weight-1pct", "blur.1", "blur weight[1] 1% too large"},
      {Fault::weight_0_1pct, "weight-0.1pct", "blur.1", "blur weight[1] 0.1% too large"},
      {Fault::weight_0_01pct, "weight-0.01pct", "blur.1", "blur weight[1] 0.01% too large"},
      {Fault::skip_pass, "skip-pass", "blur.3",
       "blur pass 3 not drawn; its ping-pong target still holds pass 1"},
      {Fault::f16_storage, "f16-storage", "input", "RGBA16F textures where f32 was asked"},
      {Fault::gamma_twice, "gamma-twice", "output", "gamma applied twice"},
      {Fault::swap_rb, "swap-rb", "composite", "R and B swapped in the composite"},
      {Fault::exposure_ignored, "exposure-ignored", "tonemap", "tone map ignores the exposure"},
      {Fault::tap_offset, "tap-offset", "down.1", "mip: downsample tap 5 at 1.5x its offset"},
      {Fault::karis_unnormalised, "karis-unnormalised", "down.1",
       "mip: Karis weights not normalised within their group (with --karis)"},
      {Fault::level_size, "level-size", "down.2",
       "mip: level 2 one texel wider than max(1, floor(n / 2))"},
  };
  return list;
}

Fault parse_fault(const std::string& name) {
  std::string known;
  for (const FaultInfo& f : fault_list()) {
    if (f.name == name) return f.fault;
    known += (known.empty() ? "" : ", ") + f.name;
  }
  throw ParamError("--inject-fault '" + name + "' is not one of: " + known);
}

bool fault_applies(Fault f, Method m) {
  const bool mip_fault = f == Fault::tap_offset || f == Fault::karis_unnormalised ||
                         f == Fault::level_size;
  const bool gaussian_fault = f == Fault::vertical_offsets_x || f == Fault::half_texel_shift ||
                              f == Fault::repeat_wrap || f == Fault::threshold_ge ||
                              f == Fault::weight_1pct || f == Fault::weight_0_1pct ||
                              f == Fault::weight_0_01pct || f == Fault::skip_pass;
  return m == Method::mip ? !gaussian_fault : !mip_fault;
}

const FaultInfo& fault_info(Fault f) {
  static const FaultInfo none{Fault::none, "none", "", "no fault"};
  for (const FaultInfo& i : fault_list())
    if (i.fault == f) return i;
  return none;
}

}  // namespace bloomref::gpu
