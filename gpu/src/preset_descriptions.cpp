// The built-in layouts' host code as pipeline descriptions (described_pipeline.h): the same
// textures, passes, uniforms and blending as the article's host (mip_chain_host.cpp), Bevy's
// render graph (bevy_host.cpp) and URP's SetupBloom (unity_host.cpp) draw, for one scene size.
// A backend that runs descriptions (the Vulkan path) runs the presets through them.
#include <algorithm>
#include <limits>

#include "bloomref/error.h"
#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/mip.h"
#include "shader_sources.h"

namespace bloomref::gpu {
namespace {

DescribedUniform number(std::vector<float> v) {
  DescribedUniform u;
  u.values = std::move(v);
  return u;
}

DescribedUniform integer(int v) {
  DescribedUniform u;
  u.kind = DescribedUniform::integer;
  u.integer_value = v;
  return u;
}

DescribedUniform of_texture(DescribedUniform::Kind kind, const std::string& texture, int times = 0) {
  DescribedUniform u;
  u.kind = kind;
  u.texture = texture;
  u.times = times;
  return u;
}

std::string level(const char* prefix, std::size_t k) { return prefix + std::to_string(k); }

class Builder {
 public:
  Builder(const std::string& preset, int w, int h) : w_(w), h_(h) { d_.file = "preset " + preset; }

  void program(const std::string& name, const char* file) {
    DescribedProgram p;
    p.fragment = std::string("bloomref's ") + file;
    p.fragment_text = shader_sources().at(file);
    d_.programs.emplace(name, std::move(p));
  }

  void texture(const std::string& name, int w, int h, Storage s,
               DescribedTexture::Content content = DescribedTexture::clear,
               const std::string& stage = "") {
    DescribedTexture t;
    t.name = name;
    t.content = content;
    t.size.exact_width = w;
    t.size.exact_height = h;
    t.format = target_format_of(s);
    t.stage = stage;
    d_.textures.push_back(std::move(t));
  }
  void scene_texture(const std::string& name, Storage s, DescribedTexture::Content content,
                     const std::string& stage) {
    texture(name, w_, h_, s, content, stage);
  }

  DescribedPass& pass(const std::string& program, const std::string& target,
                      std::vector<std::pair<std::string, std::string>> inputs,
                      const std::string& stage) {
    DescribedPass p;
    p.program = program;
    p.target = target;
    p.inputs = std::move(inputs);
    p.stage = stage;
    d_.passes.push_back(std::move(p));
    return d_.passes.back();
  }

  static void blend(DescribedPass& p, const char* src, const char* dst, float constant = 0.0f) {
    p.clear = false;
    p.blend.enabled = true;
    p.blend.src = src;
    p.blend.dst = dst;
    p.blend.constant = constant;
  }

  PipelineDescription take() { return std::move(d_); }

 private:
  int w_, h_;
  PipelineDescription d_;
};

// The engines' last pass (bevy_finish.frag): bloomref's tone map and gamma of `input` into
// "out", the output stage.
void finish(Builder& b, const std::string& input, const BloomParams& p) {
  DescribedPass& f = b.pass("finish", "out", {{"srcTexture", input}}, "output");
  f.uniforms["exposure"] = number({p.exposure});
  f.uniforms["gamma"] = number({p.gamma});
}

// mip_chain_host.cpp: the scene and bright image, RenderDownsamples from the bright image with
// srcResolution the float size halved per level, RenderUpsamples blending (ONE, ONE) into the
// larger level, the final pass over the scene and mip 0.
PipelineDescription article(const BloomParams& p, int w, int h) {
  const MipChainOptions o = mip_chain_options_for(p);
  Builder b("learnopengl-pbb", w, h);
  b.program("down", "pbb_downsample.frag");
  b.program("up", "pbb_upsample.frag");
  b.program("final", "pbb_final.frag");
  const Storage st = p.storage, levels = p.level_storage();
  b.scene_texture("scene", st, DescribedTexture::scene, "input");
  b.scene_texture("bright", st, DescribedTexture::bright, "bright");
  const std::vector<LevelSize> sizes = mip_levels(w, h, o.levels);
  for (std::size_t k = 0; k < sizes.size(); ++k)
    b.texture(level("mip", k), sizes[k].width, sizes[k].height, levels);
  b.scene_texture("out", st, DescribedTexture::clear, "");
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    DescribedPass& d = b.pass("down", level("mip", k),
                              {{"srcTexture", k == 0 ? "bright" : level("mip", k - 1)}},
                              level("down.", k + 1));
    d.uniforms["srcResolution"] = of_texture(DescribedUniform::halved, "scene", int(k));
    d.uniforms["mipLevel"] = integer(k == 0 && o.karis ? 0 : 1);
  }
  for (std::size_t k = sizes.size() - 1; k > 0; --k) {
    DescribedPass& u = b.pass("up", level("mip", k - 1), {{"srcTexture", level("mip", k)}},
                              level("up.", k));
    u.uniforms["filterRadius"] = number({o.filter_radius});
    Builder::blend(u, "one", "one");
  }
  DescribedPass& f = b.pass("final", "out", {{"scene", "scene"}, {"bloomBlur", "mip0"}}, "output");
  f.uniforms["exposure"] = number({o.exposure});
  f.uniforms["programChoice"] = integer(o.program_choice);
  f.uniforms["bloomStrength"] = number({p.strength});
  return b.take();
}

// bevy_host.cpp: the downsamples from the view, each upsample blended into the next larger
// level with its constant, the last into the view, then the tone map and gamma.
PipelineDescription bevy(const BloomParams& p, int w, int h) {
  Builder b("bevy", w, h);
  b.program("down", "bevy_downsample.frag");
  b.program("up", "bevy_upsample.frag");
  b.program("finish", "bevy_finish.frag");
  b.scene_texture("view", p.storage, DescribedTexture::scene, "input");
  const std::vector<LevelSize> sizes = chain_levels(p, w, h);
  // The 4-tap box's levels (--first-downsample box4, --downsample box4) by their own program.
  bool any_box = false;
  for (std::size_t k = 0; k < sizes.size(); ++k) any_box = any_box || box4(p, int(k));
  if (any_box) b.program("box", "box4_downsample.frag");
  for (std::size_t k = 0; k < sizes.size(); ++k)
    b.texture(level("mip", k), sizes[k].width, sizes[k].height, p.level_storage());
  b.scene_texture("out", p.storage, DescribedTexture::clear, "");
  // settings.rs, extract_component: knee = threshold x softness, in f32.
  const float knee = p.threshold * std::clamp(p.knee, 0.0f, 1.0f);
  const std::vector<float> pre = {p.threshold, p.threshold - knee, 2.0f * knee,
                                  0.25f / (knee + 0.00001f)};
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    DescribedPass& d = b.pass(box4(p, int(k)) ? "box" : "down", level("mip", k),
                              {{"srcTexture", k == 0 ? "view" : level("mip", k - 1)}},
                              level("down.", k + 1));
    if (d.program == "down") d.uniforms["firstDownsample"] = integer(k == 0 && p.karis ? 1 : 0);
    d.uniforms["softThreshold"] = integer(k == 0 && p.prefilter == Prefilter::soft_knee ? 1 : 0);
    d.uniforms["thresholdPrecomputations"] = number(pre);
  }
  const int levels = static_cast<int>(sizes.size());
  for (int k = levels - 1; k > 0; --k) {
    const LevelBlend lb = level_blend(p, k, levels);
    DescribedPass& u = b.pass("up", level("mip", std::size_t(k - 1)),
                              {{"srcTexture", level("mip", std::size_t(k))}},
                              "up." + std::to_string(k));
    Builder::blend(u, "constant_color",
                   lb.combine == LevelCombine::mix ? "one_minus_constant_color" : "one", lb.weight);
  }
  DescribedPass& c = b.pass("up", "view", {{"srcTexture", "mip0"}}, "composite");
  Builder::blend(c, "constant_color",
                 p.composite_mode == CompositeMode::mix ? "one_minus_constant_color" : "one",
                 p.strength);
  finish(b, "view", p);
  return b.take();
}

// unity_host.cpp: the prefilter into mip 0, per further mip a horizontal pass into a temporary
// of its size and a vertical pass into the mip, the upsamples from the smallest up, UberPost's
// composite, then the tone map and gamma.
PipelineDescription unity(const BloomParams& p, int w, int h) {
  Builder b("unity-urp", w, h);
  b.program("prefilter", "unity_prefilter.frag");
  b.program("blur-h", "unity_blur_h.frag");
  b.program("blur-v", "unity_blur_v.frag");
  b.program("upsample", "unity_upsample.frag");
  b.program("uber", "unity_uber.frag");
  b.program("finish", "bevy_finish.frag");
  b.scene_texture("view", p.storage, DescribedTexture::scene, "input");
  const std::vector<LevelSize> sizes = chain_levels(p, w, h);
  const Storage ls = p.level_storage();
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    b.texture(level("mip", k), sizes[k].width, sizes[k].height, ls);
    if (k > 0) b.texture(level("tmp", k), sizes[k].width, sizes[k].height, ls);
    if (k + 1 < sizes.size()) b.texture(level("up", k), sizes[k].width, sizes[k].height, ls);
  }
  b.scene_texture("comp", p.storage, DescribedTexture::clear, "");
  b.scene_texture("out", p.storage, DescribedTexture::clear, "");
  // SetupBloom: thresholdKnee = threshold * 0.5f (here --knee of the threshold), in f32; no
  // clamp (--clamp-max 0) is the largest float.
  const float knee = p.threshold * std::clamp(p.knee, 0.0f, 1.0f);
  const float clamp = p.clamp_max > 0.0f ? p.clamp_max : std::numeric_limits<float>::max();
  DescribedPass& pre = b.pass("prefilter", "mip0", {{"srcTexture", "view"}}, "down.1");
  pre.uniforms["params"] = number({p.level_weight, clamp, p.threshold, knee});
  pre.uniforms["softThreshold"] = integer(p.prefilter == Prefilter::soft_knee ? 1 : 0);
  for (std::size_t k = 1; k < sizes.size(); ++k) {
    b.pass("blur-h", level("tmp", k), {{"srcTexture", level("mip", k - 1)}}, "")
        .uniforms["texelSize"] = of_texture(DescribedUniform::texel, level("mip", k - 1));
    b.pass("blur-v", level("mip", k), {{"srcTexture", level("tmp", k)}}, level("down.", k + 1))
        .uniforms["texelSize"] = of_texture(DescribedUniform::texel, level("tmp", k));
  }
  const int levels = static_cast<int>(sizes.size());
  for (int i = levels - 2; i >= 0; --i) {
    const std::size_t k = std::size_t(i);
    const std::string low = i == levels - 2 ? level("mip", k + 1) : level("up", k + 1);
    b.pass("upsample", level("up", k), {{"srcTexture", level("mip", k)}, {"lowMip", low}},
           "up." + std::to_string(i + 1))
        .uniforms["scatter"] = number({level_blend(p, i + 1, levels).weight});
  }
  b.pass("uber", "comp", {{"srcTexture", "view"}, {"bloomTexture", levels > 1 ? "up0" : "mip0"}},
         "composite")
      .uniforms["intensity"] = number({p.strength});
  finish(b, "comp", p);
  return b.take();
}

// threejs_host.cpp: BloomNode.js's updateBefore: the high pass into the bright target, per mip
// a horizontal pass into its horizontal target and a vertical pass into its vertical one (the
// first reading the bright target, each next the vertical target before it), the composite of
// the vertical targets; then the bloom added to the scene (unity_uber.frag's arithmetic: the
// scene plus one lookup of the bloom times the strength) and the tone map and gamma.
PipelineDescription threejs(const BloomParams& p, int w, int h) {
  Builder b("threejs", w, h);
  b.program("highpass", "threejs_highpass.frag");
  b.program("blur", "threejs_blur.frag");
  b.program("composite", "threejs_composite.frag");
  b.program("add", "unity_uber.frag");
  b.program("finish", "bevy_finish.frag");
  b.scene_texture("view", p.storage, DescribedTexture::scene, "input");
  const std::vector<LevelSize> sizes = chain_levels(p, w, h);
  const Storage ls = p.level_storage();
  b.texture("bright", sizes[0].width, sizes[0].height, ls);
  for (std::size_t k = 1; k < sizes.size(); ++k) {
    b.texture(level("h", k), sizes[k].width, sizes[k].height, ls);
    b.texture(level("v", k), sizes[k].width, sizes[k].height, ls);
  }
  b.texture("sum", sizes[0].width, sizes[0].height, ls);
  b.scene_texture("comp", p.storage, DescribedTexture::clear, "");
  b.scene_texture("out", p.storage, DescribedTexture::clear, "");
  DescribedPass& hp = b.pass("highpass", "bright", {{"srcTexture", "view"}}, "down.1");
  hp.uniforms["threshold"] = number({p.threshold});
  hp.uniforms["smoothWidth"] = number({p.smooth_width});
  const LumaWeights<float> lw = luma_weights<float>(p.luma);
  hp.uniforms["lumaWeights"] = number({lw.r, lw.g, lw.b});
  for (std::size_t k = 1; k < sizes.size(); ++k) {
    const int radius = p.level_kernels[k - 1];
    std::vector<float> c = separable_coefficients(radius, level_sigma(p, int(k) + 1), p.level_normalise);
    c.resize(24, 0.0f);
    const std::string in = k == 1 ? "bright" : level("v", k - 1);
    for (int axis = 0; axis < 2; ++axis) {
      const std::string target = level(axis == 0 ? "h" : "v", k);
      DescribedPass& bp =
          b.pass("blur", target, {{"colorTexture", axis == 0 ? in : level("h", k)}},
                 axis == 0 ? "" : level("down.", k + 1));
      bp.uniforms["invSize"] = of_texture(DescribedUniform::texel, target);
      bp.uniforms["direction"] = number({axis == 0 ? 1.0f : 0.0f, axis == 0 ? 0.0f : 1.0f});
      bp.uniforms["kernelRadius"] = integer(radius);
      for (std::size_t j = 0; j < 6; ++j)
        bp.uniforms["coefficients" + std::to_string(j)] =
            number({c[4 * j], c[4 * j + 1], c[4 * j + 2], c[4 * j + 3]});
    }
  }
  const int mips = static_cast<int>(sizes.size()) - 1;
  std::vector<std::pair<std::string, std::string>> blurs;
  for (int i = 1; i <= 5; ++i)
    blurs.push_back({"blurTexture" + std::to_string(i), level("v", std::size_t(std::min(i, mips)))});
  std::vector<float> f(5, 0.0f);
  for (int i = 0; i < mips; ++i) f[std::size_t(i)] = p.level_factors[std::size_t(i)];
  DescribedPass& cp = b.pass("composite", "sum", blurs, "up.1");
  cp.uniforms["mips"] = integer(mips);
  cp.uniforms["bloomFactors"] = number({f[0], f[1], f[2], f[3]});
  cp.uniforms["bloomFactor5"] = number({f[4]});
  cp.uniforms["bloomRadius"] = number({p.level_radius});
  cp.uniforms["bloomStrength"] = number({p.level_strength});
  b.pass("add", "comp", {{"srcTexture", "view"}, {"bloomTexture", "sum"}}, "composite")
      .uniforms["intensity"] = number({p.strength});
  finish(b, "comp", p);
  return b.take();
}

}  // namespace

PipelineDescription preset_description(const BloomParams& p, int width, int height) {
  if (bevy_layout(p)) return bevy(p, width, height);
  if (unity_layout(p)) return unity(p, width, height);
  if (threejs_layout(p)) return threejs(p, width, height);
  if (article_layout(p)) return article(p, width, height);
  throw ParamError(
      "bloomref's shaders draw seed 002's chain (--method mip), the article's (--preset "
      "learnopengl-pbb), Bevy's (--preset bevy), Unity URP's (--preset unity-urp) and three.js's "
      "(--preset threejs); this "
      "combination of variant options has none: judge yours with check --shaders");
}

}  // namespace bloomref::gpu
