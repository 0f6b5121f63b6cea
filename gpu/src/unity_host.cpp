// Preset unity-urp: Unity URP's bloom as PostProcessPass.SetupBloom draws it
// (Unity-Technologies/Graphics com.unity.render-pipelines.universal/Runtime/Passes/
// PostProcessPass.cs at 032e79e), with bloomref's GLSL of its passes (gpu/shaders/unity_*.frag):
// the prefilter into mip 0 at half size, each further mip a horizontal pass into a temporary
// target of its size and a vertical pass into the mip, the upsamples from the smallest up, the
// bloom added to the scene where UberPost does it, then bloomref's tone map and gamma.
#include <epoxy/gl.h>

#include <algorithm>
#include <limits>

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
  return host::own_program(name, file, host, "unity-urp");
}

const HostUniform kSource{"srcTexture", HostUniform::sampler, true, "texture unit 0"};
const HostUniform kTexelSize{"texelSize", HostUniform::vector, true,
                             "1 / the source's size (_BlitTex_TexelSize.xy)", 2};

class UnityHost {
 public:
  UnityHost(GlContext& ctx, const BloomParams& p, ConstImageView scene)
      : ctx_(ctx), p_(p), scene_(scene), w_(scene.width), h_(scene.height),
        prefilter_(own_program("prefilter", "unity_prefilter.frag",
                               {kSource,
                                {"params", HostUniform::vector, true,
                                 "scatter, clamp, threshold, knee (_Params)", 4},
                                {"softThreshold", HostUniform::integer, true,
                                 "1: the soft threshold"}})),
        blur_h_(own_program("blur-h", "unity_blur_h.frag", {kSource, kTexelSize})),
        blur_v_(own_program("blur-v", "unity_blur_v.frag", {kSource, kTexelSize})),
        up_(own_program("upsample", "unity_upsample.frag",
                        {kSource,
                         {"lowMip", HostUniform::sampler, true, "texture unit 1: the level below"},
                         {"scatter", HostUniform::number, true, "scatter (_Params.x)"}})),
        uber_(own_program("uber", "unity_uber.frag",
                          {kSource,
                           {"bloomTexture", HostUniform::sampler, true, "texture unit 1: up.1"},
                           {"intensity", HostUniform::number, true, "intensity"}})),
        finish_(own_program("finish", "bevy_finish.frag",
                            {kSource,
                             {"exposure", HostUniform::number, true, "exposure"},
                             {"gamma", HostUniform::number, true, "gamma"}})) {
    // SetupBloom: thresholdKnee = threshold * 0.5f (here --knee of the threshold), in f32; no
    // clamp (--clamp-max 0) is the largest float.
    const float knee = p.threshold * std::clamp(p.knee, 0.0f, 1.0f);
    const float clamp = p.clamp_max > 0.0f ? p.clamp_max : std::numeric_limits<float>::max();
    for (const UserProgram* prog : {&prefilter_, &blur_h_, &blur_v_, &up_, &uber_, &finish_})
      prog->set_sampler("srcTexture", 0);
    prefilter_.set_vector("params", {p.level_weight, clamp, p.threshold, knee});
    prefilter_.set_integer("softThreshold", p.prefilter == Prefilter::soft_knee ? 1 : 0);
    up_.set_sampler("lowMip", 1);
    uber_.set_sampler("bloomTexture", 1);
    uber_.set_number("intensity", p.strength);
    finish_.set_number("exposure", p.exposure);
    finish_.set_number("gamma", p.gamma);
    ctx_.check("building bloomref's programs for preset unity-urp");
  }

  StageTrace run() {
    const auto t_start = Clock::now();
    upload();
    downsamples();
    upsamples();
    composite();
    finish();
    trace_.total_ms = ms_since(t_start);
    return std::move(trace_);
  }

 private:
  void add(const std::string& name, const Texture& t, double ms) {
    host::add_stage(trace_, name, t, ms);
  }

  Texture level(int w, int h) const {
    Texture t(w, h, storage_format(p_.level_storage()));
    t.set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
    return t;
  }

  // The camera's colour: the scene after the non-finite policy, stored as its target stores it.
  void upload() { view_ = host::upload_scene(ctx_, p_, scene_, trace_); }


  // The prefilter into mip 0; then per mip FragBlurH into a temporary of its size (mipUp) and
  // FragBlurV from it into the mip (mipDown).
  void downsamples() {
    for (const LevelSize& l : chain_levels(p_, w_, h_)) mips_.push_back(level(l.width, l.height));
    double ms = quad_.draw(ctx_, prefilter_, {&view_}, mips_[0], nullptr, nullptr,
                           "the prefilter pass down.1");
    add("down.1", mips_[0], ms);
    for (std::size_t k = 1; k < mips_.size(); ++k) {
      const Texture& src = mips_[k - 1];
      Texture tmp = level(mips_[k].width, mips_[k].height);
      const std::string name = "down." + std::to_string(k + 1);
      blur_h_.set_vector("texelSize", {1.0f / float(src.width), 1.0f / float(src.height)});
      ms = quad_.draw(ctx_, blur_h_, {&src}, tmp, nullptr, nullptr,
                      "the horizontal pass of " + name);
      blur_v_.set_vector("texelSize", {1.0f / float(tmp.width), 1.0f / float(tmp.height)});
      ms += quad_.draw(ctx_, blur_v_, {&tmp}, mips_[k], nullptr, nullptr,
                       "the vertical pass of " + name);
      add(name, mips_[k], ms);
    }
  }

  // for i = mipCount - 2 .. 0: mipUp[i] = Upsample(mipDown[i], the level below: mipDown of the
  // last mip, else mipUp[i + 1]).
  void upsamples() {
    const int levels = static_cast<int>(mips_.size());
    ups_.resize(mips_.size());
    for (int i = levels - 2; i >= 0; --i) {
      const std::size_t k = std::size_t(i);
      up_.set_number("scatter", level_blend(p_, i + 1, levels).weight);
      ups_[k] = level(mips_[k].width, mips_[k].height);
      const Texture& low = i == levels - 2 ? mips_[k + 1] : ups_[k + 1];
      const std::string name = "up." + std::to_string(i + 1);
      const double ms = quad_.draw(ctx_, up_, {&mips_[k], &low}, ups_[k], nullptr, nullptr,
                                   "the upsample pass " + name);
      add(name, ups_[k], ms);
    }
  }

  void composite() {
    comp_ = Texture(w_, h_, storage_format(p_.storage));
    const Texture& bloom = mips_.size() > 1 ? ups_[0] : mips_[0];
    const double ms = quad_.draw(ctx_, uber_, {&view_, &bloom}, comp_, nullptr, nullptr,
                                 "the uber pass (composite)");
    add("composite", comp_, ms);
  }

  void finish() {
    Texture out(w_, h_, storage_format(p_.storage));
    const std::array<float, 4> black = {0.0f, 0.0f, 0.0f, 1.0f};
    const double ms = quad_.draw(ctx_, finish_, {&comp_}, out, nullptr, &black,
                                 "the tone map and gamma pass");
    add("output", out, ms);
  }

  GlContext& ctx_;
  const BloomParams& p_;
  ConstImageView scene_;
  int w_, h_;
  UserProgram prefilter_, blur_h_, blur_v_, up_, uber_, finish_;
  host::QuadState quad_;
  Texture view_, comp_;
  std::vector<Texture> mips_, ups_;
  StageTrace trace_;
};

}  // namespace

bool unity_layout(const BloomParams& p) {
  return p.method == Method::mip && p.first_downsample == FirstDownsample::bilinear &&
         (p.prefilter == Prefilter::none ||
          (p.prefilter == Prefilter::soft_knee && p.knee_form == KneeForm::unity)) &&
         p.downsample == DownsampleFilter::gaussian && p.upsample == UpsampleFilter::bilinear &&
         p.level_combine == LevelCombine::lerp && p.level_weights == LevelWeights::constant &&
         p.bloom_upscale == BloomUpscale::bilinear && p.composite_mode == CompositeMode::add &&
         p.composite == CompositeOrder::before_tonemap && p.texel_step == TexelStep::texture &&
         p.first_level_height == 0 && !p.karis;
}

StageTrace execute_gl_unity(GlContext& ctx, const BloomParams& p, ConstImageView scene) {
  if (!unity_layout(p))
    throw ParamError("bloomref's GL shaders for Unity URP's layout need --first-downsample "
                     "bilinear, --prefilter none or soft-knee with --knee-form unity, "
                     "--downsample gaussian, --upsample bilinear, --level-combine lerp, "
                     "--level-weights constant, --bloom-upscale bilinear, --composite-mode add, "
                     "--composite before-tonemap, --texel-step texture and no --karis");
  host::require_fits(scene);
  return UnityHost(ctx, p, scene).run();
}

}  // namespace bloomref::gpu
