#include "bloomref/vulkan/described.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <sstream>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "reflect.h"
#include "stage_program.h"
#include "vk_objects.h"

namespace bloomref::vulkan {
namespace {

using gpu::DescribedBlend;
using gpu::DescribedPass;
using gpu::DescribedTexture;
using gpu::DescribedUniform;
using gpu::TargetFormat;
using Clock = std::chrono::steady_clock;

// The image format a target format is kept in: RGB16F as RGBA16F (a storage image has no
// three-channel half format; alpha is judged nowhere).
VkFormat vk_format(TargetFormat f) {
  switch (f) {
    case TargetFormat::rgba32f: return VK_FORMAT_R32G32B32A32_SFLOAT;
    case TargetFormat::rgba16f:
    case TargetFormat::rgb16f: return VK_FORMAT_R16G16B16A16_SFLOAT;
    case TargetFormat::r11f_g11f_b10f: return VK_FORMAT_B10G11R11_UFLOAT_PACK32;
    case TargetFormat::rgba8: return VK_FORMAT_R8G8B8A8_UNORM;
  }
  return VK_FORMAT_R32G32B32A32_SFLOAT;
}

const char* qualifier(VkFormat f) {
  switch (f) {
    case VK_FORMAT_R16G16B16A16_SFLOAT: return "rgba16f";
    case VK_FORMAT_B10G11R11_UFLOAT_PACK32: return "r11f_g11f_b10f";
    case VK_FORMAT_R8G8B8A8_UNORM: return "rgba8";
    default: return "rgba32f";
  }
}

const char* qualifier(TargetFormat f) { return qualifier(vk_format(f)); }

// GL's blend factor (glBlendFunc's, by either name: "one_minus_src_color" or
// "GL_ONE_MINUS_SRC_COLOR") as a GLSL vec4 of src, dst and the constant.
std::string factor(const std::string& name) {
  gpu::blend_factor(name);  // ParamError for an unknown name
  std::string key = name.rfind("GL_", 0) == 0 ? name.substr(3) : name;
  std::transform(key.begin(), key.end(), key.begin(), [](unsigned char c) { return std::tolower(c); });
  static const std::map<std::string, const char*> kTerms = {
      {"zero", "vec4(0.0)"},
      {"one", "vec4(1.0)"},
      {"src_color", "src"},
      {"one_minus_src_color", "(vec4(1.0) - src)"},
      {"dst_color", "dst"},
      {"one_minus_dst_color", "(vec4(1.0) - dst)"},
      {"src_alpha", "vec4(src.a)"},
      {"one_minus_src_alpha", "vec4(1.0 - src.a)"},
      {"dst_alpha", "vec4(dst.a)"},
      {"one_minus_dst_alpha", "vec4(1.0 - dst.a)"},
      {"constant_color", "vec4(bloomref_blend_constant)"},
      {"one_minus_constant_color", "vec4(1.0 - bloomref_blend_constant)"}};
  return kTerms.at(key);
}

struct Translated {
  std::string text;
  std::vector<std::string> samplers;    // binding 1 and on, in declaration order
  std::vector<PushMember> members;
  std::map<std::string, std::string> initial;  // member -> its initialiser
  std::uint32_t push_bytes = 0;
};

Translated translate(const std::string& source, const std::string& name, TargetFormat format,
                     const DescribedBlend& blend) {
  static const std::regex version(R"(^\s*#\s*version\b)");
  static const std::regex sampler(R"(^\s*uniform\s+(?:(?:lowp|mediump|highp)\s+)?sampler2D\s+(\w+)\s*;)");
  static const std::regex plain(
      R"(^\s*uniform\s+(?:(?:lowp|mediump|highp)\s+)?(float|int|uint|bool|vec2|vec3|vec4|ivec2)\s+(\w+)\s*(?:=\s*([^;]+))?;)");
  static const std::regex in(R"(^\s*(?:layout\s*\([^)]*\)\s*)?(?:smooth\s+|noperspective\s+)?in\s+(\w+)\s+(\w+)\s*;)");
  static const std::regex out(R"(^\s*(?:layout\s*\([^)]*\)\s*)?out\s+(\w+)\s+(\w+)\s*;)");
  static const std::regex main_fn(R"(\bvoid\s+main\s*\(\s*(void)?\s*\))");
  static const std::regex frag_coord(R"(\bgl_FragCoord\b)");
  static const std::regex number(
      R"(^\s*([-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?[fF]?|true|false)\s*$)");
  Translated t;
  std::string body;
  std::vector<std::string> varyings;
  std::string out_name, out_type;
  std::istringstream lines(source);
  std::string line;
  std::smatch m;
  while (std::getline(lines, line)) {
    if (std::regex_search(line, version)) {
      body += "\n";  // keeps the line numbers of the compiler's messages
    } else if (std::regex_search(line, m, sampler)) {
      body += "layout(binding = " + std::to_string(t.samplers.size() + 1) +
              ") uniform sampler2D " + m[1].str() + ";\n";
      t.samplers.push_back(m[1]);
    } else if (std::regex_search(line, m, plain)) {
      t.members.push_back({m[2], m[1]});
      if (m[3].matched) {
        if (!std::regex_match(m[3].str(), number))
          throw ParamError(name + ": uniform '" + m[2].str() + "' has an initialiser (" + m[3].str() +
                           ") that is not a number; a compute shader's push constant has none");
        const std::string v = m[3];
        t.initial[m[2]] = v.find("true") != std::string::npos    ? "1"
                          : v.find("false") != std::string::npos ? "0"
                                                                 : v;
      }
      body += "\n";
    } else if (std::regex_search(line, m, in)) {
      if (m[1] != "vec2")
        throw ParamError(name + ": input '" + m[2].str() + "' is a " + m[1].str() +
                         "; bloomref's pass-through vertex shader gives one vec2, the texture "
                         "coordinate");
      varyings.push_back(m[2]);
      body += m[1].str() + " " + m[2].str() + ";\n";
    } else if (std::regex_search(line, m, out)) {
      if (!out_name.empty())
        throw ParamError(name + ": more than one output ('" + out_name + "', '" + m[2].str() +
                         "'); a pass draws into one target");
      out_name = m[2], out_type = m[1];
      body += m[1].str() + " " + m[2].str() + ";\n";
    } else {
      line = std::regex_replace(line, main_fn, "void bloomref_fragment_main()");
      body += std::regex_replace(line, frag_coord, "bloomref_FragCoord") + "\n";
    }
  }
  if (out_name.empty()) throw ParamError(name + ": the shader has no output");
  if (blend.enabled) t.members.push_back({"bloomref_blend_constant", "float"});
  const std::string block = t.members.empty() ? "" : push_constant_block(t.members, t.push_bytes);
  const std::string result = out_type == "vec4" ? out_name
                             : out_type == "vec3" ? "vec4(" + out_name + ", 1.0)"
                             : out_type == "vec2" ? "vec4(" + out_name + ", 0.0, 1.0)"
                                                  : "vec4(" + out_name + ", 0.0, 0.0, 1.0)";
  std::string run = "  bloomref_FragCoord = vec4(vec2(texel) + 0.5, 0.5, 1.0);\n";
  for (const std::string& v : varyings) run += "  " + v + " = (vec2(texel) + 0.5) / vec2(size);\n";
  run += "  bloomref_fragment_main();\n  vec4 src = " + result + ";\n";
  if (blend.enabled) {
    // GL's blending (glBlendEquation(GL_FUNC_ADD)): a factor of one multiplies nothing and a
    // factor of zero drops its term, as the fixed-function blender does.
    auto term = [](const std::string& f, const char* v) -> std::string {
      if (f == "vec4(0.0)") return "";
      return f == "vec4(1.0)" ? v : std::string(v) + " * " + f;
    };
    const std::string s = term(factor(blend.src), "src"), d = term(factor(blend.dst), "dst");
    run += "  vec4 dst = imageLoad(bloomref_target, texel);\n";
    run += "  src = " + (s.empty() && d.empty() ? std::string("vec4(0.0)")
                         : s.empty()            ? d
                         : d.empty()            ? s
                                                : s + " + " + d) + ";\n";
  }
  t.text = "#version 450\n" + block + "vec4 bloomref_FragCoord;\n" + body +
           "layout(local_size_x = 8, local_size_y = 8) in;\n"
           "layout(" + std::string(qualifier(format)) + ", binding = 0) uniform image2D bloomref_target;\n"
           "void main() {\n"
           "  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);\n"
           "  ivec2 size = imageSize(bloomref_target);\n"
           "  if (any(greaterThanEqual(texel, size))) return;\n" + run +
           "  imageStore(bloomref_target, texel, src);\n}\n";
  return t;
}

// One fragment program compiled for one target format and blending.
struct Program {
  Translated t;
  std::unique_ptr<ComputePipeline> pipeline;
};

class DescribedRunner {
 public:
  DescribedRunner(Context& ctx, ConstImageView scene, const gpu::PipelineDescription& d,
                  const BloomParams& p)
      : ctx_(ctx.impl()), scene_(scene), d_(d), p_(p) {}

  StageTrace run() {
    const auto t_start = Clock::now();
    make_textures();
    for (std::size_t i = 0; i < d_.passes.size(); ++i) draw(i);
    trace_.total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t_start).count();
    return std::move(trace_);
  }

 private:
  struct Texture {
    std::unique_ptr<Image2D> image;
    std::unique_ptr<Sampler> sampler;
  };

  std::string where(std::size_t pass) const {
    return d_.file + ": pass " + std::to_string(pass + 1);
  }

  std::unique_ptr<Image2D> image(int w, int h, VkFormat f) {
    VkFormatProperties props{};
    vkGetPhysicalDeviceFormatProperties(ctx_.physical, f, &props);
    const VkFormatFeatureFlags need =
        VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT;
    if ((props.optimalTilingFeatures & need) != need)
      throw VulkanError(std::string("this Vulkan device cannot store and sample ") + qualifier(f) +
                        " images in a compute shader");
    return std::make_unique<Image2D>(ctx_, w, h, f,
                                     VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_STORAGE_BIT);
  }

  // Copies one image into another of the same size texel by texel through a compute shader:
  // the device converts between formats as its stores and loads do.
  void convert(const Image2D& from, const Image2D& to) {
    const std::string key = std::string(qualifier(from.format)) + ">" + qualifier(to.format);
    auto it = converters_.find(key);
    if (it == converters_.end()) {
      const std::string text =
          std::string("#version 450\nlayout(local_size_x = 8, local_size_y = 8) in;\n") +
          "layout(" + qualifier(to.format) + ", binding = 0) uniform writeonly image2D dst;\n" +
          "layout(" + qualifier(from.format) + ", binding = 1) uniform readonly image2D src;\n" +
          "void main() {\n  ivec2 t = ivec2(gl_GlobalInvocationID.xy);\n"
          "  if (any(greaterThanEqual(t, imageSize(dst)))) return;\n"
          "  imageStore(dst, t, imageLoad(src, t));\n}\n";
      const std::vector<std::uint32_t> code = compile_compute(text, "convert.comp", "bloomref's format copy");
      it = converters_
               .emplace(key, std::make_unique<ComputePipeline>(
                                 ctx_, code.data(), code.size() * 4,
                                 std::vector<VkDescriptorType>{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                                               VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
                                 0))
               .first;
    }
    it->second->bind_image(0, to.view());
    it->second->bind_image(1, from.view());
    timed_dispatch(ctx_, *it->second, nullptr, to.width, to.height);
  }

  Image read(Image2D& img) {
    Image out = Image::uninitialised(img.width, img.height);
    std::vector<unsigned char> bytes;
    if (img.format == VK_FORMAT_R32G32B32A32_SFLOAT) {
      bytes = img.download();
    } else {
      Image2D wide(ctx_, img.width, img.height, VK_FORMAT_R32G32B32A32_SFLOAT,
                   VK_IMAGE_USAGE_STORAGE_BIT);
      convert(img, wide);
      bytes = wide.download();
    }
    std::memcpy(out.data(), bytes.data(), bytes.size());
    return out;
  }

  void upload(Image2D& img, const Image& content) {
    if (img.format == VK_FORMAT_R32G32B32A32_SFLOAT) return img.upload(content.data());
    Image2D wide(ctx_, img.width, img.height, VK_FORMAT_R32G32B32A32_SFLOAT,
                 VK_IMAGE_USAGE_STORAGE_BIT);
    wide.upload(content.data());
    convert(wide, img);
  }

  void make_textures() {
    const int w = scene_.width, h = scene_.height;
    const Image sanitized = gpu::sanitized_scene(scene_, p_, trace_.nonfinite);
    const std::vector<std::pair<int, int>> sizes = gpu::texture_sizes(d_, w, h);
    for (std::size_t i = 0; i < d_.textures.size(); ++i) {
      const DescribedTexture& t = d_.textures[i];
      const auto [tw, th] = sizes[i];
      Texture tex;
      tex.image = image(tw, th, vk_format(t.format));
      const VkSamplerAddressMode mode =
          t.wrap == gpu::TextureWrap::repeat            ? VK_SAMPLER_ADDRESS_MODE_REPEAT
          : t.wrap == gpu::TextureWrap::mirrored_repeat ? VK_SAMPLER_ADDRESS_MODE_MIRRORED_REPEAT
          : t.wrap == gpu::TextureWrap::clamp_to_border ? VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER
                                                        : VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
      tex.sampler = std::make_unique<Sampler>(
          ctx_, t.filter == gpu::TextureFilter::nearest ? VK_FILTER_NEAREST : VK_FILTER_LINEAR, mode);
      if (t.content == DescribedTexture::clear) {
        clear(*tex.image);
      } else {
        if (tw != w || th != h)
          throw ParamError(d_.file + ": texture '" + t.name + "' holds the " +
                           (t.content == DescribedTexture::scene ? "scene" : "bright image") +
                           " and must be the scene's size");
        upload(*tex.image, gpu::texture_content(t, sanitized.cview(), p_));
      }
      if (!t.stage.empty()) trace_.stages.push_back({t.stage, read(*tex.image), 0.0, false});
      textures_.emplace(t.name, std::move(tex));
    }
  }

  const Texture& black() {
    if (!black_.image) {
      black_.image = image(1, 1, VK_FORMAT_R32G32B32A32_SFLOAT);
      black_.sampler = std::make_unique<Sampler>(ctx_, VK_FILTER_LINEAR, false);
      const float texel[4] = {0.0f, 0.0f, 0.0f, 1.0f};
      black_.image->upload(texel);
    }
    return black_;
  }

  void clear(const Image2D& img) {
    ctx_.submit([&](VkCommandBuffer cb) {
      const VkClearColorValue black{};
      const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
      vkCmdClearColorImage(cb, img.handle(), VK_IMAGE_LAYOUT_GENERAL, &black, 1, &all);
    });
  }

  Program& program(const DescribedPass& pass, TargetFormat format) {
    const std::string key = pass.program + "|" + qualifier(format) + "|" +
                            (pass.blend.enabled ? pass.blend.src + "," + pass.blend.dst : "");
    auto it = programs_.find(key);
    if (it != programs_.end()) return it->second;
    const gpu::DescribedProgram& prog = d_.programs.at(pass.program);
    if (!prog.vertex.empty())
      throw ParamError(d_.file + ": program '" + pass.program + "' has its own vertex shader (" +
                       prog.vertex + "); the Vulkan path runs each pass as a compute shader "
                       "over its target, with bloomref's pass-through texture coordinates");
    const gpu::ShaderSource fs = prog.fragment_text.empty()
                                     ? gpu::load_shader(prog.fragment)
                                     : gpu::ShaderSource{prog.fragment, prog.fragment_text};
    Program p;
    p.t = translate(fs.text, fs.path, format, pass.blend);
    std::vector<std::uint32_t> code;
    try {
      code = compile_compute(p.t.text, fs.path, fs.path);
    } catch (const VulkanError& e) {
      throw gpu::UserShaderError(fs.path, e.what());
    }
    std::vector<VkDescriptorType> types = {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE};
    types.insert(types.end(), p.t.samplers.size(), VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER);
    p.pipeline = std::make_unique<ComputePipeline>(ctx_, code.data(), code.size() * 4, types,
                                                   p.t.push_bytes);
    return programs_.emplace(key, std::move(p)).first->second;
  }

  // The push constants of one pass: each member's initialiser, then what the pass sets.
  std::vector<unsigned char> constants(std::size_t i, const DescribedPass& pass, const Program& prog) {
    std::vector<unsigned char> push(prog.t.push_bytes, 0);
    auto put = [&](const PushMember& m, const std::vector<float>& v) {
      const bool ints = m.type == "int" || m.type == "uint" || m.type == "bool" || m.type == "ivec2";
      for (std::size_t c = 0; c < v.size(); ++c) {
        if (ints) {
          const std::int32_t x = static_cast<std::int32_t>(v[c]);
          std::memcpy(push.data() + m.offset + 4 * c, &x, 4);
        } else {
          std::memcpy(push.data() + m.offset + 4 * c, &v[c], 4);
        }
      }
    };
    auto components = [](const std::string& type) -> std::size_t {
      return type == "vec4" ? 4 : type == "vec3" ? 3 : type == "vec2" || type == "ivec2" ? 2 : 1;
    };
    for (const PushMember& m : prog.t.members) {
      if (m.name == "bloomref_blend_constant") {
        put(m, {pass.blend.constant});
        continue;
      }
      const auto set = pass.uniforms.find(m.name);
      std::vector<float> v;
      if (set != pass.uniforms.end()) {
        v = values(set->second);
      } else if (const auto init = prog.t.initial.find(m.name); init != prog.t.initial.end()) {
        v = {std::stof(init->second)};
      } else {
        throw ParamError(where(i) + " does not set uniform '" + m.name + "' of " +
                         d_.programs.at(pass.program).fragment + ", which has no initialiser");
      }
      if (v.size() != components(m.type))
        throw ParamError(where(i) + " sets uniform '" + m.name + "' (a " + m.type + ") with " +
                         std::to_string(v.size()) + " value(s)");
      put(m, v);
    }
    return push;
  }

  std::vector<float> values(const DescribedUniform& u) const {
    const Image2D* t = u.texture.empty() ? nullptr : textures_.at(u.texture).image.get();
    return gpu::uniform_values(u, t ? t->width : 0, t ? t->height : 0);
  }

  void draw(std::size_t i) {
    if (!d_.programs.at(d_.passes[i].program).compute.empty()) return draw_compute(i);
    const auto t0 = Clock::now();
    const DescribedPass& pass = d_.passes[i];
    const auto target_it = textures_.find(pass.target);
    if (target_it == textures_.end())
      throw ParamError(where(i) + " draws into '" + pass.target + "', not a texture of it");
    Image2D& target = *target_it->second.image;
    const DescribedTexture* decl = nullptr;
    for (const DescribedTexture& t : d_.textures)
      if (t.name == pass.target) decl = &t;
    Program& prog = program(pass, decl->format);
    for (const auto& [sampler, texture] : pass.inputs)
      if (texture == pass.target)
        throw ParamError(where(i) + " reads '" + pass.target + "', the texture it draws into");
    // GL's samplers: a sampler the pass binds reads its input's texture unit; one it does not
    // keeps the unit an earlier pass of the program gave it (0 at first) and reads what this
    // pass bound there, or an incomplete texture (black) where it bound nothing.
    std::map<std::string, std::size_t>& units = units_[pass.program];
    for (std::size_t u = 0; u < pass.inputs.size(); ++u) units[pass.inputs[u].first] = u;
    for (std::size_t s = 0; s < prog.t.samplers.size(); ++s) {
      const std::size_t unit = units.count(prog.t.samplers[s]) ? units.at(prog.t.samplers[s]) : 0;
      const Texture& tex = unit < pass.inputs.size() ? textures_.at(pass.inputs[unit].second) : black();
      prog.pipeline->bind_image(std::uint32_t(s + 1), tex.image->view(), tex.sampler->handle());
    }
    prog.pipeline->bind_image(0, target.view());
    const std::vector<unsigned char> push = constants(i, pass, prog);
    if (pass.clear) clear(target);
    const double device_ms =
        timed_dispatch(ctx_, *prog.pipeline, push.data(), target.width, target.height);
    finish(pass, target, t0, device_ms);
  }

  // Counts a pass's time and reads its target back when it names a stage.
  void finish(const DescribedPass& pass, Image2D& target, Clock::time_point t0, double device_ms) {
    // A pass that names no stage (URP's horizontal pass) counts toward the next that does.
    pending_ms_ += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    pending_device_ms_ = device_ms < 0 || pending_device_ms_ < 0 ? -1 : pending_device_ms_ + device_ms;
    if (pass.stage.empty()) return;
    trace_.stages.push_back({pass.stage, read(target), pending_ms_, false});
    trace_.timings.emplace_back(pass.stage, pending_ms_);
    if (pending_device_ms_ >= 0) trace_.device_timings.emplace_back(pass.stage, pending_device_ms_);
    pending_ms_ = pending_device_ms_ = 0;
  }

  // A user's compute shader: compiled (GLSL, HLSL) or read (SPIR-V), reflected, and its
  // pipeline made with the bindings it declares.
  struct ComputeProgram {
    std::string file;
    Reflection r;
    std::unique_ptr<ComputePipeline> pipeline;
    std::map<std::uint32_t, std::unique_ptr<Buffer>> buffers;  // its uniform buffers
  };

  ComputeProgram& compute_program(const std::string& name) {
    auto it = compute_.find(name);
    if (it != compute_.end()) return it->second;
    const gpu::DescribedProgram& prog = d_.programs.at(name);
    ComputeProgram cp;
    cp.file = prog.compute;
    std::string ext = std::filesystem::path(cp.file).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    std::vector<std::uint32_t> code;
    if (ext == ".spv") {
      std::ifstream in(cp.file, std::ios::binary);
      if (!in) throw InputError(cp.file, "cannot be read");
      const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (bytes.size() < 20 || bytes.size() % 4 != 0)
        throw InputError(cp.file, "is not SPIR-V: " + std::to_string(bytes.size()) +
                                      " bytes, not a whole number of 32-bit words with a header");
      code.resize(bytes.size() / 4);
      std::memcpy(code.data(), bytes.data(), bytes.size());
      if (code[0] != 0x07230203u) throw InputError(cp.file, "is not SPIR-V (no magic number)");
    } else {
      const gpu::ShaderSource src = gpu::load_shader(cp.file);
      try {
        code = compile_compute(src.text, cp.file, cp.file, ext == ".hlsl", prog.entry);
      } catch (const VulkanError& e) {
        throw gpu::UserShaderError(cp.file, e.what());
      }
    }
    cp.r = reflect(code, cp.file);  // ParamError naming the file
    std::vector<std::pair<std::uint32_t, VkDescriptorType>> types;
    for (const ReflectedBinding& b : cp.r.bindings) {
      if (b.set != 0)
        throw InputError(cp.file, "'" + b.name + "' is in descriptor set " + std::to_string(b.set) +
                                      "; bloomref binds set 0 only");
      using K = ReflectedBinding::Kind;
      types.emplace_back(b.binding, b.kind == K::sampled_image    ? VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER
                                    : b.kind == K::storage_image  ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                    : b.kind == K::separate_image ? VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE
                                    : b.kind == K::sampler        ? VK_DESCRIPTOR_TYPE_SAMPLER
                                                                  : VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
      if (b.kind == K::uniform_buffer)
        cp.buffers[b.binding] = std::make_unique<Buffer>(ctx_, std::max<std::uint32_t>(b.size, 16),
                                                         VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
    }
    if (cp.r.local_size[2] != 1)
      throw InputError(cp.file, "has a work group " + std::to_string(cp.r.local_size[2]) +
                                    " deep; bloomref dispatches 2-D groups over a texture");
    cp.pipeline = std::make_unique<ComputePipeline>(ctx_, code.data(), code.size() * 4, types,
                                                    cp.r.push_bytes, prog.entry);
    return compute_.emplace(name, std::move(cp)).first->second;
  }

  std::string bindings_of(const ComputeProgram& cp) const {
    std::string out;
    for (const ReflectedBinding& b : cp.r.bindings)
      out += (out.empty() ? "" : ", ") + b.name + " (binding " + std::to_string(b.binding) + ", " +
             to_string(b.kind) + ")";
    return out.empty() ? "none" : out;
  }

  // Writes the pass's uniforms into a block's members; each member must be set, and `used`
  // collects the names set.
  void fill(std::size_t i, const DescribedPass& pass, const ComputeProgram& cp,
            const std::vector<ReflectedMember>& members, const std::string& block,
            unsigned char* data, std::set<std::string>& used) {
    for (const ReflectedMember& m : members) {
      const auto u = pass.uniforms.find(m.name);
      if (u == pass.uniforms.end())
        throw ParamError(where(i) + " does not set '" + m.name + "' (" + m.type + ") of " +
                         block + " of " + cp.file);
      const std::vector<float> v = values(u->second);
      if (v.size() != m.components)
        throw ParamError(where(i) + " sets '" + m.name + "' (a " + m.type + " of " + cp.file +
                         ") with " + std::to_string(v.size()) + " value(s)");
      for (std::size_t c = 0; c < v.size(); ++c) {
        if (m.integer) {
          const std::int32_t x = static_cast<std::int32_t>(v[c]);
          std::memcpy(data + m.offset + 4 * c, &x, 4);
        } else {
          std::memcpy(data + m.offset + 4 * c, &v[c], 4);
        }
      }
      used.insert(m.name);
    }
  }

  void draw_compute(std::size_t i) {
    const auto t0 = Clock::now();
    const DescribedPass& pass = d_.passes[i];
    ComputeProgram& cp = compute_program(pass.program);
    using K = ReflectedBinding::Kind;
    auto matches = [](const ReflectedBinding& b, const std::string& key) {
      return key == b.name || key == std::to_string(b.binding);
    };
    auto find = [&](const std::vector<std::pair<std::string, std::string>>& entries,
                    const ReflectedBinding& b) -> const std::string* {
      for (const auto& [key, texture] : entries)
        if (matches(b, key)) return &texture;
      return nullptr;
    };
    // Every entry of the pass names a binding of its kind.
    for (const auto& [key, texture] : pass.inputs)
      if (std::none_of(cp.r.bindings.begin(), cp.r.bindings.end(), [&](const ReflectedBinding& b) {
            return b.kind != K::storage_image && b.kind != K::uniform_buffer && matches(b, key);
          }))
        throw ParamError(where(i) + " reads '" + texture + "' through '" + key + "', which is not a "
                         "sampled image, texture or sampler of " + cp.file + " (its bindings: " +
                         bindings_of(cp) + ")");
    for (const auto& [key, texture] : pass.images)
      if (std::none_of(cp.r.bindings.begin(), cp.r.bindings.end(), [&](const ReflectedBinding& b) {
            return b.kind == K::storage_image && matches(b, key);
          }))
        throw ParamError(where(i) + " binds '" + texture + "' to '" + key + "', which is not a "
                         "storage image of " + cp.file + " (its bindings: " + bindings_of(cp) + ")");
    std::set<std::string> used;
    for (const ReflectedBinding& b : cp.r.bindings) {
      const std::string what = "'" + b.name + "' (binding " + std::to_string(b.binding) + ", " +
                               to_string(b.kind) + ") of " + cp.file;
      if (b.kind == K::uniform_buffer) {
        Buffer& buf = *cp.buffers.at(b.binding);
        std::memset(buf.data(), 0, buf.size());
        fill(i, pass, cp, b.members, "uniform buffer '" + b.name + "'",
             static_cast<unsigned char*>(buf.data()), used);
        cp.pipeline->bind_buffer(b.binding, buf.handle(), buf.size());
        continue;
      }
      const std::string* texture = find(b.kind == K::storage_image ? pass.images : pass.inputs, b);
      if (!texture)
        throw ParamError(where(i) + " gives " + what + " no texture (" +
                         (b.kind == K::storage_image ? "\"images\"" : "\"inputs\"") + ")");
      const Texture& tex = textures_.at(*texture);
      if (b.kind == K::storage_image) {
        const std::string have = qualifier(tex.image->format);
        if (!b.format.empty() && b.format != have)
          throw ParamError(where(i) + " binds '" + *texture + "' (" + have + ") to " + what +
                           ", declared " + b.format);
        cp.pipeline->bind_image(b.binding, tex.image->view());
      } else if (b.kind == K::sampler) {
        cp.pipeline->bind_image(b.binding, VK_NULL_HANDLE, tex.sampler->handle());
      } else {
        cp.pipeline->bind_image(b.binding, tex.image->view(), tex.sampler->handle());
      }
    }
    std::vector<unsigned char> push(cp.r.push_bytes, 0);
    fill(i, pass, cp, cp.r.push, "the push constants", push.data(), used);
    for (const auto& [name, u] : pass.uniforms)
      if (!used.count(name))
        throw ParamError(where(i) + " sets '" + name + "', which is not a push constant or "
                         "uniform-buffer member of " + cp.file);
    Image2D& target = *textures_.at(pass.target).image;
    std::uint32_t gx = std::uint32_t(pass.groups_x), gy = std::uint32_t(pass.groups_y);
    if (gx == 0) {
      const Image2D& over = *textures_.at(pass.dispatch_over.empty() ? pass.target : pass.dispatch_over).image;
      gx = (std::uint32_t(over.width) + cp.r.local_size[0] - 1) / cp.r.local_size[0];
      gy = (std::uint32_t(over.height) + cp.r.local_size[1] - 1) / cp.r.local_size[1];
    }
    if (pass.clear) clear(target);
    const double device_ms =
        timed_dispatch_groups(ctx_, *cp.pipeline, push.empty() ? nullptr : push.data(), gx, gy);
    finish(pass, target, t0, device_ms);
  }

  Context::Impl& ctx_;
  ConstImageView scene_;
  const gpu::PipelineDescription& d_;
  const BloomParams& p_;
  std::map<std::string, Texture> textures_;
  Texture black_;
  std::map<std::string, std::map<std::string, std::size_t>> units_;  // program -> sampler -> unit
  std::map<std::string, Program> programs_;
  std::map<std::string, ComputeProgram> compute_;
  std::map<std::string, std::unique_ptr<ComputePipeline>> converters_;
  StageTrace trace_;
  double pending_ms_ = 0, pending_device_ms_ = 0;
};

}  // namespace

std::string fragment_as_compute(const std::string& source, const std::string& name,
                                TargetFormat target_format, const DescribedBlend& blend) {
  return translate(source, name, target_format, blend).text;
}

StageTrace run_described(Context& ctx, ConstImageView scene, const gpu::PipelineDescription& d,
                         const BloomParams& params) {
  if (params.precision != Precision::f32)
    throw ParamError("--precision f64 is the CPU truth; the Vulkan path computes in f32");
  return DescribedRunner(ctx, scene, d, params).run();
}

}  // namespace bloomref::vulkan
