// bloomref Vulkan — a pipeline description (bloomref/gpu/described_pipeline.h) run through
// Vulkan compute: each pass's fragment shader becomes a compute shader over its target (one
// invocation per texel, its texture coordinate the texel's centre over the target's size, as
// the pass-through vertex shader interpolates it; gl_FragCoord the centre), GL's blending done
// in the shader with the target read before it is written. The built-in presets run so
// (gpu::preset_description).
#pragma once

#include <string>

#include "bloomref/executor.h"
#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/vulkan/context.h"

namespace bloomref::vulkan {

/// The GLSL compute shader a fragment shader of a description becomes: `source` (GLSL 330 or
/// later, with `in` texture coordinates, one `out` colour, plain uniforms and sampler2D
/// uniforms) with its uniforms in a push-constant block, its samplers at bindings 1 and on, its
/// target a storage image of `target_format` at binding 0 and, where `blend` is enabled, GL's
/// blending of its result with what the target holds. Throws ParamError naming `name` for what
/// a compute shader cannot be given (a vertex shader's varyings other than a vec2, more than one
/// output, an initialiser that is not a number).
std::string fragment_as_compute(const std::string& source, const std::string& name,
                                gpu::TargetFormat target_format, const gpu::DescribedBlend& blend);

/// Runs `d` on `scene` (params: the non-finite policy, a bright texture's threshold, threads).
/// The trace holds the stages its textures and passes name, in order, with each dispatch's
/// device time. Throws ParamError (naming the description and the pass) as gpu::run_described
/// does, UserShaderError for a shader that does not compile for Vulkan, VulkanError when the
/// device cannot store a format.
StageTrace run_described(Context& ctx, ConstImageView scene, const gpu::PipelineDescription& d,
                         const BloomParams& params);

}  // namespace bloomref::vulkan
