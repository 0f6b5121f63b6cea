// bloomref GPU — the same Plan executed in OpenGL, every stage readable back.
//
// Fragment path (the seeds' way): one MRT draw writes `input` and `bright`, ping-pong
// framebuffers run the blur passes through GL_LINEAR / GL_CLAMP_TO_EDGE lookups, then one draw
// each for composite, tonemap and output. Compute path: the same shaders' arithmetic as compute
// shaders writing images. Storage f32 / f16 / r11g11b10 / rgba8 is RGBA32F / RGBA16F /
// R11F_G11F_B10F / RGBA8 for every stage texture; the scene is uploaded as RGBA32F (the user's
// floats, unrounded).
#pragma once

#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/gpu/context.h"

namespace bloomref::gpu {

enum class ShaderKind { fragment, compute };
std::string to_string(ShaderKind k);
ShaderKind parse_shader_kind(const std::string& s);

/// Deliberate bugs, each charged to the stage it is injected in (docs/design.md, "Parity and the tolerance model": "not
/// vacuous"). Names are the CLI's --inject-fault values.
enum class Fault {
  none,
  vertical_offsets_x,  ///< seed 001's blur shader: the vertical pass offsets along x
  half_texel_shift,    ///< blur lookups half a texel off
  repeat_wrap,         ///< GL_REPEAT instead of GL_CLAMP_TO_EDGE on the blur's source
  threshold_ge,        ///< >= instead of > at the threshold
  weight_1pct,         ///< blur weight[1] 1% too large
  weight_0_1pct,       ///< blur weight[1] 0.1% too large
  weight_0_01pct,      ///< blur weight[1] 0.01% too large
  skip_pass,           ///< blur pass 3 not drawn: its target keeps pass 1's result
  f16_storage,         ///< RGBA16F textures where f32 storage was asked
  gamma_twice,         ///< gamma applied twice
  swap_rb,             ///< R and B swapped in the composite
  exposure_ignored,    ///< tone map without the exposure
  // method mip (seed 003)
  tap_offset,          ///< downsample tap 5 at 1.5x its offset
  karis_unnormalised,  ///< Karis weights not divided by their group's sum (needs --karis)
  level_size,          ///< level 2 allocated one texel wider than max(1, floor(n / 2))
  level_offset,        ///< the upsample of level 2 reads level 4 where level 3 is specified
};

struct FaultInfo {
  Fault fault;
  std::string name;
  std::string stage;  ///< where it is injected: the stage parity must charge
  std::string description;
};

const std::vector<FaultInfo>& fault_list();
/// Throws ParamError listing the known names.
Fault parse_fault(const std::string& name);
const FaultInfo& fault_info(Fault f);
/// Whether a fault exists in a method's shaders (blur faults in gaussian, level faults in mip;
/// storage, composite, tone map and gamma faults in both).
bool fault_applies(Fault f, Method m);
/// `source`, the text of stage shader `file` (gpu/shaders), with the edits that inject `f`
/// (none for the faults the host injects: wrap mode, a skipped pass, texture format, level
/// size, level offset). Any backend that compiles these files can inject the same bugs.
std::string apply_fault(Fault f, const std::string& file, std::string source);
/// Whether `f` is injected by editing the shaders alone (apply_fault changes some file).
bool fault_in_shaders(Fault f);

struct GlOptions {
  ShaderKind shaders = ShaderKind::fragment;
  bool keep_all = false;  ///< read back every stage (compare, debug)
  Fault fault = Fault::none;
};

/// Runs the plan; timings are wall times around each stage's draws followed by glFinish.
StageTrace execute_gl(GlContext& ctx, const Plan& plan, ConstImageView scene,
                      const GlOptions& opt = {});

}  // namespace bloomref::gpu
