#pragma once

#include <map>
#include <string>

namespace bloomref::gpu {
/// Shader file name -> source text, embedded from gpu/shaders at build time.
const std::map<std::string, std::string>& shader_sources();
}  // namespace bloomref::gpu
