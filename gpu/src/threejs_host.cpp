// Preset threejs: three.js's bloom as BloomNode.js draws it (mrdoob/three.js
// examples/jsm/tsl/display/BloomNode.js at fef3c54, updateBefore), with bloomref's GLSL of its
// passes (gpu/shaders/threejs_*.frag): the high pass into the bright target at half size, each
// mip a horizontal pass into its horizontal target and a vertical pass into its vertical one,
// the composite of the vertical targets into the first horizontal one, then the bloom added to
// the scene (the example's `scenePassColor.add( bloomPass )`), bloomref's tone map and gamma.
// Its host is a pipeline description (preset_descriptions.cpp), run here by the described host.

#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/mip.h"
#include "user_host.h"

namespace bloomref::gpu {

bool threejs_layout(const BloomParams& p) {
  // The shader holds 24 coefficients: the radii of the mips drawn at most 24.
  bool kernels_fit = true;
  for (int k = 0; k < p.levels && std::size_t(k) < p.level_kernels.size(); ++k)
    kernels_fit = kernels_fit && p.level_kernels[std::size_t(k)] <= 24;
  return p.method == Method::mip && p.level_count == LevelCount::threejs &&
         p.first_downsample == FirstDownsample::bilinear &&
         p.prefilter == Prefilter::smoothstep &&
         p.luma_space == LumaSpace::linear && p.clamp_max == 0.0f &&
         p.downsample == DownsampleFilter::separable && p.level_combine == LevelCombine::sum &&
         p.levels <= 5 && kernels_fit && p.bloom_upscale == BloomUpscale::bilinear &&
         p.composite_mode == CompositeMode::add && p.composite == CompositeOrder::before_tonemap &&
         p.texel_step == TexelStep::texture && !p.karis;
}

StageTrace execute_gl_threejs(GlContext& ctx, const BloomParams& p, ConstImageView scene) {
  if (!threejs_layout(p))
    throw ParamError("bloomref's GL shaders for three.js's layout need --level-count threejs with "
                     "--levels at most 5, --first-downsample bilinear, --prefilter smoothstep, "
                     "--luma-space linear, no --clamp-max, --downsample separable with "
                     "--level-kernels at most 24, --level-combine sum, --bloom-upscale bilinear, "
                     "--composite-mode add, --composite before-tonemap, --texel-step texture and "
                     "no --karis");
  host::require_fits(scene);
  return run_described(ctx, scene, preset_description(p, scene.width, scene.height), p).trace;
}

}  // namespace bloomref::gpu
