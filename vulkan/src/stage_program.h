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
  struct Member {
    std::string name, type;
    std::uint32_t offset;
  };
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
