// The GL path's stage shaders and compute entry point (gpu/shaders), embedded at configure time
// (vulkan/CMakeLists.txt) for the Vulkan stage programs.
#pragma once

#include <map>
#include <string>

namespace bloomref::vulkan {
/// Shader file name -> text.
const std::map<std::string, std::string>& vulkan_shader_sources();
}  // namespace bloomref::vulkan
