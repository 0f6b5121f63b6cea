// bloomref Vulkan — a Plan run through Vulkan compute with bloomref's own stage shaders (the GL
// path's gpu/shaders files, compiled for Vulkan): every stage read back for parity, as the GL
// executor's keep_all trace. Methods gaussian and mip (seed 002's chain), f32 and f16 storage;
// the presets' chains through their pipeline descriptions (described.h).
#pragma once

#include <functional>
#include <string>

#include "bloomref/executor.h"
#include "bloomref/plan.h"
#include "bloomref/vulkan/context.h"

namespace bloomref::vulkan {

/// An edit of a stage shader's text before it is compiled: (file name, text) -> text. The CLI
/// passes gpu::apply_fault's, so that `compare --inject-fault` breaks the Vulkan run the way it
/// breaks GL's.
using SourceEdit = std::function<std::string(const std::string& file, std::string text)>;

/// The faults compare injects through the host rather than the shaders' text (gpu::Fault's
/// repeat-wrap, skip-pass, f16-storage, level-size, mip-level-offset), as the GL executor
/// injects them: each at the same stage.
struct HostFaults {
  bool repeat_wrap = false;   ///< the blur's source sampled with REPEAT, not CLAMP_TO_EDGE
  bool skip_pass = false;     ///< blur pass 3 not dispatched: its image keeps pass 1's result
  bool f16_storage = false;   ///< RGBA16F images where f32 storage was asked
  bool level_size = false;    ///< level 2 one texel wider than max(1, floor(n / 2))
  bool level_offset = false;  ///< the upsample of level 2 reads level 4, not level 3
};

/// Runs `plan` (params as the plan gives them) on `scene`. Every stage is computed whole (no
/// adaptive leaving out). A mip-chain variant (a preset's chain: learnopengl-pbb, bevy,
/// unity-urp) runs its host code's passes through run_described (gpu::preset_description).
/// Throws ParamError for what it does not run (f64 precision, a variant no preset draws, a
/// fault in a variant), VulkanError when the device fails.
StageTrace execute_vulkan(Context& ctx, const Plan& plan, ConstImageView scene,
                          const SourceEdit& edit = {}, const HostFaults& faults = {});

}  // namespace bloomref::vulkan
