#include <map>
#include <stdexcept>

#include "bloomref/error.h"
#include "bloomref/gpu/gl_executor.h"
#include "fault_patches.h"

namespace bloomref::gpu {
namespace {

// weight[1] of both blur kernels (only the compiled one matters) scaled by `scale`, as the
// shader's float arithmetic would: the literal times the scale, rounded to float.
std::vector<SourcePatch> weight_patches(const std::string& scale) {
  return {{"blur_pass.glsl", "float weight[3] = float[](0.2270270270, 0.3162162162,",
           "float weight[3] = float[](0.2270270270, 0.3162162162 * " + scale + ","},
          {"blur_pass.glsl", "float weight[5] = float[](0.2270270270, 0.1945945946,",
           "float weight[5] = float[](0.2270270270, 0.1945945946 * " + scale + ","}};
}

const std::map<Fault, std::vector<SourcePatch>>& patch_table() {
  static const std::map<Fault, std::vector<SourcePatch>> table = {
      // seed 001's blur shader: the vertical branch offsets along x.
      {Fault::vertical_offsets_x,
       {{"blur_pass.glsl", "vec2(0.0, tex_offset.y * offset[i])",
         "vec2(tex_offset.y * offset[i], 0.0)"}}},
      {Fault::half_texel_shift,
       {{"blur_pass.glsl", "  vec3 result = texture(image, uv).rgb * weight[0];",
         "  uv = uv + 0.5 * tex_offset;\n  vec3 result = texture(image, uv).rgb * weight[0];"}}},
      {Fault::threshold_ge,
       {{"extract_bright.glsl", "threshold_luminance(v.rgb) > threshold",
         "threshold_luminance(v.rgb) >= threshold"}}},
      {Fault::weight_1pct, weight_patches("1.01")},
      {Fault::weight_0_1pct, weight_patches("1.001")},
      {Fault::weight_0_01pct, weight_patches("1.0001")},
      {Fault::gamma_twice,
       {{"encode_output.glsl", "  vec3 c = pow(max(m.rgb, vec3(0.0)), vec3(1.0 / gamma));",
         "  vec3 c = pow(max(m.rgb, vec3(0.0)), vec3(1.0 / gamma));\n"
         "  c = pow(max(c, vec3(0.0)), vec3(1.0 / gamma));"}}},
      {Fault::swap_rb,
       {{"composite.glsl", "  vec3 hdr = s.rgb + strength * b;",
         "  vec3 hdr = s.rgb + strength * b;\n  hdr = hdr.bgr;"}}},
      {Fault::exposure_ignored, {{"tonemap.glsl", "vec3 x = -h.rgb * exposure;", "vec3 x = -h.rgb;"}}},
      // Tap 5 (the corner (-2, -2)) half a texel further out on each axis.
      {Fault::tap_offset,
       {{"downsample.glsl", "vec2 o = vec2(down_offset[i]);",
         "vec2 o = vec2(down_offset[i]) * (i == 5 ? 1.5 : 1.0);"}}},
      {Fault::karis_unnormalised,
       {{"downsample.glsl", "float f = group_weight[g] * w[i] / s;",
         "float f = group_weight[g] * w[i];"}}},
  };
  return table;
}

}  // namespace

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
      {Fault::level_offset, "mip-level-offset", "up.2",
       "mip: the upsample of level 2 reads level 4 where level 3 is specified (an index off by "
       "one; needs 4 levels)"},
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
                         f == Fault::level_size || f == Fault::level_offset;
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

const std::vector<SourcePatch>& fault_patches(Fault f) {
  static const std::vector<SourcePatch> none;
  const auto it = patch_table().find(f);
  return it == patch_table().end() ? none : it->second;
}

std::string apply_fault(Fault f, const std::string& file, std::string source) {
  for (const SourcePatch& p : fault_patches(f)) {
    if (p.file != file) continue;
    const std::size_t at = source.find(p.anchor);
    const bool once = at != std::string::npos && source.find(p.anchor, at + 1) == std::string::npos;
    if (!once)
      throw std::logic_error("fault '" + fault_info(f).name + "': anchor '" + p.anchor + "' is " +
                             (at == std::string::npos ? "not in " : "more than once in ") + file);
    source.replace(at, p.anchor.size(), p.replacement);
  }
  return source;
}

bool fault_in_shaders(Fault f) { return !fault_patches(f).empty(); }

}  // namespace bloomref::gpu
