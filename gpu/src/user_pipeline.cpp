#include "bloomref/gpu/user_pipeline.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "bloomref/stages.h"
#include "gl_objects.h"
#include "user_host.h"
#include "user_program.h"

namespace bloomref::gpu {
namespace {

using host::Clock;
using host::gl_filter;
using host::gl_format;
using host::gl_wrap;
using host::flipped_rows;
using host::ms_since;
using host::QuadState;
using host::number;

template <class E>
struct Named {
  E value;
  const char* name;
  const char* gl_name;
};

constexpr Named<TargetFormat> kFormats[] = {{TargetFormat::rgba16f, "rgba16f", "GL_RGBA16F"},
                                            {TargetFormat::rgb16f, "rgb16f", "GL_RGB16F"},
                                            {TargetFormat::rgba32f, "rgba32f", "GL_RGBA32F"},
                                            {TargetFormat::r11f_g11f_b10f, "r11f_g11f_b10f",
                                             "GL_R11F_G11F_B10F"},
                                            {TargetFormat::rgba8, "rgba8", "GL_RGBA8"}};
constexpr Named<TextureFilter> kFilters[] = {{TextureFilter::linear, "linear", "GL_LINEAR"},
                                             {TextureFilter::nearest, "nearest", "GL_NEAREST"}};
constexpr Named<TextureWrap> kWraps[] = {
    {TextureWrap::clamp_to_edge, "clamp-to-edge", "GL_CLAMP_TO_EDGE"},
    {TextureWrap::repeat, "repeat", "GL_REPEAT"},
    {TextureWrap::mirrored_repeat, "mirrored-repeat", "GL_MIRRORED_REPEAT"},
    {TextureWrap::clamp_to_border, "clamp-to-border", "GL_CLAMP_TO_BORDER"}};
constexpr Named<FinalTarget> kFinalTargets[] = {{FinalTarget::same, "same", "same"},
                                                {FinalTarget::rgba8, "rgba8", "GL_RGBA8"}};
constexpr Named<RowOrder> kRows[] = {{RowOrder::same, "same", "same"},
                                     {RowOrder::flipped, "flipped", "flipped"}};

template <class E, std::size_t N>
std::string name_of(const Named<E> (&table)[N], E v) {
  for (const auto& n : table)
    if (n.value == v) return n.name;
  return "?";
}

template <class E, std::size_t N>
E parse(const Named<E> (&table)[N], const char* what, const std::string& s) {
  std::string names;
  // Case aside: the help and GL's own spelling say RGBA16F, GL_CLAMP_TO_EDGE, ...
  auto same = [](const std::string& a, const char* b) {
    return a.size() == std::strlen(b) &&
           std::equal(a.begin(), a.end(), b, [](char x, char y) {
             return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
           });
  };
  for (const auto& n : table) {
    if (same(s, n.name) || same(s, n.gl_name)) return n.value;
    names += (names.empty() ? "" : ", ") + std::string(n.name);
  }
  throw ParamError(std::string(what) + " '" + s + "' is not one of: " + names);
}

std::string numbers(const std::vector<float>& v) {
  std::string s = "(";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + number(v[i]);
  return s + ")";
}

std::string describe(const LayoutValue& v) {
  switch (v.kind) {
    case LayoutValue::texel_size:
      return "the targets' texel size (1 / width, 1 / height)";
    case LayoutValue::target_size:
      return "the targets' size (width, height)";
    case LayoutValue::texel_x:
      return "one texel along x (1 / width, 0)";
    case LayoutValue::texel_y:
      return "one texel along y (0, 1 / height)";
    case LayoutValue::numbers:
      break;
  }
  return v.values.size() == 1 ? number(v.values[0]) : numbers(v.values);
}

// A layout's further uniforms of one program, as host uniforms.
void add_set(std::vector<HostUniform>& host,
             const std::vector<std::pair<std::string, LayoutValue>>& set,
             const std::string& layout_file) {
  for (const auto& [name, value] : set)
    host.push_back({name, HostUniform::vector, true,
                    "set to " + describe(value) + ", layout " + layout_file, value.components()});
}

// What the preset's host code sets in each program (bloom.cpp's shaderBlur, shaderBloomFinal),
// under the layout's names.
std::vector<HostUniform> blur_host(const PresetLayout& l) {
  std::vector<HostUniform> host = {
      {l.blur_image, HostUniform::sampler, true,
       "texture unit 0: the bright image on pass 1, else the other ping-pong target"}};
  if (l.direction.empty())
    host.push_back({l.horizontal, HostUniform::flag, true, "true on odd passes: pass 1 is horizontal"});
  else
    host.push_back({l.direction, HostUniform::vector, true,
                    describe(l.direction_h) + " on odd (horizontal) passes, " +
                        describe(l.direction_v) + " on even ones, layout " + l.file,
                    l.direction_h.components()});
  add_set(host, l.blur_set, l.file);
  return host;
}

std::vector<HostUniform> final_host(const UserPipelineOptions& opt) {
  const PresetLayout& l = opt.layout;
  std::vector<HostUniform> host = {
      {l.final_scene, HostUniform::sampler, true, "texture unit 0: the scene"},
      {l.final_bloom, HostUniform::sampler, true, "texture unit 1: the last blur pass"},
      // Without `bloom` the shader always adds the bloom: refused only when asked off.
      {l.bloom, HostUniform::flag, !opt.bloom, opt.bloom ? "true" : "false: bloom off"},
      {l.exposure, HostUniform::number, true, "exposure = " + number(opt.exposure)}};
  add_set(host, l.final_set, l.file);
  return host;
}

std::vector<HostUniform> bright_host(const UserPipelineOptions& opt) {
  const PresetLayout& l = opt.layout;
  std::vector<HostUniform> host = {
      {l.bright_scene, HostUniform::sampler, true, "texture unit 0: the scene"},
      {l.threshold, HostUniform::number, false, "threshold = " + number(opt.threshold)}};
  add_set(host, l.bright_set, l.file);
  return host;
}

// The layout's further uniforms of one program, set for targets of w x h.
void set_values(const UserProgram& p, const std::vector<std::pair<std::string, LayoutValue>>& set,
                int w, int h) {
  for (const auto& [name, value] : set) p.set_vector(name, value.at(w, h));
}

struct Programs {
  std::optional<UserProgram> bright;
  UserProgram blur, final;
};

Programs build_programs_unchecked(GlContext& ctx, const LearnOpenGLShaders& s,
                                  const UserPipelineOptions& opt) {
  Programs p;
  const PresetLayout& l = opt.layout;
  const VertexNames names{l.position, l.texcoords, l.varying};
  if (s.bright_fs) {
    p.bright = build_user_program("bright", s.bright_vs ? &*s.bright_vs : nullptr, *s.bright_fs,
                                  bright_host(opt), names);
    p.bright->set_sampler(l.bright_scene, 0);
    p.bright->set_number(l.threshold, opt.threshold);
  } else if (s.bright_vs) {
    throw ParamError("a bright-pass vertex shader (" + s.bright_vs->path +
                     ") was given without a bright-pass fragment shader");
  }
  p.blur = build_user_program("blur", s.blur_vs ? &*s.blur_vs : nullptr, s.blur_fs, blur_host(l),
                              names);
  p.blur.set_sampler(l.blur_image, 0);
  p.final = build_user_program("final", s.final_vs ? &*s.final_vs : nullptr, s.final_fs,
                               final_host(opt), names);
  p.final.set_sampler(l.final_scene, 0);
  p.final.set_sampler(l.final_bloom, 1);
  p.final.set_flag(l.bloom, opt.bloom);
  p.final.set_number(l.exposure, opt.exposure);
  ctx.check("building the user's programs");
  return p;
}

Programs build_programs(GlContext& ctx, const LearnOpenGLShaders& s,
                        const UserPipelineOptions& opt) {
  ctx.check("before building the user's programs");
  try {
    return build_programs_unchecked(ctx, s, opt);
  } catch (const UserShaderError&) {
    // The compiler's errors also arrive as GL debug messages of type error; they are in the
    // UserShaderError already, and must not be charged to the next GL call.
    try {
      ctx.check("building the user's programs");
    } catch (const GlError&) {
    }
    throw;
  }
}

std::vector<ProgramInterface> interfaces(const Programs& p) {
  std::vector<ProgramInterface> out;
  if (p.bright) out.push_back(p.bright->interface);
  out.push_back(p.blur.interface);
  out.push_back(p.final.interface);
  return out;
}

void validate(const UserPipelineOptions& opt) {
  const PresetLayout& l = opt.layout;
  if (!l.direction.empty() &&
      (l.direction_h.components() < 1 || l.direction_h.components() > 4 ||
       l.direction_h.components() != l.direction_v.components()))
    throw ParamError("the blur direction '" + l.direction +
                     "' needs as many components (1 to 4) for both axes");
  for (const auto* set : {&l.bright_set, &l.blur_set, &l.final_set})
    for (const auto& [name, v] : *set)
      if (v.kind == LayoutValue::numbers && (v.values.empty() || v.values.size() > 4))
        throw ParamError("uniform '" + name + "' is given " + std::to_string(v.values.size()) +
                         " numbers: a float, vec2, vec3 or vec4 takes 1 to 4");
  if (opt.passes < 0 || opt.passes > 1000)
    throw ParamError("passes " + std::to_string(opt.passes) + " is not in [0, 1000]");
  if (!std::isfinite(opt.exposure)) throw ParamError("exposure must be finite");
  if (!std::isfinite(opt.threshold)) throw ParamError("threshold must be finite");
  for (float c : opt.clear_colour)
    if (!std::isfinite(c)) throw ParamError("the clear colour must be finite");
}

}  // namespace

std::string to_string(TargetFormat f) {
  return name_of(kFormats, f);
}
std::string to_string(TextureFilter f) {
  return name_of(kFilters, f);
}
std::string to_string(TextureWrap w) {
  return name_of(kWraps, w);
}
std::string to_string(RowOrder r) {
  return name_of(kRows, r);
}
TargetFormat parse_target_format(const std::string& s) {
  return parse(kFormats, "target format", s);
}
TextureFilter parse_texture_filter(const std::string& s) {
  return parse(kFilters, "filter", s);
}
TextureWrap parse_texture_wrap(const std::string& s) {
  return parse(kWraps, "wrap", s);
}
RowOrder parse_row_order(const std::string& s) {
  return parse(kRows, "row order", s);
}
std::string to_string(FinalTarget t) {
  return name_of(kFinalTargets, t);
}
FinalTarget parse_final_target(const std::string& s) {
  return parse(kFinalTargets, "final target", s);
}

Storage storage_of(TargetFormat f) {
  return f == TargetFormat::rgba32f ? Storage::f32
         : f == TargetFormat::rgba8 ? Storage::rgba8
                                    : Storage::f16;
}

TargetFormat target_format_of(Storage s) {
  switch (s) {
    case Storage::f32: return TargetFormat::rgba32f;
    case Storage::f16: return TargetFormat::rgba16f;
    case Storage::r11g11b10: return TargetFormat::r11f_g11f_b10f;
    case Storage::rgba8: return TargetFormat::rgba8;
  }
  return TargetFormat::rgba32f;
}

ShaderSource load_shader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot be read: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(path, "cannot be read");
  return {path, text.str()};
}

std::vector<float> LayoutValue::at(int w, int h) const {
  switch (kind) {
    case texel_size:
      return {1.0f / static_cast<float>(w), 1.0f / static_cast<float>(h)};
    case target_size:
      return {static_cast<float>(w), static_cast<float>(h)};
    case texel_x:
      return {1.0f / static_cast<float>(w), 0.0f};
    case texel_y:
      return {0.0f, 1.0f / static_cast<float>(h)};
    case numbers:
      break;
  }
  return values;
}

UserPipelineOptions options_for(const BloomParams& params) {
  if (params.method != Method::gaussian)
    throw ParamError(
        "the learnopengl preset runs the gaussian method (ping-pong blur passes); "
        "--method " +
        to_string(params.method) + " has no such passes");
  if (params.storage == Storage::rgba8)
    throw ParamError("--storage rgba8: the tutorial's final pass draws the composite, the tone "
                     "map and the gamma at once, so it stores none of them in 8 bits as "
                     "bloomref's stages would be; its 8-bit window is judged with "
                     "--final-target rgba8");
  UserPipelineOptions opt;
  opt.format = target_format_of(params.storage);
  opt.passes = params.passes;
  opt.first_horizontal = params.first_axis == FirstAxis::horizontal;
  opt.exposure = params.exposure;
  opt.threshold = params.threshold;
  opt.luma = luma_rule(params);
  opt.nonfinite = params.nonfinite;
  opt.threads = params.threads;
  return opt;
}

std::vector<ProgramInterface> check_learnopengl(GlContext& ctx, const LearnOpenGLShaders& shaders,
                                                const UserPipelineOptions& opt) {
  validate(opt);
  return interfaces(build_programs(ctx, shaders, opt));
}

namespace {

// The tutorial's host code (src/5.advanced_lighting/7.bloom/bloom.cpp), one method per step:
// the scene in its target, the bright pass, the ping-pong blur, the final pass. Every pass is
// read back into the trace.
class LearnOpenGLHost {
 public:
  LearnOpenGLHost(GlContext& ctx, ConstImageView scene, const LearnOpenGLShaders& shaders,
                  const UserPipelineOptions& opt)
      : ctx_(ctx), scene_(scene), opt_(opt), w_(scene.width), h_(scene.height),
        format_(gl_format(opt.format)), prog_(build_programs(ctx, shaders, opt)) {
    run_.programs = interfaces(prog_);
    run_.bright_source = shaders.bright_fs ? shaders.bright_fs->path : "oracle";
    const PresetLayout& l = opt.layout;
    if (prog_.bright) set_values(*prog_.bright, l.bright_set, w_, h_);
    set_values(prog_.blur, l.blur_set, w_, h_);
    set_values(prog_.final, l.final_set, w_, h_);
  }

  UserPipelineRun run() {
    const auto t_start = Clock::now();
    const auto t0 = Clock::now();
    upload_scene();
    const double input_ms = ms_since(t0);
    bright_pass(input_ms);
    const Texture* bloom = blur_passes();
    final_pass(*bloom);
    run_.trace.total_ms = ms_since(t_start);
    return std::move(run_);
  }

 private:
  void add(const std::string& name, Image&& img, double ms) {
    run_.trace.stages.push_back({name, std::move(img), ms, false});
    run_.trace.timings.emplace_back(name, ms);
  }

  Texture upload(const Image& img, GLenum format = 0) const {
    if (!format) format = format_;
    if (opt_.rows != RowOrder::flipped) return Texture(w_, h_, format, img.data());
    const Image f = flipped_rows(img.cview());
    return Texture(w_, h_, format, f.data());
  }

  Image read_back(const Texture& t) const {
    Image img = Image::uninitialised(w_, h_);
    t.read(img.data());
    return opt_.rows == RowOrder::flipped ? flipped_rows(img.cview()) : img;
  }

  Texture target() const {
    Texture t(w_, h_, format_);
    sample(t);
    return t;
  }

  void sample(const Texture& t) const { t.set_sampling(gl_filter(opt_.filter), gl_wrap(opt_.wrap)); }

  // The scene as the user's renderer leaves it in its target: the oracle's input stage
  // (non-finite policy, then the target's storage), which both sides then read.
  void upload_scene() {
    sanitized_ = Image(w_, h_);
    run_.trace.nonfinite =
        sanitize(scene_, sanitized_.view(), opt_.nonfinite, storage_of(opt_.format), opt_.threads);
    if (opt_.nonfinite == NonFinite::error && run_.trace.nonfinite.total() > 0)
      throw ParamError("the scene holds " + std::to_string(run_.trace.nonfinite.total()) +
                       " NaN or infinite values, refused under --nonfinite error");
    // The tutorial's MRT form computes the bright image from the colour it shades, before its
    // target stores it: that pass reads the scene unrounded (RGBA32F) and writes the stored one.
    if (prog_.bright && prog_.bright->has_output(1)) {
      scene_tex_ = upload(sanitized_, GL_RGBA32F);
    } else {
      Image input = sanitized_;
      store(input.view(), storage_of(opt_.format), opt_.half_rounding, opt_.threads);
      scene_tex_ = upload(input);
    }
    sample(scene_tex_);
    bright_tex_ = target();
    ctx_.check("uploading the scene");
  }

  // The oracle's bright image, or the user's bright pass (the tutorial's MRT form writes the
  // scene the final pass reads to location 0 and the bright image to location 1).
  void bright_pass(double input_ms) {
    double ms = 0;
    if (!prog_.bright) {
      const auto t0 = Clock::now();
      Image bright(w_, h_);
      extract_bright(sanitized_.cview(), bright.view(), opt_.threshold, opt_.threads, false,
                     nullptr, nullptr, opt_.luma);
      store(bright.view(), storage_of(opt_.format), opt_.half_rounding, opt_.threads);
      bright_tex_ = upload(bright);
      sample(bright_tex_);
      ctx_.check("uploading the oracle's bright image");
      ms = ms_since(t0);
    } else if (prog_.bright->has_output(1)) {
      Texture scene_out = target();
      ms = quad_.draw(ctx_, *prog_.bright, {&scene_tex_}, scene_out, &bright_tex_,
                      &opt_.clear_colour, "the user's bright pass");
      scene_tex_ = std::move(scene_out);
    } else {
      ms = quad_.draw(ctx_, *prog_.bright, {&scene_tex_}, bright_tex_, nullptr, &opt_.clear_colour,
                      "the user's bright pass");
    }
    add("input", read_back(scene_tex_), input_ms);
    add("bright", read_back(bright_tex_), ms);
  }

  // bloom.cpp's loop: pingpong[horizontal] is drawn from the bright image on the first
  // iteration, else from pingpong[!horizontal]; the bloom is pingpong[!horizontal] after it.
  const Texture* blur_passes() {
    ping_[0] = target();
    ping_[1] = target();
    bool horizontal = opt_.first_horizontal;
    for (int k = 1; k <= opt_.passes; ++k) {
      const Texture& src = k == 1 ? bright_tex_ : ping_[horizontal ? 0 : 1];
      const PresetLayout& l = opt_.layout;
      if (l.direction.empty()) prog_.blur.set_flag(l.horizontal, horizontal);
      else prog_.blur.set_vector(l.direction, (horizontal ? l.direction_h : l.direction_v).at(w_, h_));
      const std::string name = "blur." + std::to_string(k);
      const double ms = quad_.draw(ctx_, prog_.blur, {&src}, ping_[horizontal ? 1 : 0], nullptr,
                                   &opt_.clear_colour, ("the user's blur pass " + name).c_str());
      add(name, read_back(ping_[horizontal ? 1 : 0]), ms);
      horizontal = !horizontal;
    }
    return opt_.passes > 0 ? &ping_[horizontal ? 0 : 1] : &bright_tex_;
  }

  void final_pass(const Texture& bloom) {
    const bool unorm8 = opt_.final_target == FinalTarget::rgba8;
    Texture out(w_, h_, unorm8 ? GL_RGBA8 : format_);
    run_.output_code_bits = unorm8 ? 8 : 0;
    const double ms = quad_.draw(ctx_, prog_.final, {&scene_tex_, &bloom}, out, nullptr,
                                 &opt_.clear_colour, "the user's final pass");
    add("output", read_back(out), ms);
  }

  GlContext& ctx_;
  ConstImageView scene_;
  const UserPipelineOptions& opt_;
  int w_, h_;
  GLenum format_;
  Programs prog_;
  QuadState quad_;
  Image sanitized_;
  Texture scene_tex_, bright_tex_;
  Texture ping_[2];
  UserPipelineRun run_;
};

}  // namespace

UserPipelineRun run_learnopengl(GlContext& ctx, ConstImageView scene,
                                const LearnOpenGLShaders& shaders, const UserPipelineOptions& opt) {
  validate(opt);
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (scene.width <= 0 || scene.height <= 0 || scene.width > max_size || scene.height > max_size)
    throw ParamError("a " + std::to_string(scene.width) + "x" + std::to_string(scene.height) +
                     " scene does not fit this GL's textures (GL_MAX_TEXTURE_SIZE " +
                     std::to_string(max_size) + ")");
  return LearnOpenGLHost(ctx, scene, shaders, opt).run();
}

}  // namespace bloomref::gpu
