// bloomref Vulkan — a Plan run through Vulkan compute with bloomref's own stage shaders (the GL
// path's gpu/shaders files, compiled for Vulkan): every stage read back for parity, as the GL
// executor's keep_all trace. Methods gaussian and mip (seed 002's chain), f32 and f16 storage.
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

/// Runs `plan` (params as the plan gives them) on `scene`. Every stage is computed whole (no
/// adaptive leaving out). Throws ParamError for what it does not run (f64 precision, a mip-chain
/// variant, the mix composite), VulkanError when the device fails.
StageTrace execute_vulkan(Context& ctx, const Plan& plan, ConstImageView scene,
                          const SourceEdit& edit = {});

}  // namespace bloomref::vulkan
