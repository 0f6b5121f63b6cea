#include "reflect.h"

#include <spirv_cross/spirv_cross_c.h>

#include <memory>

#include "bloomref/error.h"

namespace bloomref::vulkan {
namespace {

struct Owner {
  spvc_context ctx = nullptr;
  ~Owner() {
    if (ctx) spvc_context_destroy(ctx);
  }
};

std::string format_name(SpvImageFormat f) {
  switch (f) {
    case SpvImageFormatRgba32f: return "rgba32f";
    case SpvImageFormatRgba16f: return "rgba16f";
    case SpvImageFormatR11fG11fB10f: return "r11f_g11f_b10f";
    case SpvImageFormatRgba8: return "rgba8";
    case SpvImageFormatUnknown: return "";
    default: return "format " + std::to_string(int(f));
  }
}

class Reflector {
 public:
  Reflector(const std::vector<std::uint32_t>& spirv, const std::string& file) : file_(file) {
    if (spvc_context_create(&own_.ctx) != SPVC_SUCCESS) throw Error("SPIRV-Cross: no context");
    spvc_parsed_ir ir = nullptr;
    if (spvc_context_parse_spirv(own_.ctx, spirv.data(), spirv.size(), &ir) != SPVC_SUCCESS ||
        spvc_context_create_compiler(own_.ctx, SPVC_BACKEND_NONE, ir,
                                     SPVC_CAPTURE_MODE_TAKE_OWNERSHIP, &comp_) != SPVC_SUCCESS)
      throw ParamError(file + ": is not SPIR-V SPIRV-Cross can read: " +
                       spvc_context_get_last_error_string(own_.ctx));
  }

  Reflection run() {
    Reflection r;
    for (int i = 0; i < 3; ++i)
      r.local_size[i] = spvc_compiler_get_execution_mode_argument_by_index(
          comp_, SpvExecutionModeLocalSize, unsigned(i));
    spvc_resources res = nullptr;
    if (spvc_compiler_create_shader_resources(comp_, &res) != SPVC_SUCCESS)
      throw ParamError(file_ + ": its resources cannot be reflected");
    using K = ReflectedBinding::Kind;
    const std::pair<spvc_resource_type, K> kinds[] = {
        {SPVC_RESOURCE_TYPE_SAMPLED_IMAGE, K::sampled_image},
        {SPVC_RESOURCE_TYPE_STORAGE_IMAGE, K::storage_image},
        {SPVC_RESOURCE_TYPE_SEPARATE_IMAGE, K::separate_image},
        {SPVC_RESOURCE_TYPE_SEPARATE_SAMPLERS, K::sampler},
        {SPVC_RESOURCE_TYPE_UNIFORM_BUFFER, K::uniform_buffer}};
    for (const auto& [type, kind] : kinds) {
      for (const spvc_reflected_resource& rr : list(res, type)) {
        ReflectedBinding b{kind, rr.name ? rr.name : "", 0, 0, "", {}, 0};
        b.set = spvc_compiler_get_decoration(comp_, rr.id, SpvDecorationDescriptorSet);
        b.binding = spvc_compiler_get_decoration(comp_, rr.id, SpvDecorationBinding);
        const spvc_type t = spvc_compiler_get_type_handle(comp_, rr.type_id);
        if (kind == K::storage_image) b.format = format_name(spvc_type_get_image_storage_format(t));
        if (kind == K::uniform_buffer) {
          if (b.name.empty()) b.name = spvc_compiler_get_name(comp_, rr.base_type_id);
          b.members = members(rr.base_type_id, b.name);
          std::size_t size = 0;
          spvc_compiler_get_declared_struct_size(
              comp_, spvc_compiler_get_type_handle(comp_, rr.base_type_id), &size);
          b.size = std::uint32_t(size);
        }
        r.bindings.push_back(std::move(b));
      }
    }
    for (const auto type : {SPVC_RESOURCE_TYPE_STORAGE_BUFFER, SPVC_RESOURCE_TYPE_SUBPASS_INPUT,
                            SPVC_RESOURCE_TYPE_ATOMIC_COUNTER})
      for (const spvc_reflected_resource& rr : list(res, type))
        throw ParamError(file_ + ": '" + std::string(rr.name ? rr.name : "") +
                         "' is a storage buffer, atomic counter or input attachment; bloomref "
                         "binds images, samplers, uniform buffers and push constants");
    for (const spvc_reflected_resource& rr : list(res, SPVC_RESOURCE_TYPE_PUSH_CONSTANT)) {
      r.push = members(rr.base_type_id, "the push constants");
      std::size_t size = 0;
      spvc_compiler_get_declared_struct_size(
          comp_, spvc_compiler_get_type_handle(comp_, rr.base_type_id), &size);
      r.push_bytes = std::uint32_t(size);
    }
    return r;
  }

 private:
  std::vector<spvc_reflected_resource> list(spvc_resources res, spvc_resource_type type) {
    const spvc_reflected_resource* l = nullptr;
    std::size_t n = 0;
    spvc_resources_get_resource_list_for_type(res, type, &l, &n);
    return std::vector<spvc_reflected_resource>(l, l + n);
  }

  std::vector<ReflectedMember> members(spvc_type_id struct_id, const std::string& block) {
    const spvc_type st = spvc_compiler_get_type_handle(comp_, struct_id);
    std::vector<ReflectedMember> out;
    for (unsigned i = 0; i < spvc_type_get_num_member_types(st); ++i) {
      ReflectedMember m;
      const char* name = spvc_compiler_get_member_name(comp_, struct_id, i);
      m.name = name ? name : "";
      unsigned offset = 0;
      spvc_compiler_type_struct_member_offset(comp_, st, i, &offset);
      m.offset = offset;
      const spvc_type mt = spvc_compiler_get_type_handle(comp_, spvc_type_get_member_type(st, i));
      const spvc_basetype base = spvc_type_get_basetype(mt);
      m.components = spvc_type_get_vector_size(mt);
      if (spvc_type_get_columns(mt) != 1 || spvc_type_get_num_array_dimensions(mt) != 0 ||
          m.components < 1 || m.components > 4 ||
          (base != SPVC_BASETYPE_FP32 && base != SPVC_BASETYPE_INT32 &&
           base != SPVC_BASETYPE_UINT32 && base != SPVC_BASETYPE_BOOLEAN))
        throw ParamError(file_ + ": member '" + m.name + "' of " + block +
                         " is not a 32-bit scalar or vector; bloomref sets those only");
      m.integer = base != SPVC_BASETYPE_FP32;
      const std::string prefix = base == SPVC_BASETYPE_FP32    ? ""
                                 : base == SPVC_BASETYPE_UINT32 ? "u"
                                 : base == SPVC_BASETYPE_INT32  ? "i"
                                                                : "b";
      m.type = m.components == 1 ? (base == SPVC_BASETYPE_FP32    ? "float"
                                    : base == SPVC_BASETYPE_UINT32 ? "uint"
                                    : base == SPVC_BASETYPE_INT32  ? "int"
                                                                   : "bool")
                                 : prefix + "vec" + std::to_string(m.components);
      out.push_back(m);
    }
    return out;
  }

  std::string file_;
  Owner own_;
  spvc_compiler comp_ = nullptr;
};

}  // namespace

Reflection reflect(const std::vector<std::uint32_t>& spirv, const std::string& file) {
  return Reflector(spirv, file).run();
}

std::string to_string(ReflectedBinding::Kind k) {
  switch (k) {
    case ReflectedBinding::sampled_image: return "a sampled image";
    case ReflectedBinding::storage_image: return "a storage image";
    case ReflectedBinding::separate_image: return "a texture";
    case ReflectedBinding::sampler: return "a sampler";
    case ReflectedBinding::uniform_buffer: return "a uniform buffer";
  }
  return "a binding";
}

}  // namespace bloomref::vulkan
