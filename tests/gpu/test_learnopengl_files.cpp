// The LearnOpenGL tutorial's own, unmodified bloom shaders through the learnopengl preset.
//
// They are not part of this repository (their licence is the tutorial's, and bloomref copies no
// code). To run these tests, put the four files of JoeyDeVries/LearnOpenGL's
// src/5.advanced_lighting/7.bloom/ in a folder -- 7.blur.fs, 7.bloom_final.fs, 7.blur.vs and
// 7.bloom_final.vs -- for instance:
//     git clone --depth 1 https://github.com/JoeyDeVries/LearnOpenGL
//     export BLOOMREF_LEARNOPENGL_DIR=$PWD/LearnOpenGL/src/5.advanced_lighting/7.bloom
// Without the variable these tests warn and pass. The hidden test [learnopengl-corpus] also
// prints every stage's largest error on each corpus image (BLOOMREF_CORPUS) that has no NaN,
// Inf or negative value.
#include <catch2/catch.hpp>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "bloomref/gpu/device_facts.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/io.h"
#include "test_util.h"
#include "gl_fixture.h"
#include "user_shader_checks.h"

using namespace bloomref;
using gpu::UserPipelineOptions;

namespace {

std::optional<gpu::LearnOpenGLShaders> tutorial_shaders() {
  const char* dir = std::getenv("BLOOMREF_LEARNOPENGL_DIR");
  if (!dir || !*dir) {
    WARN(
        "BLOOMREF_LEARNOPENGL_DIR is not set: the tutorial's shaders are not tested (see "
        "tests/gpu/test_learnopengl_files.cpp for how to get them)");
    return std::nullopt;
  }
  const std::filesystem::path d(dir);
  gpu::LearnOpenGLShaders s;
  s.blur_fs = gpu::load_shader((d / "7.blur.fs").string());
  s.final_fs = gpu::load_shader((d / "7.bloom_final.fs").string());
  if (std::filesystem::exists(d / "7.blur.vs"))
    s.blur_vs = gpu::load_shader((d / "7.blur.vs").string());
  if (std::filesystem::exists(d / "7.bloom_final.vs"))
    s.final_vs = gpu::load_shader((d / "7.bloom_final.vs").string());
  return s;
}

// The scene of test_user_shaders.cpp's checks: a dim background in [0.05, 0.45] with bright
// texels inside, on the edges and in a corner.
Image small_scene(int w, int h) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float b = 0.05f + 0.05f * float((x * 5 + y * 3) % 9);
      float* p = img.pixel(x, y);
      p[0] = b, p[1] = 0.7f * b + 0.03f, p[2] = 0.5f * b + 0.05f, p[3] = 1.0f;
    }
  float* a = img.pixel(w / 3, h / 4);
  a[0] = a[1] = a[2] = 8.0f;
  float* c = img.pixel(w - 1, 0);
  c[0] = 20.0f;
  float* e = img.pixel(w / 2, h - 1);
  e[1] = 9.0f;
  return img;
}

// Tolerances: those of test_user_shaders.cpp (same derivations): blur 1e-5 of the largest
// input (+ one binary16 ULP for half targets), output 1e-4 absolute (+ one binary16 ULP).
test::Tolerance blur_tol(gpu::TargetFormat f) {
  return f == gpu::TargetFormat::rgba32f ? test::Tolerance{1e-5, 0, 0}
                                         : test::Tolerance{1e-5, kHalfMinDenormal, 1.0 / 1024};
}
test::Tolerance out_tol(gpu::TargetFormat f) {
  return f == gpu::TargetFormat::rgba32f ? test::Tolerance{0, 1e-4, 0}
                                         : test::Tolerance{0, 1e-4, 1.0 / 1024};
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

}  // namespace

TEST_CASE("the tutorial's shaders pass the CPU stages, f16 and f32",
          "[user-shaders][learnopengl]") {
  gpu::GlContext* ctx = test::gl_context();
  const auto shaders = tutorial_shaders();
  if (!ctx || !shaders) return;
  for (gpu::TargetFormat f : {gpu::TargetFormat::rgba16f, gpu::TargetFormat::rgba32f})
    for (auto [w, h] : {std::pair{48, 32}, std::pair{37, 23}}) {
      UserPipelineOptions opt;  // the tutorial's host state: 10 passes, exposure 1, bloom on
      opt.format = f;
      const Image scene = small_scene(w, h);
      const auto run = gpu::run_learnopengl(*ctx, scene.cview(), *shaders, opt);
      REQUIRE(run.trace.stages.size() == 13);
      for (const auto& e : test::isolated_errors(scene, run.trace, opt, opt.half_rounding,
                                                 blur_tol(f), out_tol(f))) {
        INFO(gpu::to_string(f) << " " << w << "x" << h << " " << e.stage << ": max |d| "
                               << e.max_abs << ", ratio " << e.max_ratio);
        CHECK(e.nan_gl == 0);
        CHECK(e.max_ratio <= 1.0);
      }
    }
}

TEST_CASE("broken copies of the tutorial's shaders fail at their stage",
          "[user-shaders][learnopengl]") {
  gpu::GlContext* ctx = test::gl_context();
  const auto shaders = tutorial_shaders();
  if (!ctx || !shaders) return;
  UserPipelineOptions opt;
  opt.format = gpu::TargetFormat::rgba32f;
  opt.passes = 4;
  const Image scene = small_scene(48, 32);
  SECTION("blur weight[1] 1% too large: blur.1 fails") {
    gpu::LearnOpenGLShaders s = *shaders;
    s.blur_fs.text = replaced(s.blur_fs.text, "0.1945945946", "0.1965405405");
    const auto e =
        test::isolated_errors(scene, gpu::run_learnopengl(*ctx, scene.cview(), s, opt).trace, opt,
                              opt.half_rounding, blur_tol(opt.format), out_tol(opt.format));
    CHECK(e[1].stage == "blur.1");
    CHECK(e[1].max_ratio > 10);
  }
  SECTION("the bloom added twice: output fails, the blur passes") {
    gpu::LearnOpenGLShaders s = *shaders;
    s.final_fs.text =
        replaced(s.final_fs.text, "hdrColor += bloomColor", "hdrColor += 2.0 * bloomColor");
    const auto e =
        test::isolated_errors(scene, gpu::run_learnopengl(*ctx, scene.cview(), s, opt).trace, opt,
                              opt.half_rounding, blur_tol(opt.format), out_tol(opt.format));
    CHECK(e[4].max_ratio <= 1.0);  // blur.4
    CHECK(e.back().stage == "output");
    CHECK(e.back().max_ratio > 10);
  }
}

TEST_CASE("the tutorial's shaders on the corpus: largest error per stage",
          "[.][learnopengl-corpus]") {
  gpu::GlContext* ctx = test::gl_context();
  const auto shaders = tutorial_shaders();
  if (!ctx || !shaders) return;
  // Half targets: the uploads and the CPU round as this device's render-target writes do.
  const gpu::DeviceFacts facts = gpu::measure_device_facts(*ctx);
  const HalfRounding rounding = facts.half_rounding == "toward-zero"
                                    ? HalfRounding::toward_zero
                                    : HalfRounding::nearest_even_saturate;
  std::printf("%s: half writes round %s\n", facts.renderer.c_str(), facts.half_rounding.c_str());
  for (const std::string& file : test::corpus_files()) {
    const Image scene = load_image(file).image;
    // The input policy (zero) removes NaN and Inf; negative values stay, and the tutorial's
    // final pass takes pow of a negative tone-mapped value (undefined in GLSL).
    std::size_t negative = 0;
    for (std::size_t i = 0; i < scene.values().size(); ++i)
      negative += i % 4 != 3 && scene.values()[i] < 0;
    const std::string name = std::filesystem::path(file).filename().string();
    for (gpu::TargetFormat f : {gpu::TargetFormat::rgba16f, gpu::TargetFormat::rgba32f}) {
      UserPipelineOptions opt;
      opt.format = f;
      opt.half_rounding = rounding;
      const auto run = gpu::run_learnopengl(*ctx, scene.cview(), *shaders, opt);
      const StageTrace cpu = test::cpu_trace(scene, opt, opt.half_rounding);
      std::printf("%-22s %4dx%-4d %-7s", name.c_str(), scene.width(), scene.height(),
                  gpu::to_string(f).c_str());
      double worst_ratio = 0;
      std::string worst;
      test::StageError worst_e;
      std::size_t output_nan = 0;
      for (const auto& e : test::isolated_errors(scene, run.trace, opt, opt.half_rounding,
                                                 blur_tol(f), out_tol(f))) {
        if (e.max_ratio > worst_ratio) worst_ratio = e.max_ratio, worst = e.stage, worst_e = e;
        if (e.stage == "blur.1" || e.stage == "blur.10" || e.stage == "output")
          std::printf(" %s %.3g", e.stage.c_str(), e.max_abs);
        if (e.stage == "output") output_nan = e.nan_gl;
      }
      const double e2e_blur = test::stage_error("blur.10", run.trace.find("blur.10")->image,
                                                cpu.find("blur.10")->image, 1, 0)
                                  .max_abs;
      const double e2e_out = test::stage_error("output", run.trace.find("output")->image,
                                               cpu.find("output")->image, 1, 0)
                                 .max_abs;
      std::printf(
          " | e2e blur.10 %.3g output %.3g | worst/bound %.3g (%s) | negative in %zu,"
          " NaN out %zu\n",
          e2e_blur, e2e_out, worst_ratio, worst.c_str(), negative, output_nan);
      if (worst_ratio > 1)
        std::printf("    over its bound at (%d, %d) channel %d: GL %.9g, CPU %.9g\n", worst_e.x,
                    worst_e.y, worst_e.channel, worst_e.gl, worst_e.cpu);
      if (negative == 0) CHECK(worst_ratio <= 1.0);
    }
  }
}
