// The learnopengl preset refuses what its host code cannot drive (gpu/user_pipeline.h): a
// shader that does not compile or link, a sampler or uniform it requires that is missing or
// mistyped, one it does not know; and it reports how it sets each uniform it accepts.
#include <catch2/catch.hpp>

#include "bloomref/gpu/user_pipeline.h"
#include "gl_fixture.h"
#include "user_shader_sources.h"

using namespace bloomref;
using gpu::LearnOpenGLShaders;
using gpu::ShaderSource;
using gpu::UserPipelineOptions;
using test::kBlur9;
using test::kFinal;
using test::own_shaders;

TEST_CASE("shaders that do not fit the preset are refused, naming the file and the name",
          "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const UserPipelineOptions opt;
  auto refusal = [&](const LearnOpenGLShaders& s, const UserPipelineOptions& o) -> std::string {
    try {
      gpu::check_learnopengl(*ctx, s, o);
    } catch (const gpu::UserShaderError& e) {
      return e.file() + " | " + e.what();
    }
    return "accepted";
  };
  auto replaced = [](std::string text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    REQUIRE(at != std::string::npos);
    return text.replace(at, from.size(), to);
  };
  CHECK(refusal(own_shaders(), opt) == "accepted");
  SECTION("a compile error: the file and the compiler's log") {
    const std::string m =
        refusal(own_shaders(replaced(kBlur9, "sum += texture", "sum += textur")), opt);
    CHECK_THAT(m,
               Catch::Contains("test_blur9.fs | test_blur9.fs: fragment shader does not compile"));
    CHECK_THAT(m, Catch::Contains("textur"));  // the log names the culprit
  }
  SECTION("a sampler the preset requires is missing") {
    const std::string m = refusal(
        own_shaders(kBlur9,
                    replaced(kFinal, "hdr += texture(bloomBlur, TexCoords).rgb", "hdr *= 2.0")),
        opt);
    CHECK_THAT(m, Catch::StartsWith("test_final.fs | "));
    CHECK_THAT(m, Catch::Contains("sampler 'bloomBlur'"));
    CHECK_THAT(m, Catch::Contains("missing"));
  }
  SECTION("a uniform the preset requires is unused, so missing") {
    const std::string m =
        refusal(own_shaders(kBlur9, replaced(kFinal, "-hdr * exposure", "-hdr")), opt);
    CHECK_THAT(m, Catch::Contains("uniform 'exposure'"));
    CHECK_THAT(m, Catch::Contains("missing"));
  }
  SECTION("an unknown uniform: refused without an initialiser, kept with one") {
    const std::string base = replaced(kBlur9, "uniform bool horizontal;",
                                      "uniform bool horizontal;\nuniform float spread@;");
    const std::string used =
        replaced(base, "vec2 d = horizontal ? vec2(texel.x, 0.0) : vec2(0.0, texel.y);",
                 "vec2 d = spread * (horizontal ? vec2(texel.x, 0.0) : vec2(0.0, texel.y));");
    const std::string m = refusal(own_shaders(replaced(used, "@", "")), opt);
    CHECK_THAT(m, Catch::StartsWith("test_blur9.fs | "));
    CHECK_THAT(m, Catch::Contains("uniform 'spread'"));
    CHECK_THAT(m, Catch::Contains("used at 0"));
    CHECK(refusal(own_shaders(replaced(used, "@", " = 1.0")), opt) == "accepted");
  }
  SECTION("an unknown array: refused when every element is 0, kept when one is not") {
    const std::string used = replaced(
        replaced(kFinal, "uniform float exposure;", "uniform float exposure;\nuniform vec2 k[3]@;"),
        "vec3 mapped", "hdr *= k[0].x + k[1].y + k[2].x;\n  vec3 mapped");
    const std::string m = refusal(own_shaders(kBlur9, replaced(used, "@", "")), opt);
    CHECK_THAT(m, Catch::Contains("uniform 'k' (vec2)"));
    CHECK(refusal(own_shaders(kBlur9, replaced(used, "@", " = vec2[](vec2(0.0), vec2(0.0), "
                                                       "vec2(1.0, 0.0))")),
                  opt) == "accepted");
  }
  SECTION("an unknown sampler") {
    const std::string m = refusal(
        own_shaders(kBlur9,
                    replaced(replaced(kFinal, "uniform bool bloom;",
                                      "uniform bool bloom;\nuniform sampler2D dirt;"),
                             "vec3 mapped", "hdr += texture(dirt, TexCoords).rgb;\n  vec3 mapped")),
        opt);
    CHECK_THAT(m, Catch::Contains("sampler 'dirt'"));
  }
  SECTION("a host uniform of another type") {
    const std::string m =
        refusal(own_shaders(replaced(
                    replaced(kBlur9, "uniform bool horizontal;", "uniform float horizontal;"),
                    "vec2 d = horizontal ?", "vec2 d = horizontal > 0.5 ?")),
                opt);
    CHECK_THAT(m, Catch::Contains("uniform 'horizontal' is declared float"));
  }
  SECTION("bloom off needs the `bloom` uniform") {
    const std::string always = replaced(kFinal, "if (bloom) ", "");
    UserPipelineOptions off;
    off.bloom = false;
    CHECK(refusal(own_shaders(kBlur9, always), opt) == "accepted");
    CHECK_THAT(refusal(own_shaders(kBlur9, always), off), Catch::Contains("uniform 'bloom'"));
  }
  SECTION("a vertex attribute the preset does not feed") {
    LearnOpenGLShaders s = own_shaders();
    s.blur_vs = ShaderSource{"odd.vs", R"glsl(#version 330 core
layout(location = 0) in vec3 aPos;
layout(location = 2) in vec2 aUV;
out vec2 TexCoords;
void main() { TexCoords = aUV; gl_Position = vec4(aPos, 1.0); }
)glsl"};
    const std::string m = refusal(s, opt);
    CHECK_THAT(m, Catch::StartsWith("odd.vs | "));
    CHECK_THAT(m, Catch::Contains("attribute 'aUV'"));
  }
  SECTION("a link error names both files") {
    // The fragment shader's input is a vec3 where the vertex shader writes a vec2.
    std::string blur = replaced(kBlur9, "in vec2 TexCoords;", "in vec3 TexCoords;");
    for (auto at = blur.find("TexCoords)"); at != std::string::npos; at = blur.find("TexCoords)"))
      blur.replace(at, 10, "TexCoords.xy)");
    for (auto at = blur.find("TexCoords +"); at != std::string::npos; at = blur.find("TexCoords +"))
      blur.replace(at, 11, "TexCoords.xy +");
    for (auto at = blur.find("TexCoords -"); at != std::string::npos; at = blur.find("TexCoords -"))
      blur.replace(at, 11, "TexCoords.xy -");
    const std::string m = refusal(own_shaders(blur), opt);
    CHECK_THAT(m, Catch::Contains("user_quad.vert + test_blur9.fs"));
    CHECK_THAT(m, Catch::Contains("does not link"));
  }
  SECTION("an unreadable file") {
    CHECK_THROWS_AS(gpu::load_shader("no/such/dir/7.blur.fs"), InputError);
  }
}

TEST_CASE("the programs' interfaces say how each uniform is set", "[user-shaders]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const auto programs = gpu::check_learnopengl(*ctx, own_shaders(), {});
  REQUIRE(programs.size() == 2);
  CHECK(programs[0].program == "blur");
  CHECK(programs[0].fragment_file == "test_blur9.fs");
  CHECK(programs[0].vertex_file.empty());
  auto role = [](const gpu::ProgramInterface& p, const std::string& name) -> std::string {
    for (const auto& u : p.uniforms)
      if (u.name == name) return u.type + " " + std::to_string(u.size) + ": " + u.role;
    for (const auto& a : p.attributes)
      if (a.name == name) return a.type + " @" + std::to_string(a.location) + ": " + a.role;
    return "absent";
  };
  CHECK(role(programs[0], "w") == "float 5: not set by the host: kept at its initialiser");
  CHECK_THAT(role(programs[0], "horizontal"), Catch::StartsWith("bool 1: set by the host"));
  CHECK_THAT(role(programs[0], "image"), Catch::StartsWith("sampler2D 1: set by the host"));
  CHECK_THAT(role(programs[1], "bloomBlur"), Catch::Contains("texture unit 1"));
  CHECK_THAT(role(programs[1], "aPos"), Catch::StartsWith("vec3 @0: fed by the host"));
  CHECK_THAT(role(programs[1], "aTexCoords"), Catch::StartsWith("vec2 @1: fed by the host"));
}

TEST_CASE("options from bloomref's parameters, and the names of host state",
          "[user-shaders][options]") {
  BloomParams p;
  p.storage = Storage::f16;
  p.passes = 7;
  p.exposure = 0.25f;
  p.threshold = 2.0f;
  const UserPipelineOptions o = gpu::options_for(p);
  CHECK(o.format == gpu::TargetFormat::rgba16f);
  CHECK(o.passes == 7);
  CHECK(o.exposure == 0.25f);
  CHECK(o.threshold == 2.0f);
  p.storage = Storage::f32;
  CHECK(gpu::options_for(p).format == gpu::TargetFormat::rgba32f);
  p.method = Method::mip;
  CHECK_THROWS_AS(gpu::options_for(p), ParamError);
  CHECK(gpu::parse_target_format("GL_RGB16F") == gpu::TargetFormat::rgb16f);
  CHECK(gpu::parse_texture_wrap("mirrored-repeat") == gpu::TextureWrap::mirrored_repeat);
  CHECK(gpu::parse_texture_filter("GL_NEAREST") == gpu::TextureFilter::nearest);
  CHECK(gpu::parse_row_order("flipped") == gpu::RowOrder::flipped);
  CHECK_THROWS_WITH(gpu::parse_texture_wrap("clamp"),
                    Catch::Contains("clamp-to-edge, repeat, mirrored-repeat"));
  CHECK(gpu::storage_of(gpu::TargetFormat::rgb16f) == Storage::f16);
}
