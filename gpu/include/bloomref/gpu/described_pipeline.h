// A bloom's host code as data (docs/check.md, "Any host code: a pipeline description"): the
// textures it draws into, the programs and the passes in order, each pass's inputs, uniforms,
// blending and the bloomref stage its target holds afterwards. run_described runs the user's
// shaders so, in a headless GL context, and reads back every pass that names a stage. The file
// format and its parser are the CLI's (cli/check/pipeline.cpp; docs/schemas/pipeline.v1.json).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "bloomref/gpu/context.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/image.h"
#include "bloomref/params.h"

namespace bloomref::gpu {

/// How a texture's size follows from another's (declared before it): `scale` times its width
/// and height, rounded down (floor), to the nearest (round, halves up) or up (ceil), at least 1;
/// the scene's own size when `of` is "scene" and scale is 1.
/// `halvings` > 0: halved that many times instead, each time rounded. `height` > 0: that height
/// and the width in proportion, round(width x height / its height) computed in f32, halves away
/// from zero (a bloom texture of fixed height, as Bevy's 512).
struct SizeRule {
  std::string of = "scene";
  int exact_width = 0, exact_height = 0;  ///< > 0: that size, whatever the rest says
  double scale = 1.0;
  int halvings = 0;
  int height = 0;
  enum Rounding { floor, round, ceil } rounding = floor;
};

struct DescribedTexture {
  std::string name;
  /// What it holds before the first pass: black (clear), the scene after the non-finite policy,
  /// or the bright image bloomref makes from it (luminance > threshold), both stored in the
  /// texture's format.
  enum Content { clear, scene, bright } content = clear;
  SizeRule size;
  TargetFormat format = TargetFormat::rgba16f;
  TextureFilter filter = TextureFilter::linear;
  TextureWrap wrap = TextureWrap::clamp_to_edge;
  std::string stage;  ///< the bloomref stage it holds before the first pass; empty: none
};

struct DescribedUniform {
  /// number: a float (or a vector of floats); integer: an int; flag: a bool; size: a texture's
  /// integer size as a float vec2; texel: 1 / that size; halved: the size of `texture` halved
  /// `times` times in float, as a host that keeps a float size does (vec2).
  /// width, height: one of a texture's integer sizes as a float.
  enum Kind { number, integer, flag, size, texel, halved, width, height } kind = number;
  std::vector<float> values;
  int integer_value = 0;
  std::string texture;
  int times = 0;
};

struct DescribedBlend {
  bool enabled = false;
  std::string src = "GL_ONE", dst = "GL_ONE";
  float constant = 0.0f;  ///< glBlendColor's, for the CONSTANT_COLOR factors
};

struct DescribedPass {
  std::string program;
  std::vector<std::pair<std::string, std::string>> inputs;  ///< sampler -> texture, unit order
  std::string target;
  std::map<std::string, DescribedUniform> uniforms;
  DescribedBlend blend;
  bool clear = true;   ///< cleared to black before the draw (false: it draws over what is there)
  /// A compute program's storage images: binding (its name, or its number) -> texture.
  std::vector<std::pair<std::string, std::string>> images;
  /// A compute program's work groups: over `dispatch_over`'s size (the target's when empty) in
  /// groups of its local size, or exactly groups_x x groups_y when those are > 0.
  std::string dispatch_over;
  int groups_x = 0, groups_y = 0;
  std::string stage;   ///< the bloomref stage the target holds after this pass; empty: none
};

struct DescribedProgram {
  std::string fragment, vertex;  ///< files; vertex empty: bloomref's pass-through
  std::string fragment_text;     ///< not empty: the fragment shader's text, `fragment` its name
  /// A compute shader instead (Vulkan only): GLSL (#version 450), HLSL (.hlsl) or SPIR-V (.spv),
  /// its entry point `entry`.
  std::string compute, entry = "main";
};

struct PipelineDescription {
  std::string file;  ///< where it was read from (messages)
  std::map<std::string, DescribedProgram> programs;
  std::vector<DescribedTexture> textures;
  std::vector<DescribedPass> passes;
};

/// Each texture's width and height for a `width` x `height` scene, in declaration order.
std::vector<std::pair<int, int>> texture_sizes(const PipelineDescription& d, int width, int height);

/// What texture `t` (content scene or bright) holds before the first pass: `sanitized` (the
/// scene after the non-finite policy) or the bright image made from it (luminance > the
/// threshold of `params`), stored in the texture's format.
Image texture_content(const DescribedTexture& t, ConstImageView sanitized, const BloomParams& params);

/// The scene as the passes' textures start from it: NaN and infinities replaced as
/// `params.nonfinite` says (counted in `counts`); ParamError when the policy is `error` and
/// there are any.
Image sanitized_scene(ConstImageView scene, const BloomParams& params, NonFiniteCounts& counts);

/// The value(s) a host sets uniform `u` to, as floats: its numbers, its integer, or the size of
/// its texture (`width` x `height`) as the kind says (the size, a texel, halved `times` times,
/// one side).
std::vector<float> uniform_values(const DescribedUniform& u, int width, int height);

/// The blend factors by GL name ("GL_ONE", "GL_ONE_MINUS_CONSTANT_COLOR", ...) or short name
/// ("one", "one_minus_constant_color"); ParamError listing the known ones otherwise.
unsigned blend_factor(const std::string& name);

struct DescribedRun {
  StageTrace trace;  ///< the stages the passes named, in pass order
  std::vector<ProgramInterface> programs;
};

/// The chain a built-in layout draws, as a description for a `width` x `height` scene: the
/// article's host (execute_gl_mip_chain's combinations), Bevy's render graph (bevy_layout) or
/// URP's SetupBloom (unity_layout), around bloomref's shaders of their passes
/// (gpu/shaders/pbb_*, bevy_*, unity_*), every texture at the size its host makes it and every
/// stage the host reads back (input, bright where the host has one, down.k, up.k, composite
/// where it draws one, output). Throws ParamError for a combination no built-in host draws.
PipelineDescription preset_description(const BloomParams& params, int width, int height);

/// Runs the description on `scene` (params: the non-finite policy, the threshold of a bright
/// texture, the threads). Refuses (UserShaderError, ParamError naming the description and the
/// pass) a shader that does not compile, a sampler or uniform the description does not set and
/// the shader does not initialise, an unknown texture or program, a pass drawing into a texture
/// it reads.
DescribedRun run_described(GlContext& ctx, ConstImageView scene, const PipelineDescription& d,
                           const BloomParams& params);

}  // namespace bloomref::gpu
