#include "user_host.h"

#include <algorithm>
#include <regex>
#include <sstream>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "shader_sources.h"

namespace bloomref::gpu::host {

std::string number(float v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

std::string varying_of(const ShaderSource& fs, const std::string& fallback) {
  static const std::regex in_vec2(
      R"((?:^|[;\s])in\s+(?:(?:highp|mediump|lowp|smooth|noperspective)\s+)*)"
      R"(vec2\s+([A-Za-z_]\w*)\s*;)");
  std::smatch m;
  return std::regex_search(fs.text, m, in_vec2) ? m[1].str() : fallback;
}

GLenum gl_format(TargetFormat f) {
  switch (f) {
    case TargetFormat::rgba16f:
      return GL_RGBA16F;
    case TargetFormat::rgb16f:
      return GL_RGB16F;
    case TargetFormat::rgba32f:
      return GL_RGBA32F;
    case TargetFormat::r11f_g11f_b10f:
      return GL_R11F_G11F_B10F;
    case TargetFormat::rgba8:
      return GL_RGBA8;
  }
  return GL_RGBA32F;
}

GLenum gl_filter(TextureFilter f) {
  return f == TextureFilter::nearest ? GL_NEAREST : GL_LINEAR;
}

GLenum gl_wrap(TextureWrap w) {
  switch (w) {
    case TextureWrap::clamp_to_edge:
      return GL_CLAMP_TO_EDGE;
    case TextureWrap::repeat:
      return GL_REPEAT;
    case TextureWrap::mirrored_repeat:
      return GL_MIRRORED_REPEAT;
    case TextureWrap::clamp_to_border:
      return GL_CLAMP_TO_BORDER;  // the default border colour: (0, 0, 0, 0)
  }
  return GL_CLAMP_TO_EDGE;
}

Image flipped_rows(ConstImageView src) {
  Image out = Image::uninitialised(src.width, src.height);
  for (int y = 0; y < src.height; ++y)
    std::copy(src.row(y), src.row(y) + std::size_t(src.width) * kChannels,
              out.view().row(src.height - 1 - y));
  return out;
}

UserProgram own_program(const char* name, const char* file, const std::vector<HostUniform>& host,
                        const std::string& preset) {
  const ShaderSource fs{std::string("bloomref's ") + file, shader_sources().at(file)};
  VertexNames names;
  names.varying = "texCoord";
  return build_user_program(name, nullptr, fs, host, names, preset);
}

GLenum storage_format(Storage s) {
  return s == Storage::r11g11b10 ? GL_R11F_G11F_B10F
         : s == Storage::rgba8   ? GL_RGBA8
         : s == Storage::f16     ? GL_RGBA16F
                                 : GL_RGBA32F;
}

void require_fits(ConstImageView scene) {
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (scene.width > max_size || scene.height > max_size)
    throw ParamError("a " + std::to_string(scene.width) + "x" + std::to_string(scene.height) +
                     " scene does not fit this GL's textures (GL_MAX_TEXTURE_SIZE " +
                     std::to_string(max_size) + ")");
}

void add_stage(StageTrace& trace, const std::string& name, const Texture& t, double ms) {
  Image img = Image::uninitialised(t.width, t.height);
  t.read(img.data());
  trace.stages.push_back({name, std::move(img), ms, false});
  trace.timings.emplace_back(name, ms);
}

Texture upload_scene(GlContext& ctx, const BloomParams& p, ConstImageView scene,
                     StageTrace& trace) {
  const auto t0 = Clock::now();
  Image sanitized(scene.width, scene.height);
  trace.nonfinite = sanitize(scene, sanitized.view(), p.nonfinite, p.storage, p.threads);
  if (p.nonfinite == NonFinite::error && trace.nonfinite.total() > 0)
    throw ParamError("the scene holds " + std::to_string(trace.nonfinite.total()) +
                     " NaN or infinite values, refused under --nonfinite error");
  store(sanitized.view(), p.storage, HalfRounding::nearest_even_saturate, p.threads);
  Texture view(scene.width, scene.height, storage_format(p.storage), sanitized.data());
  view.set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
  ctx.check("uploading the scene");
  add_stage(trace, "input", view, ms_since(t0));
  return view;
}

}  // namespace bloomref::gpu::host
