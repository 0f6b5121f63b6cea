// The host side shared by the presets that run a user's shaders (user_pipeline.cpp,
// mip_chain_host.cpp) and the engines' (bevy_host.cpp, unity_host.cpp): the full-screen quad
// the tutorials draw, GL enums of the options, rows, bloomref's own programs and the scene.
#pragma once

#include <epoxy/gl.h>

#include <array>
#include <chrono>
#include <string>
#include <vector>

#include "bloomref/gpu/context.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/image.h"
#include "gl_objects.h"
#include "user_program.h"

namespace bloomref::gpu::host {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0);

GLenum gl_format(TargetFormat f);
GLenum gl_filter(TextureFilter f);
GLenum gl_wrap(TextureWrap w);

/// A uniform's value as the interface report and messages print it ("0.005").
std::string number(float v);

/// The texture coordinate a fragment shader reads (`in vec2 NAME;`), for bloomref's pass-through
/// vertex shader to write: the first such declaration, else `fallback`.
std::string varying_of(const ShaderSource& fs, const std::string& fallback);

/// The image upside down (RowOrder::flipped uploads and readbacks).
Image flipped_rows(ConstImageView src);

// The engine presets' hosts (bevy_host.cpp, unity_host.cpp) around bloomref's own GLSL.

/// bloomref's fragment shader `file` (gpu/shaders) as program `name` with the pass-through
/// vertex shader writing `texCoord`; `preset` names the host in messages.
UserProgram own_program(const char* name, const char* file, const std::vector<HostUniform>& host,
                        const std::string& preset);

/// The GL format of a stage stored as `s` (RGBA32F, RGBA16F, R11F_G11F_B10F).
GLenum storage_format(Storage s);

/// Throws ParamError naming both sizes unless a `scene` fits this GL's textures.
void require_fits(ConstImageView scene);

/// Reads `t` back into `trace` as stage `name`, drawn in `ms`.
void add_stage(StageTrace& trace, const std::string& name, const Texture& t, double ms);

/// The scene after `p`'s non-finite policy (counts into trace.nonfinite), stored as
/// `p.storage` stores it, as a GL_LINEAR, clamp-to-edge texture; recorded as stage `input`.
/// Throws ParamError under --nonfinite error when the scene holds NaN or Inf.
Texture upload_scene(GlContext& ctx, const BloomParams& p, ConstImageView scene,
                     StageTrace& trace);

// The quad of bloom.cpp's renderQuad: a triangle strip, (x, y, z, s, t) per corner.
constexpr float kQuad[] = {
    -1.0f, 1.0f,  0.0f, 0.0f, 1.0f,  // top left
    -1.0f, -1.0f, 0.0f, 0.0f, 0.0f,  // bottom left
    1.0f,  1.0f,  0.0f, 1.0f, 1.0f,  // top right
    1.0f,  -1.0f, 0.0f, 1.0f, 0.0f,  // bottom right
};

// The quad's vertex array, and the fixed-function state the tutorial's passes run with.
class QuadState {
 public:
  QuadState() {
    glGenVertexArrays(1, &vao_);
    glGenBuffers(1, &vbo_);
    glBindVertexArray(vao_);
    glBindBuffer(GL_ARRAY_BUFFER, vbo_);
    glBufferData(GL_ARRAY_BUFFER, sizeof kQuad, kQuad, GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 5 * sizeof(float), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float),
                          reinterpret_cast<const void*>(3 * sizeof(float)));
    for (GLenum cap : {GL_BLEND, GL_DEPTH_TEST, GL_SCISSOR_TEST, GL_CULL_FACE, GL_STENCIL_TEST,
                       GL_FRAMEBUFFER_SRGB})
      glDisable(cap);
  }
  ~QuadState() {
    glBindVertexArray(0);
    glUseProgram(0);
    glDeleteBuffers(1, &vbo_);
    glDeleteVertexArrays(1, &vao_);
  }
  QuadState(const QuadState&) = delete;
  QuadState& operator=(const QuadState&) = delete;

  // Clears the target(s) to the clear colour and draws the quad with `prog`, `units[i]` bound
  // to texture unit i; returns the wall time of the draw, glFinish included.
  // `clear` null: the target keeps what it holds (a pass that blends into it).
  double draw(GlContext& ctx, const UserProgram& prog, const std::vector<const Texture*>& units,
              const Texture& out0, const Texture* out1, const std::array<float, 4>* clear,
              const std::string& what) {
    Framebuffer fb(out0, out1);
    glViewport(0, 0, out0.width, out0.height);
    if (clear) {
      glClearColor((*clear)[0], (*clear)[1], (*clear)[2], (*clear)[3]);
      glClear(GL_COLOR_BUFFER_BIT);
    }
    glUseProgram(prog.program.id);
    for (std::size_t i = 0; i < units.size(); ++i) {
      glActiveTexture(GL_TEXTURE0 + static_cast<GLenum>(i));
      glBindTexture(GL_TEXTURE_2D, units[i]->id);
    }
    glBindVertexArray(vao_);
    glFinish();
    const auto t0 = Clock::now();
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    glFinish();
    const double ms = ms_since(t0);
    glActiveTexture(GL_TEXTURE0);
    ctx.check(what.c_str());
    return ms;
  }

 private:
  GLuint vao_ = 0, vbo_ = 0;
};

}  // namespace bloomref::gpu::host
