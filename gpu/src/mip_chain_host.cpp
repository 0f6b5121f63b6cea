// Preset learnopengl-pbb: the guest article's host code (physically_based_bloom.cpp,
// bloomFBO::Init, BloomRenderer::RenderDownsamples / RenderUpsamples, the final pass) around
// the user's unmodified shaders (user_pipeline.h says what it binds and sets).
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/mip.h"
#include "bloomref/stages.h"
#include "shader_sources.h"
#include "user_host.h"
#include "user_program.h"

namespace bloomref::gpu {
namespace {

using host::Clock;
using host::ms_since;
using host::number;
using host::varying_of;

struct Programs {
  UserProgram down, up, final;
};

std::vector<HostUniform> final_host(const MipChainOptions& opt) {
  std::vector<HostUniform> host = {{"scene", HostUniform::sampler, true, "texture unit 0: the scene"},
             {"bloomBlur", HostUniform::sampler, true, "texture unit 1: mip 0 after the upsamples"},
             {"exposure", HostUniform::number, true, "exposure = " + number(opt.exposure)},
             {"programChoice", HostUniform::integer, false,
              "programChoice = " + std::to_string(opt.program_choice)}};
  if (!std::isnan(opt.strength))
    host.push_back({"bloomStrength", HostUniform::number, false,
                    "bloomStrength = " + number(opt.strength)});
  return host;
}

Programs build(GlContext& ctx, const MipChainShaders& s, const MipChainOptions& opt) {
  ctx.check("before building the user's programs");
  const std::string preset = "learnopengl-pbb";
  auto names = [](const ShaderSource& fs, const char* fallback) {
    VertexNames n;
    n.varying = varying_of(fs, fallback);
    return n;
  };
  try {
    Programs p{
        build_user_program(
            "downsample", s.downsample_vs ? &*s.downsample_vs : nullptr, s.downsample_fs,
            {{"srcTexture", HostUniform::sampler, true,
              "texture unit 0: the bright image for mip 0, else the mip above"},
             // Not required: a shader may take its step from textureSize (judged, not refused).
             {"srcResolution", HostUniform::vector, false,
              "the float size of what it reads: the image's, then halved per mip", 2},
             {"mipLevel", HostUniform::integer, false,
              opt.karis ? "0 on the first pass (Karis average), then 1" : "1 (no Karis average)"}},
            names(s.downsample_fs, "texCoord"), preset),
        build_user_program(
            "upsample", s.upsample_vs ? &*s.upsample_vs : nullptr, s.upsample_fs,
            {{"srcTexture", HostUniform::sampler, true, "texture unit 0: the smaller mip"},
             {"filterRadius", HostUniform::number, false,
              "filterRadius = " + number(opt.filter_radius)}},
            names(s.upsample_fs, "texCoord"), preset),
        build_user_program(
            "final", s.final_vs ? &*s.final_vs : nullptr, s.final_fs,
            final_host(opt),
            names(s.final_fs, "TexCoords"), preset)};
    p.down.set_sampler("srcTexture", 0);
    p.up.set_sampler("srcTexture", 0);
    p.up.set_number("filterRadius", opt.filter_radius);
    p.final.set_sampler("scene", 0);
    p.final.set_sampler("bloomBlur", 1);
    p.final.set_number("exposure", opt.exposure);
    p.final.set_integer("programChoice", opt.program_choice);
    if (!std::isnan(opt.strength)) p.final.set_number("bloomStrength", opt.strength);
    ctx.check("building the user's programs");
    return p;
  } catch (const UserShaderError&) {
    try {  // the compiler's errors also arrive as GL debug messages; they are in the error
      ctx.check("building the user's programs");
    } catch (const GlError&) {
    }
    throw;
  }
}

void validate(const MipChainOptions& opt) {
  if (opt.levels < 1 || opt.levels > 16)
    throw ParamError("levels " + std::to_string(opt.levels) + " is not in [1, 16]");
  if (!std::isfinite(opt.filter_radius) || opt.filter_radius < 0)
    throw ParamError("the filter radius must be finite and >= 0");
  if (!std::isfinite(opt.exposure)) throw ParamError("exposure must be finite");
  if (!std::isfinite(opt.threshold)) throw ParamError("threshold must be finite");
}

class MipChainHost {
 public:
  MipChainHost(GlContext& ctx, ConstImageView scene, const MipChainShaders& shaders,
               const MipChainOptions& opt)
      : ctx_(ctx), scene_(scene), opt_(opt), w_(scene.width), h_(scene.height),
        prog_(build(ctx, shaders, opt)) {
    out_.run.programs = {prog_.down.interface, prog_.up.interface, prog_.final.interface};
    out_.run.bright_source = "oracle";
    out_.strength = prog_.final.number("bloomStrength");  // after the host set it, if it did
  }

  MipChainRun run() {
    const auto t_start = Clock::now();
    upload();
    downsamples();
    upsamples();
    final_pass();
    out_.run.trace.total_ms = ms_since(t_start);
    return std::move(out_);
  }

 private:
  void add(const std::string& name, Image&& img, double ms) {
    out_.run.trace.stages.push_back({name, std::move(img), ms, false});
    out_.run.trace.timings.emplace_back(name, ms);
  }

  Texture upload_image(const Image& img) const {
    const GLenum f = host::gl_format(opt_.format);
    if (opt_.rows != RowOrder::flipped) return Texture(w_, h_, f, img.data());
    const Image flipped = host::flipped_rows(img.cview());
    return Texture(w_, h_, f, flipped.data());
  }

  Image read_back(const Texture& t) const {
    Image img = Image::uninitialised(t.width, t.height);
    t.read(img.data());
    return opt_.rows == RowOrder::flipped ? host::flipped_rows(img.cview()) : img;
  }

  // The scene after the non-finite policy, and the bright image the scene shader writes beside
  // it, both stored as their RGBA16F targets store them.
  void upload() {
    const auto t0 = Clock::now();
    Image sanitized(w_, h_);
    const Storage st = storage_of(opt_.format);
    out_.run.trace.nonfinite = sanitize(scene_, sanitized.view(), opt_.nonfinite, st, opt_.threads);
    if (opt_.nonfinite == NonFinite::error && out_.run.trace.nonfinite.total() > 0)
      throw ParamError("the scene holds " + std::to_string(out_.run.trace.nonfinite.total()) +
                       " NaN or infinite values, refused under --nonfinite error");
    Image bright(w_, h_);
    extract_bright(sanitized.cview(), bright.view(), opt_.threshold, opt_.threads, false, nullptr,
                   nullptr, opt_.luma);
    store(sanitized.view(), st, opt_.half_rounding, opt_.threads);
    store(bright.view(), st, opt_.half_rounding, opt_.threads);
    scene_tex_ = upload_image(sanitized);
    bright_tex_ = upload_image(bright);
    for (const Texture* t : {&scene_tex_, &bright_tex_}) t->set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
    ctx_.check("uploading the scene and the bright image");
    const double ms = ms_since(t0);
    add("input", read_back(scene_tex_), ms);
    add("bright", read_back(bright_tex_), 0.0);
  }

  // RenderDownsamples: mip k from mip k-1 (the bright image first), srcResolution the float
  // size of what it reads.
  void downsamples() {
    const std::vector<LevelSize> sizes = mip_levels(w_, h_, opt_.levels);
    for (const LevelSize& l : sizes) {
      mips_.emplace_back(l.width, l.height, host::gl_format(opt_.level_format));
      mips_.back().set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
    }
    for (std::size_t k = 0; k < mips_.size(); ++k) {
      const Texture& src = k == 0 ? bright_tex_ : mips_[k - 1];
      prog_.down.set_vector("srcResolution", {halved_size(w_, int(k)), halved_size(h_, int(k))});
      prog_.down.set_integer("mipLevel", k == 0 && opt_.karis ? 0 : 1);
      const std::string name = "down." + std::to_string(k + 1);
      const double ms = quad_.draw(ctx_, prog_.down, {&src}, mips_[k], nullptr, nullptr,
                                   "the user's downsample pass " + name);
      add(name, read_back(mips_[k]), ms);
    }
  }

  // RenderUpsamples: additive blending, mip k-1 drawn from mip k.
  void upsamples() {
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE);
    glBlendEquation(GL_FUNC_ADD);
    for (std::size_t k = mips_.size() - 1; k > 0; --k) {
      const std::string name = "up." + std::to_string(k);
      const double ms = quad_.draw(ctx_, prog_.up, {&mips_[k]}, mips_[k - 1], nullptr, nullptr,
                                   "the user's upsample pass " + name);
      add(name, read_back(mips_[k - 1]), ms);
    }
    glDisable(GL_BLEND);
  }

  void final_pass() {
    const bool unorm8 = opt_.final_target == FinalTarget::rgba8;
    Texture out(w_, h_, unorm8 ? GL_RGBA8 : host::gl_format(opt_.format));
    out_.run.output_code_bits = unorm8 ? 8 : 0;
    const std::array<float, 4> black = {0.0f, 0.0f, 0.0f, 1.0f};
    const double ms = quad_.draw(ctx_, prog_.final, {&scene_tex_, &mips_[0]}, out, nullptr, &black,
                                 "the user's final pass");
    add("output", read_back(out), ms);
  }

  GlContext& ctx_;
  ConstImageView scene_;
  const MipChainOptions& opt_;
  int w_, h_;
  Programs prog_;
  host::QuadState quad_;
  Texture scene_tex_, bright_tex_;
  std::vector<Texture> mips_;
  MipChainRun out_;
};

}  // namespace

MipChainOptions mip_chain_options_for(const BloomParams& p) {
  if (p.method != Method::mip)
    throw ParamError("the learnopengl-pbb preset runs a mip chain; --method " +
                     to_string(p.method) + " has none");
  if (p.storage == Storage::rgba8)
    throw ParamError("--storage rgba8: the article's final pass draws the composite, the tone map "
                     "and the gamma at once, so it stores none of them in 8 bits as bloomref's "
                     "stages would be; its 8-bit window is judged with check --shaders "
                     "learnopengl-pbb --final-target rgba8, 8-bit levels with --chain-storage rgba8");
  MipChainOptions o;
  o.format = target_format_of(p.storage);
  o.level_format = target_format_of(p.level_storage());
  o.levels = p.levels;
  o.karis = p.karis;
  o.filter_radius = p.upsample_radius;
  o.exposure = p.exposure;
  o.threshold = p.threshold;
  o.luma = luma_rule(p);
  o.nonfinite = p.nonfinite;
  o.threads = p.threads;
  return o;
}

std::vector<ProgramInterface> check_mip_chain(GlContext& ctx, const MipChainShaders& shaders,
                                              const MipChainOptions& opt) {
  validate(opt);
  Programs p = build(ctx, shaders, opt);
  return {p.down.interface, p.up.interface, p.final.interface};
}

MipChainRun run_mip_chain(GlContext& ctx, ConstImageView scene, const MipChainShaders& shaders,
                          const MipChainOptions& opt) {
  validate(opt);
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (scene.width < 2 || scene.height < 2 || scene.width > max_size || scene.height > max_size)
    throw ParamError("a " + std::to_string(scene.width) + "x" + std::to_string(scene.height) +
                     " scene does not fit this GL's textures or has no mip to draw (GL_MAX_TEXTURE_SIZE " +
                     std::to_string(max_size) + ")");
  return MipChainHost(ctx, scene, shaders, opt).run();
}

bool article_layout(const BloomParams& p) {
  return p.method == Method::mip && p.prefilter == Prefilter::bright &&
         (!p.karis || p.karis_form == KarisForm::group_srgb) &&
         p.texel_step == TexelStep::halved_float && p.upsample_radius > 0 &&
         p.bloom_upscale == BloomUpscale::bilinear && p.composite_mode == CompositeMode::mix &&
         p.composite == CompositeOrder::before_tonemap && p.gamma == 2.2f && unity_free(p) &&
         p.first_downsample == FirstDownsample::taps13 && p.downsample == DownsampleFilter::taps13;
}

StageTrace execute_gl_mip_chain(GlContext& ctx, const BloomParams& p, ConstImageView scene) {
  if (bevy_layout(p)) return execute_gl_bevy(ctx, p, scene);
  if (unity_layout(p)) return execute_gl_unity(ctx, p, scene);
  if (threejs_layout(p)) return execute_gl_threejs(ctx, p, scene);
  if (!article_layout(p))
    throw ParamError(
        "bloomref's GL shaders run seed 002's chain (--method mip), the article's "
        "(--preset learnopengl-pbb, whose shaders take gamma 2.2 and the other options as "
        "they are), Bevy's (--preset bevy), Unity URP's (--preset unity-urp) and three.js's (--preset threejs); this combination of variant options has no GL "
        "shaders: judge yours with check --shaders");
  auto own = [](const char* name) {
    return ShaderSource{std::string("bloomref's ") + name, shader_sources().at(name)};
  };
  const MipChainShaders shaders{own("pbb_downsample.frag"), own("pbb_upsample.frag"),
                                own("pbb_final.frag"), std::nullopt, std::nullopt, std::nullopt};
  MipChainOptions opt = mip_chain_options_for(p);
  opt.strength = p.strength;
  MipChainRun run = run_mip_chain(ctx, scene, shaders, opt);
  return std::move(run.run.trace);
}

}  // namespace bloomref::gpu
