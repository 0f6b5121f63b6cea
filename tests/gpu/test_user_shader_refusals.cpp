// The learnopengl preset refuses what its host code cannot drive (gpu/user_pipeline.h): a
// shader that does not compile or link, a sampler or uniform it requires that is missing or
// mistyped, one it does not know, a fragment input no vertex shader writes; and it reports how
// it sets each uniform it accepts.
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
  SECTION("a fragment input no vertex shader writes: undefined in every pass") {
    // bloomref's pass-through writes TexCoords; a fragment shader reading UV would read 0.
    std::string uv = kBlur9;
    for (std::size_t at = uv.find("TexCoords"); at != std::string::npos; at = uv.find("TexCoords"))
      uv.replace(at, 9, "UV");
    std::string m = refusal(own_shaders(uv), opt);
    CHECK_THAT(m, Catch::StartsWith("test_blur9.fs | "));
    CHECK_THAT(m, Catch::Contains("input 'UV'"));
    CHECK_THAT(m, Catch::Contains("pass-through vertex shader, which writes 'TexCoords'"));
    // The layout's varying makes the pass-through write UV, for every program: the final pass
    // reading TexCoords is then the one refused, until it reads UV too.
    UserPipelineOptions named = opt;
    named.layout.varying = "UV";
    CHECK_THAT(refusal(own_shaders(uv), named), Catch::StartsWith("test_final.fs | "));
    std::string final_uv = kFinal;
    for (std::size_t at = final_uv.find("TexCoords"); at != std::string::npos;
         at = final_uv.find("TexCoords"))
      final_uv.replace(at, 9, "UV");
    CHECK(refusal(own_shaders(uv, final_uv), named) == "accepted");
    // A vertex shader of the user's that writes another name (in a comment, TexCoords does not
    // count).
    LearnOpenGLShaders s = own_shaders();
    s.blur_vs = ShaderSource{"own.vs",
                             "#version 330 core\nlayout(location = 0) in vec3 aPos;\n"
                             "layout(location = 1) in vec2 aTexCoords;\n"
                             "out vec2 uv; // not: out vec2 TexCoords;\n"
                             "void main() { uv = aTexCoords; gl_Position = vec4(aPos, 1.0); }\n"};
    m = refusal(s, opt);
    CHECK_THAT(m, Catch::Contains("input 'TexCoords' is not written by the vertex shader own.vs"));
    // Written by the user's vertex shader (two declarators in one declaration): accepted.
    s.blur_vs->text = replaced(s.blur_vs->text, "out vec2 uv;", "out vec2 uv, TexCoords;");
    s.blur_vs->text = replaced(s.blur_vs->text, "uv = aTexCoords;", "uv = aTexCoords; TexCoords = uv;");
    CHECK(refusal(s, opt) == "accepted");
    // An input declared but never read is no error.
    CHECK(refusal(own_shaders(replaced(kBlur9, "in vec2 TexCoords;", "in vec2 TexCoords;\nin vec3 unused;")),
                  opt) == "accepted");
    // Interface blocks are matched by GL itself, not compared here; nor are shaders with macros.
    std::string block = replaced(kBlur9, "in vec2 TexCoords;", "in Quad { vec2 st; } quad;");
    for (std::size_t at = block.find("TexCoords"); at != std::string::npos; at = block.find("TexCoords"))
      block.replace(at, 9, "quad.st");
    LearnOpenGLShaders b = own_shaders(block);
    b.blur_vs = ShaderSource{"block.vs",
                             "#version 330 core\nlayout(location = 0) in vec3 aPos;\n"
                             "layout(location = 1) in vec2 aTexCoords;\n"
                             "out Quad { vec2 st; } quad;\n"
                             "void main() { quad.st = aTexCoords; gl_Position = vec4(aPos, 1.0); }\n"};
    CHECK(refusal(b, opt) == "accepted");
    LearnOpenGLShaders macro = own_shaders();
    macro.blur_vs = ShaderSource{"macro.vs",
                             "#version 330 core\n#define VARYING out\nlayout(location = 0) in vec3 aPos;\n"
                             "layout(location = 1) in vec2 aTexCoords;\nVARYING vec2 TexCoords;\n"
                             "void main() { TexCoords = aTexCoords; gl_Position = vec4(aPos, 1.0); }\n"};
    CHECK(refusal(macro, opt) == "accepted");
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
