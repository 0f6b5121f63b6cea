#include "stage_program.h"

#include <shaderc/shaderc.hpp>

#include <cstring>
#include <regex>
#include <sstream>

#include "vulkan_shader_sources.h"

namespace bloomref::vulkan {
namespace {

struct Parsed {
  std::string text;
  std::vector<std::string> samplers;
  std::vector<PushMember> members;
  std::uint32_t push_bytes = 0;
};

// Moves `uniform TYPE NAME;` lines out of `src`: samplers get bindings from 2 on (0 and 1 are
// the storage images), the others are collected for the push-constant block.
void take_uniforms(const std::string& src, Parsed& out) {
  static const std::regex sampler(R"(^\s*uniform\s+sampler2D\s+(\w+)\s*;)");
  static const std::regex plain(R"(^\s*uniform\s+(float|int|bool|ivec2|vec2)\s+(\w+)\s*;)");
  std::istringstream in(src);
  std::string line;
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_search(line, m, sampler)) {
      out.text += "layout(binding = " + std::to_string(out.samplers.size() + 2) +
                  ") uniform sampler2D " + m[1].str() + ";\n";
      out.samplers.push_back(m[1]);
    } else if (std::regex_search(line, m, plain)) {
      out.members.push_back({m[2], m[1]});
    } else {
      out.text += line + "\n";
    }
  }
}

using Edit = std::function<std::string(const std::string&, std::string)>;

Parsed parse(const std::string& file, const std::vector<std::string>& defines, const Edit& edit) {
  const auto& src = vulkan_shader_sources();
  Parsed p;  // the compute entry point (its u_origin a push constant), common, the stage
  take_uniforms(src.at("compute_main.glsl"), p);
  take_uniforms(src.at("common.glsl"), p);
  take_uniforms(edit ? edit(file, src.at(file)) : src.at(file), p);
  std::string head = "#version 450\n";
  for (const std::string& d : defines) head += "#define " + d + "\n";
  const std::string block = push_constant_block(p.members, p.push_bytes);
  p.text = head + block + p.text;
  return p;
}

}  // namespace

std::string push_constant_block(std::vector<PushMember>& members, std::uint32_t& bytes) {
  // In declaration order, each at its std430 offset (vec2 and ivec2 on 8, vec3 and vec4 on 16).
  std::string block = "layout(push_constant) uniform StageConstants {\n";
  bytes = 0;
  for (PushMember& m : members) {
    const bool wide = m.type == "vec3" || m.type == "vec4";
    const std::uint32_t align = wide ? 16 : m.type == "ivec2" || m.type == "vec2" ? 8 : 4;
    const std::uint32_t size = m.type == "vec3" ? 12 : wide ? 16 : align;
    m.offset = (bytes + align - 1) / align * align;
    block += "  layout(offset = " + std::to_string(m.offset) + ") " + m.type + " " + m.name + ";\n";
    bytes = m.offset + size;
  }
  return block + "};\n";
}

std::vector<std::uint32_t> compile_compute(const std::string& text, const std::string& file,
                                           const std::string& what, bool hlsl,
                                           const std::string& entry) {
  shaderc::Compiler compiler;
  shaderc::CompileOptions options;
  options.SetTargetEnvironment(shaderc_target_env_vulkan, shaderc_env_version_vulkan_1_1);
  options.SetOptimizationLevel(shaderc_optimization_level_zero);  // the shader's own order
  if (hlsl) {
    options.SetSourceLanguage(shaderc_source_language_hlsl);
    options.SetAutoBindUniforms(true);  // registers without [[vk::binding]] numbered in order
  }
  const shaderc::SpvCompilationResult r = compiler.CompileGlslToSpv(
      text.data(), text.size(), shaderc_compute_shader, file.c_str(), entry.c_str(), options);
  if (r.GetCompilationStatus() != shaderc_compilation_status_success)
    throw VulkanError(what + " does not compile for Vulkan: " + r.GetErrorMessage());
  return std::vector<std::uint32_t>(r.cbegin(), r.cend());
}

double timed_dispatch(Context::Impl& ctx, const ComputePipeline& pipeline, const void* push,
                      int width, int height) {
  return timed_dispatch_groups(ctx, pipeline, push, std::uint32_t((width + 7) / 8),
                               std::uint32_t((height + 7) / 8));
}

double timed_dispatch_groups(Context::Impl& ctx, const ComputePipeline& pipeline, const void* push,
                             std::uint32_t groups_x, std::uint32_t groups_y) {
  const VkQueryPool q = ctx.timestamp_pool();
  ctx.submit([&](VkCommandBuffer cb) {
    if (q) {
      vkCmdResetQueryPool(cb, q, 0, 2);
      vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, q, 0);
    }
    pipeline.dispatch(cb, push, groups_x, groups_y);
    if (q) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, q, 1);
  });
  if (!q) return -1.0;
  std::uint64_t ts[2] = {0, 0};
  check(vkGetQueryPoolResults(ctx.device, q, 0, 2, sizeof ts, ts, sizeof ts[0],
                              VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
        "vkGetQueryPoolResults");
  const unsigned bits = ctx.info.timestamp_valid_bits;
  const std::uint64_t mask = bits >= 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << bits) - 1;
  const std::uint64_t ticks = ((ts[1] & mask) - (ts[0] & mask)) & mask;
  return double(ticks) * double(ctx.info.timestamp_period_ns) * 1e-6;
}

std::string vulkan_stage_source(const std::string& file, const std::vector<std::string>& defines,
                                const Edit& edit) {
  return parse(file, defines, edit).text;
}

StageProgram::StageProgram(Context::Impl& ctx, const std::string& file,
                           const std::vector<std::string>& defines, const Edit& edit)
    : ctx_(ctx), file_(file) {
  const Parsed p = parse(file, defines, edit);
  samplers_ = p.samplers;
  for (const auto& m : p.members) members_.push_back({m.name, m.type, m.offset});
  push_.assign(p.push_bytes, 0);
  const std::vector<std::uint32_t> code = compile_compute(p.text, file, "bloomref's " + file);
  std::vector<VkDescriptorType> types = {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                         VK_DESCRIPTOR_TYPE_STORAGE_IMAGE};
  for (std::size_t i = 0; i < samplers_.size(); ++i)
    types.push_back(VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER);
  pipeline_ = std::make_unique<ComputePipeline>(ctx, code.data(), code.size() * 4, types,
                                                std::uint32_t(push_.size()));
}

const StageProgram::Member& StageProgram::member(const std::string& name) const {
  for (const Member& m : members_)
    if (m.name == name) return m;
  throw VulkanError("bloomref's " + file_ + " has no uniform '" + name + "'");
}

void StageProgram::set(const std::string& name, float v) {
  const Member& m = member(name);
  if (m.type != "float") return set_int(name, int(v));
  std::memcpy(push_.data() + m.offset, &v, 4);
}

void StageProgram::set_int(const std::string& name, int v) {
  const Member& m = member(name);
  const std::int32_t i = v;
  std::memcpy(push_.data() + m.offset, &i, 4);
}

double StageProgram::run(const std::vector<const Image2D*>& inputs, const Image2D& out0,
                         const Image2D* out1, VkSampler sampler) {
  if (inputs.size() != samplers_.size())
    throw VulkanError("bloomref's " + file_ + " reads " + std::to_string(samplers_.size()) +
                      " images, given " + std::to_string(inputs.size()));
  pipeline_->bind_image(0, out0.view());
  pipeline_->bind_image(1, (out1 ? out1 : &out0)->view());
  for (std::size_t i = 0; i < inputs.size(); ++i)
    pipeline_->bind_image(std::uint32_t(i + 2), inputs[i]->view(), sampler);
  return timed_dispatch(ctx_, *pipeline_, push_.data(), out0.width, out0.height);
}

}  // namespace bloomref::vulkan
