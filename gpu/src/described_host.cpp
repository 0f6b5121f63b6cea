// A pipeline description's passes around the user's shaders (described_pipeline.h): the
// textures made in order, each program built with the uniforms the passes set, each pass drawn
// with its inputs on texture units in order, its uniforms, its blending, and read back when it
// names a stage.
#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>

#include "bloomref/error.h"
#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/mip.h"
#include "bloomref/stages.h"
#include "user_host.h"
#include "user_program.h"

namespace bloomref::gpu {
namespace {

using host::Clock;
using host::ms_since;

struct Factor {
  const char* gl;
  const char* name;
  GLenum value;
};
constexpr Factor kFactors[] = {
    {"GL_ZERO", "zero", GL_ZERO},
    {"GL_ONE", "one", GL_ONE},
    {"GL_SRC_COLOR", "src_color", GL_SRC_COLOR},
    {"GL_ONE_MINUS_SRC_COLOR", "one_minus_src_color", GL_ONE_MINUS_SRC_COLOR},
    {"GL_DST_COLOR", "dst_color", GL_DST_COLOR},
    {"GL_ONE_MINUS_DST_COLOR", "one_minus_dst_color", GL_ONE_MINUS_DST_COLOR},
    {"GL_SRC_ALPHA", "src_alpha", GL_SRC_ALPHA},
    {"GL_ONE_MINUS_SRC_ALPHA", "one_minus_src_alpha", GL_ONE_MINUS_SRC_ALPHA},
    {"GL_DST_ALPHA", "dst_alpha", GL_DST_ALPHA},
    {"GL_ONE_MINUS_DST_ALPHA", "one_minus_dst_alpha", GL_ONE_MINUS_DST_ALPHA},
    {"GL_CONSTANT_COLOR", "constant_color", GL_CONSTANT_COLOR},
    {"GL_ONE_MINUS_CONSTANT_COLOR", "one_minus_constant_color", GL_ONE_MINUS_CONSTANT_COLOR},
};

int rounded(double v, SizeRule::Rounding r) {
  const double x = r == SizeRule::floor ? std::floor(v) : r == SizeRule::ceil ? std::ceil(v)
                                                                             : std::floor(v + 0.5);
  return std::max(1, static_cast<int>(x));
}

// The uniforms one program is given over all the passes that use it (their union), its
// samplers those the passes bind.
std::vector<HostUniform> host_uniforms(const PipelineDescription& d, const std::string& program) {
  std::vector<HostUniform> out;
  auto have = [&](const std::string& n) {
    return std::any_of(out.begin(), out.end(), [&](const HostUniform& h) { return h.name == n; });
  };
  for (const DescribedPass& p : d.passes) {
    if (p.program != program) continue;
    for (const auto& [sampler, texture] : p.inputs)
      if (!have(sampler))
        out.push_back({sampler, HostUniform::sampler, true, "a texture of the description"});
    for (const auto& [name, u] : p.uniforms) {
      if (have(name)) continue;
      HostUniform h{name, HostUniform::number, true, "set by the description"};
      switch (u.kind) {
        case DescribedUniform::integer: h.kind = HostUniform::integer; break;
        case DescribedUniform::flag: h.kind = HostUniform::flag; break;
        case DescribedUniform::number:
          if (u.values.size() > 1) h.kind = HostUniform::vector, h.components = int(u.values.size());
          break;
        case DescribedUniform::width:
        case DescribedUniform::height: break;  // a float
        default: h.kind = HostUniform::vector, h.components = 2; break;
      }
      out.push_back(h);
    }
  }
  return out;
}

class DescribedHost {
 public:
  DescribedHost(GlContext& ctx, ConstImageView scene, const PipelineDescription& d,
                const BloomParams& p)
      : ctx_(ctx), scene_(scene), d_(d), p_(p) {}

  DescribedRun run() {
    const auto t_start = Clock::now();
    build_programs();
    make_textures();
    for (std::size_t i = 0; i < d_.passes.size(); ++i) draw(i);
    out_.trace.total_ms = ms_since(t_start);
    return std::move(out_);
  }

 private:
  std::string where(std::size_t pass) const {
    return d_.file + ": pass " + std::to_string(pass + 1);
  }

  void build_programs() {
    ctx_.check("before building the user's programs");
    for (const auto& [name, prog] : d_.programs) {
      if (!prog.compute.empty())
        throw ParamError(d_.file + ": program '" + name + "' is a compute shader (" + prog.compute +
                         "); it runs on Vulkan: --backend vulkan");
      const ShaderSource fs = prog.fragment_text.empty()
                                  ? load_shader(prog.fragment)
                                  : ShaderSource{prog.fragment, prog.fragment_text};
      std::optional<ShaderSource> vs;
      if (!prog.vertex.empty()) vs = load_shader(prog.vertex);
      VertexNames names;
      names.varying = host::varying_of(fs, "TexCoords");
      programs_.emplace(name, build_user_program(name, vs ? &*vs : nullptr, fs,
                                                 host_uniforms(d_, name), names,
                                                 "pipeline description's"));
      out_.programs.push_back(programs_.at(name).interface);
    }
    ctx_.check("building the user's programs");
  }

  void make_textures() {
    const int w = scene_.width, h = scene_.height;
    const Image sanitized = sanitized_scene(scene_, p_, out_.trace.nonfinite);
    const std::vector<std::pair<int, int>> sizes = texture_sizes(d_, w, h);
    for (std::size_t i = 0; i < d_.textures.size(); ++i) {
      const DescribedTexture& t = d_.textures[i];
      const int tw = sizes[i].first, th = sizes[i].second;
      const GLenum format = host::gl_format(t.format);
      if (t.content == DescribedTexture::clear) {
        textures_.emplace(t.name, Texture(tw, th, format));
        clear(textures_.at(t.name));
      } else {
        if (tw != w || th != h)
          throw ParamError(d_.file + ": texture '" + t.name + "' holds the " +
                           (t.content == DescribedTexture::scene ? "scene" : "bright image") +
                           " and must be the scene's size");
        const Image img = texture_content(t, sanitized.cview(), p_);
        textures_.emplace(t.name, Texture(w, h, format, img.data()));
      }
      textures_.at(t.name).set_sampling(host::gl_filter(t.filter), host::gl_wrap(t.wrap));
      if (!t.stage.empty()) {
        Image img = Image::uninitialised(tw, th);
        textures_.at(t.name).read(img.data());
        out_.trace.stages.push_back({t.stage, std::move(img), 0.0, false});
      }
    }
    ctx_.check("making the description's textures");
  }

  static void clear(const Texture& t) {
    Framebuffer fb(t);
    glViewport(0, 0, t.width, t.height);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT);
  }

  void set_uniform(const UserProgram& prog, const std::string& name, const DescribedUniform& u) {
    if (u.kind == DescribedUniform::integer) return prog.set_integer(name, u.integer_value);
    if (u.kind == DescribedUniform::flag) return prog.set_flag(name, u.integer_value != 0);
    const Texture* t = u.texture.empty() ? nullptr : &textures_.at(u.texture);
    const std::vector<float> v = uniform_values(u, t ? t->width : 0, t ? t->height : 0);
    if (v.size() == 1) prog.set_number(name, v[0]);
    else prog.set_vector(name, v);
  }

  void draw(std::size_t i) {
    const DescribedPass& pass = d_.passes[i];
    const UserProgram& prog = programs_.at(pass.program);
    std::vector<const Texture*> units;
    for (std::size_t u = 0; u < pass.inputs.size(); ++u) {
      if (pass.inputs[u].second == pass.target)
        throw ParamError(where(i) + " reads '" + pass.target + "', the texture it draws into");
      units.push_back(&textures_.at(pass.inputs[u].second));
      prog.set_sampler(pass.inputs[u].first, static_cast<int>(u));
    }
    for (const auto& [name, u] : pass.uniforms) set_uniform(prog, name, u);
    const Texture& target = textures_.at(pass.target);
    if (pass.blend.enabled) {
      glEnable(GL_BLEND);
      glBlendEquation(GL_FUNC_ADD);
      glBlendFunc(blend_factor(pass.blend.src), blend_factor(pass.blend.dst));
      const float c = pass.blend.constant;
      glBlendColor(c, c, c, c);
    }
    const std::array<float, 4> black = {0.0f, 0.0f, 0.0f, 0.0f};
    const double ms = quad_.draw(ctx_, prog, units, target, nullptr, pass.clear ? &black : nullptr,
                                 where(i) + " (" + pass.program + " into " + pass.target + ")");
    glDisable(GL_BLEND);
    if (pass.stage.empty()) return;
    Image img = Image::uninitialised(target.width, target.height);
    target.read(img.data());
    out_.trace.stages.push_back({pass.stage, std::move(img), ms, false});
    out_.trace.timings.emplace_back(pass.stage, ms);
  }

  GlContext& ctx_;
  ConstImageView scene_;
  const PipelineDescription& d_;
  const BloomParams& p_;
  host::QuadState quad_;
  std::map<std::string, UserProgram> programs_;
  std::map<std::string, Texture> textures_;
  DescribedRun out_;
};

}  // namespace

Image sanitized_scene(ConstImageView scene, const BloomParams& p, NonFiniteCounts& counts) {
  Image sanitized(scene.width, scene.height);
  counts = sanitize(scene, sanitized.view(), p.nonfinite, Storage::f32, p.threads);
  if (p.nonfinite == NonFinite::error && counts.total() > 0)
    throw ParamError("the scene holds " + std::to_string(counts.total()) +
                     " NaN or infinite values, refused under --nonfinite error");
  return sanitized;
}

std::vector<float> uniform_values(const DescribedUniform& u, int width, int height) {
  const float sx = static_cast<float>(width), sy = static_cast<float>(height);
  switch (u.kind) {
    case DescribedUniform::number: return u.values;
    case DescribedUniform::integer:
    case DescribedUniform::flag: return {static_cast<float>(u.integer_value)};
    case DescribedUniform::width: return {sx};
    case DescribedUniform::height: return {sy};
    case DescribedUniform::size: return {sx, sy};
    case DescribedUniform::texel: return {1.0f / sx, 1.0f / sy};
    case DescribedUniform::halved: {
      float hx = sx, hy = sy;
      for (int k = 0; k < u.times; ++k) hx *= 0.5f, hy *= 0.5f;
      return {hx, hy};
    }
  }
  return {};
}

Image texture_content(const DescribedTexture& t, ConstImageView sanitized, const BloomParams& p) {
  Image img(sanitized.width, sanitized.height);
  if (t.content == DescribedTexture::scene)
    for (int y = 0; y < sanitized.height; ++y)
      std::copy(sanitized.row(y), sanitized.row(y) + std::size_t(sanitized.width) * kChannels,
                img.view().row(y));
  else
    extract_bright(sanitized, img.view(), p.threshold, p.threads, false, nullptr, nullptr,
                   luma_rule(p));
  store(img.view(), storage_of(t.format), HalfRounding::nearest_even_saturate, p.threads);
  return img;
}

std::vector<std::pair<int, int>> texture_sizes(const PipelineDescription& d, int w, int h) {
  std::vector<std::pair<int, int>> out;
  std::map<std::string, std::size_t> index;
  for (const DescribedTexture& t : d.textures) {
    int tw = w, th = h;
    if (t.size.of != "scene") {
      const auto it = index.find(t.size.of);
      if (it == index.end())
        throw ParamError(d.file + ": texture '" + t.name + "' takes its size from '" + t.size.of +
                         "', not declared before it");
      tw = out[it->second].first, th = out[it->second].second;
    }
    if (t.size.height > 0) {
      const float ratio = static_cast<float>(t.size.height) / static_cast<float>(th);
      tw = std::max(1, static_cast<int>(std::round(static_cast<float>(tw) * ratio)));
      th = std::max(1, static_cast<int>(std::round(static_cast<float>(th) * ratio)));
    }
    for (int k = 0; k < t.size.halvings; ++k) {
      tw = rounded(tw * 0.5, t.size.rounding);
      th = rounded(th * 0.5, t.size.rounding);
    }
    if (t.size.scale != 1.0) {
      tw = rounded(tw * t.size.scale, t.size.rounding);
      th = rounded(th * t.size.scale, t.size.rounding);
    }
    if (t.size.exact_width > 0) tw = t.size.exact_width, th = t.size.exact_height;
    index[t.name] = out.size();
    out.emplace_back(tw, th);
  }
  return out;
}

unsigned blend_factor(const std::string& name) {
  std::string known;
  for (const Factor& f : kFactors) {
    if (name == f.gl || name == f.name) return f.value;
    known += std::string(known.empty() ? "" : ", ") + f.name;
  }
  throw ParamError("blend factor '" + name + "' is not one of: " + known);
}

DescribedRun run_described(GlContext& ctx, ConstImageView scene, const PipelineDescription& d,
                           const BloomParams& params) {
  return DescribedHost(ctx, scene, d, params).run();
}

}  // namespace bloomref::gpu
