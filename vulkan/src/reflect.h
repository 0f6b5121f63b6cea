// What a compute shader's SPIR-V declares (SPIRV-Cross's reflection, Debian's
// libspirv-cross-c-shared-dev): its work-group size, its descriptor bindings with their names
// and kinds, and the members of its push-constant block and uniform buffers with their offsets.
// Users' compute shaders are bound by it (described.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace bloomref::vulkan {

/// A member of a push-constant block or uniform buffer: its name, its GLSL type (float, int,
/// uint, bool, vec2..vec4, ivec2..ivec4, uvec2..uvec4) and byte offset in the block.
struct ReflectedMember {
  std::string name, type;
  std::uint32_t offset = 0;
  bool integer = false;     ///< int, uint or bool components
  std::uint32_t components = 1;
};

struct ReflectedBinding {
  enum Kind { sampled_image, storage_image, separate_image, sampler, uniform_buffer } kind;
  std::string name;  ///< the variable's name (a uniform buffer: its block's instance or type name)
  std::uint32_t set = 0, binding = 0;
  std::string format;  ///< a storage image's declared format (rgba16f, ...), empty when unknown
  std::vector<ReflectedMember> members;  ///< a uniform buffer's
  std::uint32_t size = 0;                ///< a uniform buffer's declared size in bytes
};

struct Reflection {
  std::uint32_t local_size[3] = {1, 1, 1};
  std::vector<ReflectedBinding> bindings;
  std::vector<ReflectedMember> push;  ///< the push-constant block's members
  std::uint32_t push_bytes = 0;
};

/// Reflects `spirv`; throws ParamError naming `file` for what bloomref cannot bind (a storage
/// buffer, a matrix or array member, an input attachment).
Reflection reflect(const std::vector<std::uint32_t>& spirv, const std::string& file);

/// A kind as a user reads it ("a sampled image", "a storage image", ...).
std::string to_string(ReflectedBinding::Kind k);

}  // namespace bloomref::vulkan
