// A user's own GLSL run through the learnopengl preset (gpu/user_pipeline.h): shaders written
// from docs/design.md ("Specification") with the tutorial's interface, judged against the CPU stages; the declared host
// state (format, filter, wrap, clear colour, row order) checked on inputs whose results are
// known by hand; the user's bright pass. The refusals: test_user_shader_refusals.cpp.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/half.h"
#include "gl_fixture.h"
#include "user_shader_checks.h"
#include "user_shader_sources.h"

using namespace bloomref;
using gpu::LearnOpenGLShaders;
using gpu::ShaderSource;
using gpu::UserPipelineOptions;
using test::kBlur9;
using test::kBright;
using test::kFinal;
using test::own_shaders;

namespace {

// Passes the source through, reading `horizontal` where no compiler can fold it away.
const char* kCopyBlur = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D image;
uniform bool horizontal;
void main() {
  colour = texture(image, TexCoords);
  if (!horizontal) colour.a = 0.5;
}
)glsl";

// Writes its interpolated texture coordinate; reads every host uniform where the condition
// (exposure below -1e30) never holds, so none is removed.
const char* kCoordFinal = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D scene;
uniform sampler2D bloomBlur;
uniform bool bloom;
uniform float exposure;
void main() {
  colour = vec4(TexCoords, 0.0, 1.0);
  if (exposure < -1e30 && bloom) colour = texture(scene, TexCoords) + texture(bloomBlur, TexCoords);
}
)glsl";

// A dim background between 0.05 and 0.45 (no tone-map value near 0, where gamma's slope is
// unbounded) with bright texels inside, on the edges and in a corner.
Image test_scene(int w, int h) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float b = 0.05f + 0.05f * float((x * 7 + y * 3) % 9);
      float* p = img.pixel(x, y);
      p[0] = b, p[1] = 0.8f * b + 0.02f, p[2] = 0.6f * b + 0.04f, p[3] = 1.0f;
    }
  auto set = [&](int x, int y, float r, float g, float b) {
    float* p = img.pixel(x, y);
    p[0] = r, p[1] = g, p[2] = b;
  };
  set(w / 4, h / 3, 4, 4, 4);
  set(w / 2 + 1, h / 2, 30, 12, 2);
  set(w - 2, h - 1, 0, 0, 25);
  set(0, 1, 6, 1, 1);
  return img;
}

// Tolerances, from what llvmpipe (or any GL) may do differently from the CPU's f32 order:
//  * blur, f32: the interpolated TexCoords may differ from (x + 0.5) / w by a float ULP, which
//    moves each tap by ~1e-7 texel, and the nine products and sums round in float: each well
//    under 1e-6 of the largest input; 1e-5 of it is ten times that.
//  * half targets: one ULP of binary16 (2^-10 relative; a write may round to nearest or toward
//    zero), plus the smallest half denormal.
//  * output: exp to (3 + 2|x|) ULP and pow as exp2(y log2 x) (GLSL 4.50, 4.7.1), through
//    gamma's slope, at most 2.3 for a tone-mapped value above 1 - exp(-0.05): 1e-4 absolute is
//    far above it and far below a 1% error.
test::Tolerance blur_tolerance(gpu::TargetFormat f) {
  return f == gpu::TargetFormat::rgba32f ? test::Tolerance{1e-5, 0, 0}
                                         : test::Tolerance{1e-5, kHalfMinDenormal, 1.0 / 1024};
}
test::Tolerance output_tolerance(gpu::TargetFormat f) {
  return f == gpu::TargetFormat::rgba32f ? test::Tolerance{0, 1e-4, 0}
                                         : test::Tolerance{0, 1e-4, 1.0 / 1024};
}

void check_trace_against_cpu(const Image& scene, const gpu::UserPipelineRun& run,
                             const UserPipelineOptions& opt) {
  const StageTrace& t = run.trace;
  REQUIRE(t.stages.size() == std::size_t(opt.passes) + 3);
  CHECK(t.stages.front().name == "input");
  CHECK(t.stages[1].name == "bright");
  CHECK(t.stages.back().name == "output");
  // The scene texture read back is the oracle's input stage exactly (uploaded, not computed).
  Image input(scene.width(), scene.height());
  sanitize(scene.cview(), input.view(), opt.nonfinite, gpu::storage_of(opt.format), 1);
  store(input.view(), gpu::storage_of(opt.format), opt.half_rounding, 1);
  CHECK(test::stage_error("input", t.find("input")->image, input, 0, 0).max_abs == 0);
  // ... and so is the oracle's bright image, rounded as the input is.
  Image sanitized(scene.width(), scene.height()), bright(scene.width(), scene.height());
  sanitize(scene.cview(), sanitized.view(), opt.nonfinite, gpu::storage_of(opt.format), 1);
  extract_bright(sanitized.cview(), bright.view(), opt.threshold, 1);
  store(bright.view(), gpu::storage_of(opt.format), opt.half_rounding, 1);
  CHECK(test::stage_error("bright", t.find("bright")->image, bright, 0, 0).max_abs == 0);
  for (const test::StageError& e :
       test::isolated_errors(scene, t, opt, opt.half_rounding, blur_tolerance(opt.format),
                             output_tolerance(opt.format))) {
    INFO(gpu::to_string(opt.format)
         << " " << gpu::to_string(opt.rows) << " " << scene.width() << "x" << scene.height() << " "
         << e.stage << ": max |d| " << e.max_abs << ", worst ratio " << e.max_ratio << " at ("
         << e.x << ", " << e.y << ") c" << e.channel << " gl " << e.gl << " cpu " << e.cpu);
    CHECK(e.nan_gl == 0);
    CHECK(e.max_ratio <= 1.0);
  }
}

}  // namespace

TEST_CASE("own 9-tap blur and final pass match the CPU stages", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  for (gpu::TargetFormat f :
       {gpu::TargetFormat::rgba32f, gpu::TargetFormat::rgba16f, gpu::TargetFormat::rgb16f})
    for (gpu::RowOrder rows : {gpu::RowOrder::same, gpu::RowOrder::flipped})
      for (auto [w, h] : {std::pair{40, 24}, std::pair{37, 23}}) {
        UserPipelineOptions opt;
        opt.format = f;
        opt.rows = rows;
        opt.passes = 6;
        const Image scene = test_scene(w, h);
        check_trace_against_cpu(scene,
                                gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(), opt), opt);
      }
}

TEST_CASE("a 1% weight error in the blur exceeds the blur's tolerance", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  std::string blur = kBlur9;
  const std::string w1 = "0.1945945946";
  blur.replace(blur.find(w1), w1.size(), "0.1965405405");  // x 1.01
  UserPipelineOptions opt;
  opt.passes = 1;
  const Image scene = test_scene(40, 24);
  const auto run = gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(blur), opt);
  const auto errors =
      test::isolated_errors(scene, run.trace, opt, opt.half_rounding, blur_tolerance(opt.format),
                            output_tolerance(opt.format));
  REQUIRE(errors[1].stage == "blur.1");
  CHECK(errors[1].max_ratio > 3.0);
}

TEST_CASE("bloom off: the final pass reads the scene alone", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  UserPipelineOptions opt;
  opt.format = gpu::TargetFormat::rgba32f;
  opt.passes = 2;
  opt.bloom = false;
  opt.exposure = 0.7f;
  const Image scene = test_scene(20, 10);
  const auto run = gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(), opt);
  const auto errors =
      test::isolated_errors(scene, run.trace, opt, opt.half_rounding, blur_tolerance(opt.format),
                            output_tolerance(opt.format));
  REQUIRE(errors.back().stage == "output");
  CHECK(errors.back().max_ratio <= 1.0);  // against the scene alone
  // ... and not against the scene with the bloom added.
  const Image with_bloom = test::cpu_final(scene, run.trace.find("blur.2")->image, 0.7f, 2.2f,
                                           Storage::f32, opt.half_rounding);
  CHECK(
      test::stage_error("output", run.trace.find("output")->image, with_bloom, 1e-4, 0).max_ratio >
      10);
}

TEST_CASE("the trace is in bloomref's orientation for either row order", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const int w = 8, h = 5;
  Image scene(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = scene.pixel(x, y);
      p[0] = float(2 + x), p[1] = float(2 + 10 * y), p[2] = 3.0f, p[3] = 1.0f;  // all bright
    }
  for (gpu::RowOrder rows : {gpu::RowOrder::same, gpu::RowOrder::flipped}) {
    UserPipelineOptions opt;
    opt.format = gpu::TargetFormat::rgba32f;
    opt.filter = gpu::TextureFilter::nearest;
    opt.rows = rows;
    opt.passes = 1;
    const auto run =
        gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(kCopyBlur, kCoordFinal), opt);
    const Image& copy = run.trace.find("blur.1")->image;
    const Image& out = run.trace.find("output")->image;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        INFO(gpu::to_string(rows) << " (" << x << ", " << y << ")");
        // A copy of the bright image comes back where it was, in either row order.
        CHECK(copy.pixel(x, y)[0] == float(2 + x));
        CHECK(copy.pixel(x, y)[1] == float(2 + 10 * y));
        // The texture coordinate: s = (x + 0.5) / w; t counts from GL's row 0, which is the
        // image's top row in `same` and its bottom row in `flipped`.
        const double s = (x + 0.5) / w, t = (y + 0.5) / h;
        CHECK(out.pixel(x, y)[0] == Approx(s).margin(1e-6));
        CHECK(out.pixel(x, y)[1] == Approx(rows == gpu::RowOrder::same ? t : 1 - t).margin(1e-6));
      }
  }
}

TEST_CASE("declared host state: wrap, filter, clear colour and format", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const int w = 8, h = 2;
  Image scene(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = scene.pixel(x, y);
      p[0] = p[1] = p[2] = float(x + 2), p[3] = 1.0f;  // every texel bright, value x + 2
    }
  // Reads 1.75 texels to the left: texel coordinate x + 0.5 - 1.75 = x - 1.25, a quarter
  // texel from a texel centre and never on a texel edge, so nearest has one answer.
  const char* probe = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D image;
uniform bool horizontal;
void main() {
  float dx = 1.0 / float(textureSize(image, 0).x);
  colour = texture(image, TexCoords - vec2(1.75 * dx, 0.0));
  if (!horizontal) colour.a = 0.5;
}
)glsl";
  auto blur1 = [&](gpu::TextureWrap wrap, gpu::TextureFilter filter) {
    UserPipelineOptions opt;
    opt.format = gpu::TargetFormat::rgba32f;
    opt.wrap = wrap;
    opt.filter = filter;
    opt.passes = 1;
    return gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(probe), opt)
        .trace.find("blur.1")
        ->image;
  };
  SECTION("wrap at the left edge, nearest: x = 0 reads texel coordinate -1.25") {
    // clamp -> texel 0 (value 2); repeat -> w - 1.25, texel w - 2 (value w); mirrored ->
    // 1.25, texel 1 (value 3).
    CHECK(blur1(gpu::TextureWrap::clamp_to_edge, gpu::TextureFilter::nearest).pixel(0, 0)[0] ==
          2.0f);
    CHECK(blur1(gpu::TextureWrap::repeat, gpu::TextureFilter::nearest).pixel(0, 0)[0] == float(w));
    CHECK(blur1(gpu::TextureWrap::mirrored_repeat, gpu::TextureFilter::nearest).pixel(0, 0)[0] ==
          3.0f);
  }
  SECTION(
      "filter: texel coordinate x - 1.25 is texel x - 2 (nearest) or 3:1 between x - 2 and "
      "x - 1 (linear)") {
    const Image nearest = blur1(gpu::TextureWrap::clamp_to_edge, gpu::TextureFilter::nearest);
    const Image linear = blur1(gpu::TextureWrap::clamp_to_edge, gpu::TextureFilter::linear);
    for (int x = 2; x < w; ++x) {
      INFO("x " << x);
      CHECK(nearest.pixel(x, 1)[0] == float(x));  // texel x - 2 holds x
      CHECK(linear.pixel(x, 1)[0] == Approx(0.75 * x + 0.25 * (x + 1)).margin(1e-5));
    }
  }
  SECTION("clear colour: what a vertex shader leaves uncovered") {
    const char* left_half = R"glsl(#version 330 core
layout(location = 0) in vec3 aPos;
layout(location = 1) in vec2 aTexCoords;
out vec2 TexCoords;
void main() {
  TexCoords = aTexCoords;
  gl_Position = vec4(0.5 * aPos.x - 0.5, aPos.y, aPos.z, 1.0);
}
)glsl";
    LearnOpenGLShaders s = own_shaders(kCopyBlur, kFinal);
    s.final_vs = ShaderSource{"left_half.vs", left_half};
    UserPipelineOptions opt;
    opt.format = gpu::TargetFormat::rgba32f;
    opt.passes = 1;
    opt.clear_colour = {0.25f, 0.5f, 0.75f, 0.125f};
    const Image out = gpu::run_learnopengl(*ctx, scene.cview(), s, opt).trace.find("output")->image;
    for (int x = w / 2; x < w; ++x) {
      CHECK(out.pixel(x, 1)[0] == 0.25f);
      CHECK(out.pixel(x, 1)[2] == 0.75f);
      CHECK(out.pixel(x, 1)[3] == 0.125f);
    }
    CHECK(out.pixel(0, 1)[3] == 1.0f);  // drawn
  }
  SECTION("format: a third stored as float or as half; RGB16F reads alpha back as 1") {
    const char* third = R"glsl(#version 330 core
in vec2 TexCoords;
out vec4 colour;
uniform sampler2D scene;
uniform sampler2D bloomBlur;
uniform bool bloom;
uniform float exposure;
void main() {
  colour = vec4(1.0 / 3.0);
  if (exposure < -1e30 && bloom) colour = texture(scene, TexCoords) + texture(bloomBlur, TexCoords);
}
)glsl";
    const float third_f = 1.0f / 3.0f;
    // binary16 neighbours of 1/3: 0x3555 = 0.333251953125 (below), 0x3556 = 0.33349609375.
    for (gpu::TargetFormat f :
         {gpu::TargetFormat::rgba32f, gpu::TargetFormat::rgba16f, gpu::TargetFormat::rgb16f}) {
      UserPipelineOptions opt;
      opt.format = f;
      opt.passes = 1;
      const Image out =
          gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(kCopyBlur, third), opt)
              .trace.find("output")
              ->image;
      INFO(gpu::to_string(f));
      const float v = out.pixel(1, 1)[0];
      if (f == gpu::TargetFormat::rgba32f)
        CHECK(std::fabs(v - third_f) <= 2e-7f);
      else
        CHECK((v == 0.333251953125f || v == 0.33349609375f));
      CHECK(out.pixel(1, 1)[3] == (f == gpu::TargetFormat::rgb16f ? 1.0f : v));
    }
  }
}

// The MRT form of test::kBright (as the tutorial's 7.bloom.fs writes FragColor and
// BrightColor): location 0 is the scene the final pass reads -- here twice the scene, so that
// the test can tell.
const char* kBrightMrt = R"glsl(#version 330 core
in vec2 TexCoords;
layout(location = 0) out vec4 colour;
layout(location = 1) out vec4 bright;
uniform sampler2D scene;
uniform float threshold;
void main() {
  vec3 c = texture(scene, TexCoords).rgb;
  colour = vec4(2.0 * c, 1.0);
  float l = dot(c, vec3(0.2126, 0.7152, 0.0722));
  bright = l > threshold ? vec4(c, 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}
)glsl";

TEST_CASE("the user's bright pass, one output or two", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const Image scene = test_scene(40, 24);  // no luminance within 0.5 of the threshold 1.5
  UserPipelineOptions opt;
  opt.format = gpu::TargetFormat::rgba32f;
  opt.passes = 2;
  opt.threshold = 1.5f;
  Image bright(40, 24);
  extract_bright(scene.cview(), bright.view(), 1.5f, 1);
  // Each stage within the bounds of user_shader_checks.h (the bright pass's lookups of the
  // scene at interpolated coordinates included).
  auto check_stages = [&](const gpu::UserPipelineRun& run) {
    for (const auto& e :
         test::isolated_errors(scene, run.trace, opt, opt.half_rounding, blur_tolerance(opt.format),
                               output_tolerance(opt.format))) {
      INFO(e.stage << ": max |d| " << e.max_abs << ", ratio " << e.max_ratio);
      CHECK(e.max_ratio <= 1.0);
    }
  };
  SECTION("one output: the bright image") {
    LearnOpenGLShaders s = own_shaders();
    s.bright_fs = ShaderSource{"bright.fs", kBright};
    const auto run = gpu::run_learnopengl(*ctx, scene.cview(), s, opt);
    CHECK(run.bright_source == "bright.fs");
    CHECK(run.programs.front().program == "bright");
    CHECK(test::stage_error("input", run.trace.find("input")->image, scene, 0, 0).max_abs == 0);
    check_stages(run);
    // Not vacuous: the bright texels are where the CPU's are (a texel off by one lookup error
    // is within 2e-4 of its value; a missing or extra bright texel is off by its whole value).
    CHECK(test::stage_error("bright", run.trace.find("bright")->image, bright, 1e-3, 0).max_ratio <=
          1.0);
  }
  SECTION("two outputs: location 1 is the bright image, location 0 the final pass's scene") {
    LearnOpenGLShaders s = own_shaders();
    s.bright_fs = ShaderSource{"bright_mrt.fs", kBrightMrt};
    const auto run = gpu::run_learnopengl(*ctx, scene.cview(), s, opt);
    Image twice = scene;
    for (std::size_t i = 0; i < twice.values().size(); ++i)
      if (i % 4 != 3) twice.values()[i] *= 2.0f;
    const Image look = test::lookup_term(twice, 1, 1);
    CHECK(
        test::stage_error("input", run.trace.find("input")->image, twice, 0, 0, &look).max_ratio <=
        1.0);
    check_stages(run);  // the output from the trace's input: twice the scene
    CHECK(test::stage_error("input", run.trace.find("input")->image, scene, 1e-3, 0).max_ratio > 1);
  }
  SECTION("a threshold uniform is optional; a scene sampler is not") {
    std::string fixed = kBright;
    fixed.replace(fixed.find("> threshold"), 11, "> 1.5");
    LearnOpenGLShaders s = own_shaders();
    s.bright_fs = ShaderSource{"fixed.fs", fixed};
    CHECK_NOTHROW(gpu::check_learnopengl(*ctx, s, opt));
    s.bright_fs->text = R"glsl(#version 330 core
out vec4 bright;
void main() { bright = vec4(1.0); }
)glsl";
    CHECK_THROWS_WITH(gpu::check_learnopengl(*ctx, s, opt), Catch::Contains("sampler 'scene'"));
  }
}

TEST_CASE("no blur passes: the final pass reads the bright image", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const Image scene = test_scene(20, 12);
  UserPipelineOptions opt;
  opt.format = gpu::TargetFormat::rgba32f;
  opt.passes = 0;
  const auto run = gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(), opt);
  REQUIRE(run.trace.stages.size() == 3);
  const auto errors =
      test::isolated_errors(scene, run.trace, opt, opt.half_rounding, blur_tolerance(opt.format),
                            output_tolerance(opt.format));
  REQUIRE(errors.back().stage == "output");  // from the input and the bright image
  CHECK(errors.back().max_ratio <= 1.0);
}

TEST_CASE("an 8-bit final target: codes, within half a code of the CPU's output", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  UserPipelineOptions opt;
  opt.format = gpu::TargetFormat::rgba32f;
  opt.final_target = gpu::FinalTarget::rgba8;
  opt.passes = 4;
  const Image scene = test_scene(40, 24);
  const auto run = gpu::run_learnopengl(*ctx, scene.cview(), own_shaders(), opt);
  CHECK(run.output_code_bits == 8);
  // A UNORM8 target holds k / 255 (GL 4.6, 2.3.5.2: conversion to normalized fixed point).
  const Image& out = run.trace.find("output")->image;
  double worst_code_offset = 0;
  for (float v : out.values()) worst_code_offset = std::max(worst_code_offset, std::abs(v * 255.0 - std::round(v * 255.0)));
  CHECK(worst_code_offset < 1e-4);
  // The stages before it are unchanged, and the output is the CPU's rounded to a code: the
  // f32 output tolerance plus half a code.
  for (const test::StageError& e :
       test::isolated_errors(scene, run.trace, opt, opt.half_rounding, blur_tolerance(opt.format),
                             test::Tolerance{0, 1e-4 + 0.5 / 255, 0})) {
    INFO(e.stage << ": max |d| " << e.max_abs << ", worst ratio " << e.max_ratio);
    CHECK(e.max_ratio <= 1.0);
  }
  CHECK(gpu::parse_final_target("GL_RGBA8") == gpu::FinalTarget::rgba8);
  CHECK_THROWS_AS(gpu::parse_final_target("rgb565"), ParamError);
}
