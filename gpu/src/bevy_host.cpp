// Preset bevy: Bevy's bloom render graph (bevyengine/bevy crates/bevy_post_process/src/bloom/
// mod.rs, `bloom` and prepare_bloom_textures) with bloomref's GLSL of its passes
// (gpu/shaders/bevy_*.frag): the first downsample reads the scene, the levels are drawn in
// order, each upsample blends into the next larger level with a constant colour, and the last
// blends into the scene itself. bloomref's tone map and gamma follow as one more pass.
#include <epoxy/gl.h>

#include <algorithm>

#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/mip.h"
#include "user_host.h"
#include "user_program.h"

namespace bloomref::gpu {
namespace {

using host::Clock;
using host::ms_since;
using host::storage_format;

UserProgram own_program(const char* name, const char* file, const std::vector<HostUniform>& host) {
  return host::own_program(name, file, host, "bevy");
}

class BevyHost {
 public:
  BevyHost(GlContext& ctx, const BloomParams& p, ConstImageView scene)
      : ctx_(ctx), p_(p), scene_(scene), w_(scene.width), h_(scene.height),
        down_(own_program("downsample", "bevy_downsample.frag",
                          {{"srcTexture", HostUniform::sampler, true, "texture unit 0"},
                           {"firstDownsample", HostUniform::integer, true, "1 on the first level"},
                           {"softThreshold", HostUniform::integer, true, "1: the soft threshold"},
                           {"thresholdPrecomputations", HostUniform::vector, true,
                            "Bevy's threshold_precomputations", 4}})),
        box_(own_program("box4-downsample", "box4_downsample.frag",
                         {{"srcTexture", HostUniform::sampler, true, "texture unit 0"},
                          {"softThreshold", HostUniform::integer, true, "1: the soft threshold"},
                          {"thresholdPrecomputations", HostUniform::vector, true,
                           "Bevy's threshold_precomputations", 4}})),
        up_(own_program("upsample", "bevy_upsample.frag",
                        {{"srcTexture", HostUniform::sampler, true, "texture unit 0"}})),
        finish_(own_program("finish", "bevy_finish.frag",
                            {{"srcTexture", HostUniform::sampler, true, "texture unit 0"},
                             {"exposure", HostUniform::number, true, "exposure"},
                             {"gamma", HostUniform::number, true, "gamma"}})) {
    // settings.rs, extract_component: knee = threshold x softness, in f32.
    const float knee = p.threshold * std::clamp(p.knee, 0.0f, 1.0f);
    for (UserProgram* d : {&down_, &box_}) {
      d->set_sampler("srcTexture", 0);
      d->set_vector("thresholdPrecomputations",
                    {p.threshold, p.threshold - knee, 2.0f * knee, 0.25f / (knee + 0.00001f)});
    }
    up_.set_sampler("srcTexture", 0);
    finish_.set_sampler("srcTexture", 0);
    finish_.set_number("exposure", p.exposure);
    finish_.set_number("gamma", p.gamma);
    ctx_.check("building bloomref's programs for preset bevy");
  }

  StageTrace run() {
    const auto t_start = Clock::now();
    upload();
    downsamples();
    upsamples();
    finish();
    trace_.total_ms = ms_since(t_start);
    return std::move(trace_);
  }

 private:
  void add(const std::string& name, const Texture& t, double ms) {
    host::add_stage(trace_, name, t, ms);
  }

  // The HDR view: the scene after the non-finite policy, stored as the view's format stores it.
  void upload() { view_ = host::upload_scene(ctx_, p_, scene_, trace_); }


  // downsample_first into mip 0 from the view, then mip k from mip k - 1.
  void downsamples() {
    for (const LevelSize& l : chain_levels(p_, w_, h_)) {
      mips_.emplace_back(l.width, l.height, storage_format(p_.level_storage()));
      mips_.back().set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
    }
    for (std::size_t k = 0; k < mips_.size(); ++k) {
      // The 4-tap box where the level asks for it (box4_downsample.frag), else Bevy's 13 taps.
      UserProgram& prog = box4(p_, int(k)) ? box_ : down_;
      if (&prog == &down_) down_.set_integer("firstDownsample", k == 0 && p_.karis ? 1 : 0);
      prog.set_integer("softThreshold", k == 0 && p_.prefilter == Prefilter::soft_knee ? 1 : 0);
      const std::string name = "down." + std::to_string(k + 1);
      const double ms = quad_.draw(ctx_, prog, {k == 0 ? &view_ : &mips_[k - 1]}, mips_[k],
                                   nullptr, nullptr, "the downsample pass " + name);
      add(name, mips_[k], ms);
    }
  }

  // Blend state of upsampling_pipeline.rs: colour src x C + dst x (1 - C) (EnergyConserving)
  // or + dst (Additive); alpha kept.
  static void blend(LevelCombine combine, float constant) {
    glEnable(GL_BLEND);
    glBlendColor(constant, constant, constant, constant);
    glBlendEquation(GL_FUNC_ADD);
    glBlendFuncSeparate(GL_CONSTANT_COLOR,
                        combine == LevelCombine::mix ? GL_ONE_MINUS_CONSTANT_COLOR : GL_ONE,
                        GL_ZERO, GL_ONE);
  }

  // for mip in (1..mip_count).rev(): mip drawn into mip - 1 with C(mip); then mip 0 into the view
  // with the composite's constant.
  void upsamples() {
    const int levels = static_cast<int>(mips_.size());
    for (int k = levels - 1; k > 0; --k) {
      const LevelBlend b = level_blend(p_, k, levels);
      blend(b.combine, b.weight);
      const std::string name = "up." + std::to_string(k);
      const double ms = quad_.draw(ctx_, up_, {&mips_[std::size_t(k)]}, mips_[std::size_t(k - 1)],
                                   nullptr, nullptr, "the upsample pass " + name);
      add(name, mips_[std::size_t(k - 1)], ms);
    }
    blend(p_.composite_mode == CompositeMode::mix ? LevelCombine::mix : LevelCombine::add,
          p_.strength);
    const double ms = quad_.draw(ctx_, up_, {&mips_[0]}, view_, nullptr, nullptr,
                                 "the final upsample pass");
    glDisable(GL_BLEND);
    add("composite", view_, ms);
  }

  void finish() {
    Texture out(w_, h_, storage_format(p_.storage));
    const std::array<float, 4> black = {0.0f, 0.0f, 0.0f, 1.0f};
    const double ms = quad_.draw(ctx_, finish_, {&view_}, out, nullptr, &black,
                                 "the tone map and gamma pass");
    add("output", out, ms);
  }

  GlContext& ctx_;
  const BloomParams& p_;
  ConstImageView scene_;
  int w_, h_;
  UserProgram down_, box_, up_, finish_;
  host::QuadState quad_;
  Texture view_;
  std::vector<Texture> mips_;
  StageTrace trace_;
};

}  // namespace

bool box4(const BloomParams& p, int k) {
  return k == 0 ? p.first_downsample == FirstDownsample::box4 : p.downsample == DownsampleFilter::box4;
}

bool unity_free(const BloomParams& p) {
  return p.first_downsample != FirstDownsample::bilinear &&
         (p.downsample == DownsampleFilter::taps13 || p.downsample == DownsampleFilter::box4) &&
         p.upsample == UpsampleFilter::tent && p.level_combine != LevelCombine::lerp &&
         p.level_weights != LevelWeights::constant && p.knee_form == KneeForm::bevy &&
         p.clamp_max == 0.0f && p.level_count == LevelCount::fixed &&
         p.level_combine != LevelCombine::sum && p.prefilter != Prefilter::smoothstep;
}

bool bevy_layout(const BloomParams& p) {
  return p.method == Method::mip &&
         (p.prefilter == Prefilter::none || p.prefilter == Prefilter::soft_knee) &&
         p.texel_step == TexelStep::texture && p.upsample_radius == 0.0f &&
         p.bloom_upscale == BloomUpscale::tent && p.composite == CompositeOrder::before_tonemap &&
         (!p.karis || p.karis_form == KarisForm::group_linear) && unity_free(p);
}

StageTrace execute_gl_bevy(GlContext& ctx, const BloomParams& p, ConstImageView scene) {
  if (!bevy_layout(p))
    throw ParamError("bloomref's GL shaders for Bevy's layout need --prefilter none or "
                     "soft-knee, --texel-step texture, --upsample-radius 0, --bloom-upscale tent, "
                     "--composite before-tonemap and --karis-form group-linear");
  host::require_fits(scene);
  return BevyHost(ctx, p, scene).run();
}

}  // namespace bloomref::gpu
