// bloomref's GL stage shaders (gpu/shaders/*.glsl, the same files) as Vulkan compute programs:
// the GL path's compute entry point (compute_main.glsl: 8x8 work groups storing to one or two
// storage images at bindings 0 and 1), common.glsl and the stage, their plain uniforms moved
// into one push-constant block and their samplers numbered from binding 2. Compiled to SPIR-V
// with shaderc when the run starts.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "vk_objects.h"

namespace bloomref::vulkan {

/// A plain uniform moved into the push-constant block: its name, GLSL type (float, int, bool,
/// vec2, ivec2, vec3, vec4) and byte offset.
struct PushMember {
  std::string name, type;
  std::uint32_t offset = 0;
};

/// The push-constant block of `members` in their order, each at its std430 offset (set here);
/// `bytes` is the block's size.
std::string push_constant_block(std::vector<PushMember>& members, std::uint32_t& bytes);

/// SPIR-V of the compute shader `text` (the file name `file` in messages). Throws VulkanError
/// starting with `what` and holding the compiler's message when it does not compile.
/// `hlsl`: the text is HLSL (glslang's front end), its entry point `entry`. Unoptimised: the
/// SPIR-V glslangValidator makes, with the names reflection reads.
std::vector<std::uint32_t> compile_compute(const std::string& text, const std::string& file,
                                           const std::string& what, bool hlsl = false,
                                           const std::string& entry = "main");

/// Submits one dispatch of `pipeline` (8x8 work groups over `width` x `height`) with `push` and
/// waits for it; its time on the device in ms (two timestamps), or -1 without timestamps.
double timed_dispatch(Context::Impl& ctx, const ComputePipeline& pipeline, const void* push,
                      int width, int height);
/// The same with the number of work groups given.
double timed_dispatch_groups(Context::Impl& ctx, const ComputePipeline& pipeline, const void* push,
                             std::uint32_t groups_x, std::uint32_t groups_y);

class StageProgram {
 public:
  /// Stage file `file` of gpu/shaders (with common.glsl before it) under `defines` ("NAME
  /// VALUE"). Throws VulkanError with the compiler's message when it does not compile.
  /// `edit`, when given, changes the stage file's text first (an injected fault).
  StageProgram(Context::Impl& ctx, const std::string& file, const std::vector<std::string>& defines,
               const std::function<std::string(const std::string&, std::string)>& edit = {});
  /// A push constant by its uniform name (float, int or bool); throws for an unknown name.
  void set(const std::string& name, float v);
  void set_int(const std::string& name, int v);
  /// Submits one dispatch over `out0` (and `out1`, the second output, or out0 again), reading
  /// `inputs` through its samplers in declaration order; the descriptor set is rewritten, so
  /// the previous dispatch must have finished.
  /// Returns the dispatch's time on the device in ms (its two timestamps), or -1 where the
  /// queue has no timestamps.
  double run(const std::vector<const Image2D*>& inputs, const Image2D& out0, const Image2D* out1,
             VkSampler sampler);

 private:
  using Member = PushMember;
  const Member& member(const std::string& name) const;
  Context::Impl& ctx_;
  std::string file_;
  std::vector<std::string> samplers_;
  std::vector<Member> members_;
  std::vector<unsigned char> push_;
  std::unique_ptr<ComputePipeline> pipeline_;
};

/// The GLSL text StageProgram compiles (for tests and messages).
std::string vulkan_stage_source(const std::string& file, const std::vector<std::string>& defines,
                                const std::function<std::string(const std::string&, std::string)>& edit = {});

}  // namespace bloomref::vulkan
