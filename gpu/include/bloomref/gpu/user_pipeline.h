// bloomref GPU — running a user's own, unmodified GLSL bloom shaders headless, the way their
// host code drives them, and reading back every pass as a StageTrace the parity library judges.
//
// Preset `learnopengl` (JoeyDeVries/LearnOpenGL, src/5.advanced_lighting/7.bloom/bloom.cpp, the
// host code the tutorial's 7.blur.fs and 7.bloom_final.fs are written for):
//  * every pass draws a full-screen quad: a triangle strip of four vertices, attribute location
//    0 `aPos` (vec3, the corners at z = 0) and location 1 `aTexCoords` (vec2, 0 at the left and
//    bottom corners, 1 at the right and top ones);
//  * bright: the oracle's (extract_bright on the CPU, stored as the target format stores it,
//    uploaded), or the user's bright-pass fragment shader (below);
//  * blur: `passes` draws into two ping-pong framebuffers, the first reading the bright texture
//    and each later one the other framebuffer's texture; pass k sets `horizontal` to true when k
//    is odd (the first pass is horizontal); the blur program's sampler `image` is unit 0;
//  * final: samplers `scene` (unit 0: the scene texture) and `bloomBlur` (unit 1: the last blur
//    pass's texture, or the bright texture when passes is 0), uniforms `bloom` (bool) and
//    `exposure` (float); it draws into a target of the same format.
// Host state is declared in UserPipelineOptions, never assumed: target format, filter, wrap,
// clear colour (every target is cleared to it before its pass draws), passes, exposure, bloom.
// Shaders that follow these passes under other names declare them in a PresetLayout: every name
// above (attributes, samplers, uniforms, the pass-through's varying), a direction vector in place
// of the `horizontal` flag, and further uniforms set to given values or to the targets' texel
// size or size.
//
// Interface check (before any pass runs): each linked program's active uniforms and attributes
// are read back (glGetProgramiv GL_ACTIVE_UNIFORMS / GL_ACTIVE_ATTRIBUTES) and compared with what
// the preset sets. Refused, with a UserShaderError naming the file and the name:
//  * a sampler or uniform the preset requires that is missing (a compiler drops a uniform the
//    shader never reads, so an unused `exposure` is missing too), or of another type;
//  * a sampler the preset does not know (it would read unit 0), a uniform block;
//  * a uniform the preset does not know whose value after linking is zero in every component:
//    the host never sets it, so it is used at 0. One with an initialiser (the tutorial's
//    `uniform float weight[5] = float[](...)`) keeps its initialiser and is accepted;
//  * an attribute at a location other than 0 or 1 (the host binds `aPos` and `aTexCoords`
//    there with glBindAttribLocation; a `layout(location = ...)` in the shader wins);
//  * a program without a fragment output at location 0;
//  * a fragment shader input that the vertex shader does not declare as an output (by name, in
//    the shaders' text; interface blocks and shaders with macros are left to the linker): GL
//    leaves it undefined, and llvmpipe links the program and reads 0.
// A shader that does not compile, or programs that do not link, are a UserShaderError naming
// the file(s), with the compiler's log.
//
// Orientation: bloomref images have row 0 at the top; GL's texture rows count from the bottom.
// RowOrder::same uploads image row y as texel row y (texture coordinate t = (y + 0.5) / h counts
// from the top, as the CPU oracle's coordinates do, and as bloomref's own GL path stores images);
// RowOrder::flipped uploads the top row as GL's row h - 1 (as a window would show it). Either
// way every readback is put back in bloomref's orientation, so the trace's images line up with
// the oracle's.
#pragma once

#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bloomref/error.h"
#include "bloomref/executor.h"
#include "bloomref/gpu/context.h"
#include "bloomref/half.h"
#include "bloomref/params.h"

namespace bloomref::gpu {

/// A user's shader cannot be used: it does not compile or link, or its interface is not the
/// preset's. file() names the shader file (or files, for a link error); the CLI exits 2.
class UserShaderError : public InputError {
 public:
  using InputError::InputError;
};

/// Internal formats of every texture and render target of the user's pipeline.
/// r11f_g11f_b10f: packed unsigned floats (no alpha, no sign), as engines store HDR colour.
/// rgba8: 8-bit unsigned normalised (clamped to [0, 1], 255ths), as LDR targets store colour.
enum class TargetFormat { rgba16f, rgb16f, rgba32f, r11f_g11f_b10f, rgba8 };
enum class TextureFilter { linear, nearest };
enum class TextureWrap { clamp_to_edge, repeat, mirrored_repeat, clamp_to_border };
enum class RowOrder { same, flipped };
/// Where the final pass draws: a target of `format` like every other pass, or an 8-bit UNORM
/// target as the tutorial's window (default framebuffer) is, whose codes are then what is judged.
enum class FinalTarget { same, rgba8 };

std::string to_string(TargetFormat f);
std::string to_string(TextureFilter f);
std::string to_string(TextureWrap w);
std::string to_string(RowOrder r);
std::string to_string(FinalTarget t);
// parse_* accept the names to_string gives (and GL's: "GL_RGBA16F", "GL_LINEAR",
// "GL_CLAMP_TO_EDGE", ...); they throw ParamError listing the accepted names.
TargetFormat parse_target_format(const std::string& s);
TextureFilter parse_texture_filter(const std::string& s);
TextureWrap parse_texture_wrap(const std::string& s);
RowOrder parse_row_order(const std::string& s);
FinalTarget parse_final_target(const std::string& s);
/// f16 for the half formats (and the packed R11F_G11F_B10F, whose values f16 holds exactly),
/// f32 for RGBA32F, rgba8 for RGBA8: the storage the oracle must be run with.
Storage storage_of(TargetFormat f);
/// The target format that stores as `s` does.
TargetFormat target_format_of(Storage s);

/// One shader's text and the file it came from (named in every error about it).
struct ShaderSource {
  std::string path;
  std::string text;
};
/// Reads a shader file unmodified. Throws InputError naming the file when it cannot be read.
ShaderSource load_shader(const std::string& path);

/// The user's shaders for the `learnopengl` preset. Vertex shaders left out are bloomref's
/// pass-through (gpu/shaders/user_quad.vert: TexCoords = aTexCoords, gl_Position = (aPos, 1)).
struct LearnOpenGLShaders {
  ShaderSource blur_fs, final_fs;
  std::optional<ShaderSource> blur_vs, final_vs;
  /// Optional bright pass, drawn over the quad: sampler `scene` (unit 0: the scene texture),
  /// optional uniform `threshold` (float). With one output it writes the bright image at
  /// location 0; with an output at location 1 (the tutorial's 7.bloom.fs writes FragColor and
  /// BrightColor), location 1 is the bright image and location 0 becomes the scene the final
  /// pass reads (and the trace's `input`).
  std::optional<ShaderSource> bright_fs, bright_vs;
};

/// A value the host sets a uniform of the user's layout to: given numbers (a float, vec2, vec3 or
/// vec4 by their count), or, computed from the render targets (all the scene's size), their
/// texel size (1 / width, 1 / height), their size in pixels (width, height), or one texel step
/// along x (1 / width, 0) or y (0, 1 / height).
struct LayoutValue {
  enum Kind { numbers, texel_size, target_size, texel_x, texel_y };
  Kind kind = numbers;
  std::vector<float> values;  ///< kind numbers: 1 to 4 of them
  int components() const { return kind == numbers ? static_cast<int>(values.size()) : 2; }
  /// The values to set on targets of w x h.
  std::vector<float> at(int w, int h) const;
};

/// The user's names for what the preset's host code binds and sets, for shaders that follow the
/// tutorial's passes under other names (a layout file, docs/check.md): each defaults to the
/// tutorial's own name.
struct PresetLayout {
  std::string file;  ///< the layout file, named in messages ("" = the tutorial's names)
  /// Attributes 0 and 1 of the user's vertex shaders.
  std::string position = "aPos", texcoords = "aTexCoords";
  /// The texture coordinate bloomref's pass-through vertex shader hands to a fragment shader
  /// whose vertex shader is not given.
  std::string varying = "TexCoords";
  std::string bright_scene = "scene", threshold = "threshold";
  std::string blur_image = "image", horizontal = "horizontal";
  /// Instead of the `horizontal` flag (when not empty): a float vector uniform set to
  /// `direction_h` on horizontal passes and `direction_v` on vertical ones (as many components
  /// each, 1 to 4), e.g. (1, 0) and (0, 1), or texel_x and texel_y.
  std::string direction;
  LayoutValue direction_h, direction_v;
  std::string final_scene = "scene", final_bloom = "bloomBlur", bloom = "bloom",
              exposure = "exposure";
  /// Further uniforms the host sets, per program, by the user's name (in that name's order).
  std::vector<std::pair<std::string, LayoutValue>> bright_set, blur_set, final_set;
};

struct UserPipelineOptions {
  TargetFormat format = TargetFormat::rgba16f;  ///< the tutorial's GL_RGBA16F
  TextureFilter filter = TextureFilter::linear;
  TextureWrap wrap = TextureWrap::clamp_to_edge;
  std::array<float, 4> clear_colour = {0.0f, 0.0f, 0.0f, 1.0f};
  int passes = 10;        ///< the tutorial's `amount`
  /// The tutorial's `bool horizontal = true` before its loop; false: the first pass is vertical.
  bool first_horizontal = true;
  float exposure = 1.0f;  ///< uniform `exposure`
  bool bloom = true;      ///< uniform `bloom`
  /// The oracle's bright pass (luminance > threshold), and the user's bright shader's
  /// `threshold` uniform when it has one.
  float threshold = 1.0f;
  LumaRule luma;  ///< the oracle's bright pass's luminance
  /// The scene's non-finite policy, applied on the CPU before upload (the oracle's `input`).
  NonFinite nonfinite = NonFinite::zero;
  /// How the scene and the oracle's bright image are rounded to binary16 for a half target
  /// before upload (the oracle must use the same: parity's compare_with_oracle takes it from the
  /// device profile).
  HalfRounding half_rounding = HalfRounding::nearest_even_saturate;
  RowOrder rows = RowOrder::same;
  FinalTarget final_target = FinalTarget::same;
  int threads = 0;  ///< CPU threads for the oracle's input and bright stages
  PresetLayout layout;  ///< the names the user's shaders use (default: the tutorial's)
};

/// The options a bloomref run with `params` declares: passes, exposure, threshold, non-finite
/// policy, and RGBA16F / RGBA32F from the storage. Throws ParamError for what the preset cannot
/// run (method mip). The kernel, gamma and strength are the user's shaders' own: the oracle's
/// are only what they are judged against.
UserPipelineOptions options_for(const BloomParams& params);

/// One active uniform or attribute as the linked program reports it.
struct ActiveVariable {
  std::string name;  ///< without "[0]"
  std::string type;  ///< GLSL type name ("float", "bool", "sampler2D", "vec3", ...)
  int size = 1;      ///< array length
  int location = -1;
  std::string role;  ///< "set by the host: ...", "kept at its initialiser", ...
};

struct ProgramInterface {
  std::string program;                     ///< "bright", "blur" or "final"
  std::string vertex_file, fragment_file;  ///< "" for bloomref's own vertex shader
  std::vector<ActiveVariable> uniforms, attributes;
  std::string log;  ///< the compiler's and linker's messages (warnings), if any
};

struct UserPipelineRun {
  /// `input` (the scene texture as stored), `bright`, `blur.1` ... `blur.N`, `output`, every one
  /// read back in bloomref's orientation; RGB targets read back with alpha 1. Timings are wall
  /// times around each pass's draw followed by glFinish.
  StageTrace trace;
  std::vector<ProgramInterface> programs;
  std::string bright_source;  ///< "oracle" or the bright shader's file
  int output_code_bits = 0;   ///< 8 when the final pass drew into an 8-bit target
};

/// Compiles, links and checks the user's programs against the preset without drawing: the
/// refusals above, before any work. Throws UserShaderError; GlError for a GL failure.
std::vector<ProgramInterface> check_learnopengl(GlContext& ctx, const LearnOpenGLShaders& shaders,
                                                const UserPipelineOptions& opt);

/// Runs the user's pipeline on `scene` (any size GL allows). Throws UserShaderError (bad
/// shaders), ParamError (bad options, or non-finite values under NonFinite::error), GlError.
/// The caller makes the context: GlContext::create throws GlUnavailable where there is no GL
/// (the CLI exits 3; tests skip unless BLOOMREF_REQUIRE_GL is set, tests/support/gl_fixture.h).
UserPipelineRun run_learnopengl(GlContext& ctx, ConstImageView scene,
                                const LearnOpenGLShaders& shaders,
                                const UserPipelineOptions& opt = {});

// Preset `learnopengl-pbb` (JoeyDeVries/LearnOpenGL, src/8.guest/2022/6.physically_based_bloom/
// physically_based_bloom.cpp, the host code the article's 6.new_downsample.fs, 6.new_upsample.fs
// and 6.bloom_final.fs are written for; programChoice 3):
//  * the scene and the bright image (luminance > threshold, as 6.bloom.fs writes BrightColor:
//    the oracle's, stored as the scene format stores it) are uploaded to RGBA16F textures;
//  * `levels` mips of (int)(size * 0.5^k) in `level_format` (GL_R11F_G11F_B10F), GL_LINEAR,
//    GL_CLAMP_TO_EDGE; nothing clears them;
//  * downsample: mip k drawn from mip k-1 (the bright image for k = 1) with the viewport at the
//    mip's size; sampler `srcTexture` (unit 0); `srcResolution` (vec2) the float size of what it
//    reads: the image's, then size * 0.5^(k-1), in float; `mipLevel` (int) 0 on the first pass
//    when `karis`, then 1. Each mip is read back as `down.k`;
//  * upsample: blending on, glBlendFunc(GL_ONE, GL_ONE), GL_FUNC_ADD; mip k-1 drawn from mip k
//    for k = levels-1 .. 1, `filterRadius` (float) the radius; each read back as `up.k-1`
//    (bloomref's level numbering: up.k = down.k + tent of up.k+1);
//  * final: samplers `scene` (unit 0) and `bloomBlur` (unit 1: mip 0), `exposure` (float),
//    `programChoice` (int, 3); `bloomStrength` is the shader's own (its initialiser, 0.04 in the
//    article), which the host never sets. Read back as `output`.
// Vertex shaders left out are bloomref's pass-through, writing the texture coordinate under the
// name the fragment shader reads (`texCoord` in the article's downsample and upsample shaders,
// `TexCoords` in its final shader).
struct MipChainShaders {
  ShaderSource downsample_fs, upsample_fs, final_fs;
  std::optional<ShaderSource> downsample_vs, upsample_vs, final_vs;
};

struct MipChainOptions {
  TargetFormat format = TargetFormat::rgba16f;              ///< the scene's and bright image's
  TargetFormat level_format = TargetFormat::r11f_g11f_b10f; ///< the mips'
  int levels = 6;               ///< the article's num_bloom_mips
  bool karis = true;            ///< mipLevel 0 on the first downsample (mKarisAverageOnDownsample)
  float filter_radius = 0.005f; ///< the article's bloomFilterRadius
  float exposure = 1.0f;
  int program_choice = 3;       ///< 6.bloom_final.fs: 3 = the mip-chain bloom
  float threshold = 1.0f;       ///< the bright image: luminance > threshold
  LumaRule luma;                ///< that luminance
  NonFinite nonfinite = NonFinite::zero;
  HalfRounding half_rounding = HalfRounding::nearest_even_saturate;
  RowOrder rows = RowOrder::same;
  FinalTarget final_target = FinalTarget::same;
  int threads = 0;
  /// NaN: `bloomStrength` keeps the shader's initialiser, as the article's host leaves it;
  /// else the host sets it (bloomref's own shaders, execute_gl_mip_chain).
  float strength = NAN;
};

/// The options a bloomref run with `params` declares (method mip): levels, Karis, radius,
/// exposure, threshold, policy, the levels' format from the chain storage. Throws ParamError for
/// what the preset's host code cannot run (method gaussian).
MipChainOptions mip_chain_options_for(const BloomParams& params);

/// Compiles, links and checks the three programs against the preset without drawing.
std::vector<ProgramInterface> check_mip_chain(GlContext& ctx, const MipChainShaders& shaders,
                                              const MipChainOptions& opt);

/// Runs the article's host code on `scene` with the user's shaders. The trace holds `input`,
/// `bright`, `down.1` .. `down.K`, `up.K-1` .. `up.1` and `output`; `strength` is set to the
/// final shader's bloomStrength (NaN when it has none). Throws as run_learnopengl does.
struct MipChainRun {
  UserPipelineRun run;
  float strength = NAN;
};
MipChainRun run_mip_chain(GlContext& ctx, ConstImageView scene, const MipChainShaders& shaders,
                          const MipChainOptions& opt = {});

/// bloomref's own shaders for the article's chain (gpu/shaders/pbb_*.frag) run by the same host:
/// the GL side of `compare` for a plan with the article's choices (prefilter bright, Karis
/// group-srgb or none, halved-float texel step, a radius in texture coordinates, a bilinear
/// bloom, mix). Throws ParamError for another combination.
/// Bevy's layout (bevy_layout) goes to execute_gl_bevy.
StageTrace execute_gl_mip_chain(GlContext& ctx, const BloomParams& params, ConstImageView scene);

/// Whether `params` is a chain the article's host code draws with bloomref's pbb shaders
/// (preset learnopengl-pbb and its overrides): prefilter bright, Karis group-srgb or none, the
/// halved-float texel step, a radius in texture coordinates, a bilinear bloom, mix, gamma 2.2.
bool article_layout(const BloomParams& params);

/// Whether `params` is a chain Bevy's render graph draws (preset bevy and its overrides):
/// prefilter none, the texture's texel step, a tent of one texel, the composite before the tone
/// map, Karis group-linear or none.
bool bevy_layout(const BloomParams& params);

/// bloomref's own shaders for Bevy's bloom (gpu/shaders/bevy_*.frag) in its render graph's order
/// (gpu/src/bevy_host.cpp): the trace holds `input`, `down.1` .. `down.K`, `up.K-1` .. `up.1`,
/// `composite` (the last upsample blended into the scene) and `output`. Throws ParamError
/// unless bevy_layout(params).
StageTrace execute_gl_bevy(GlContext& ctx, const BloomParams& params, ConstImageView scene);

/// Whether `params` uses none of the choices only Unity URP's layout has (its filters, lerp,
/// constant weights, its soft threshold's arithmetic, clamp and level count), nor three.js's.
bool unity_free(const BloomParams& params);

/// Whether level k (0: the first) of Bevy's layout is the 4-tap box (--first-downsample box4,
/// --downsample box4), which Bevy's layout draws with bloomref's box4_downsample.frag.
bool box4(const BloomParams& params, int k);

/// Whether `params` is a chain Unity URP's SetupBloom draws (preset unity-urp and its overrides).
bool unity_layout(const BloomParams& params);

/// bloomref's own shaders for Unity URP's bloom (gpu/shaders/unity_*.frag) in SetupBloom's order
/// (gpu/src/unity_host.cpp): the trace holds `input`, `down.1` .. `down.K`, `up.K-1` .. `up.1`,
/// `composite` and `output`. Throws ParamError unless unity_layout(params).
StageTrace execute_gl_unity(GlContext& ctx, const BloomParams& params, ConstImageView scene);

/// Whether `params` is a chain three.js's BloomNode draws (preset threejs and its overrides).
bool threejs_layout(const BloomParams& params);

/// bloomref's own shaders for three.js's bloom (gpu/shaders/threejs_*.frag) in BloomNode's order,
/// run from its description (preset_description): the trace holds `input`, `down.1` (the high
/// pass), `down.2` .. `down.K` (the blurred mips), `up.1` (their composite), `composite` and
/// `output`. Throws ParamError unless threejs_layout(params).
StageTrace execute_gl_threejs(GlContext& ctx, const BloomParams& params, ConstImageView scene);

}  // namespace bloomref::gpu
