// Small owners of GL objects (textures, framebuffers, programs) and shader assembly.
#pragma once

#include <epoxy/gl.h>

#include <string>
#include <vector>

#include "bloomref/gpu/gl_executor.h"

namespace bloomref::gpu {

class GlContext;

struct Texture {
  GLuint id = 0;
  int width = 0, height = 0;
  GLenum format = GL_RGBA32F;
  Texture() = default;
  Texture(int w, int h, GLenum internal_format, const float* data = nullptr);
  ~Texture();
  Texture(Texture&& o) noexcept { *this = std::move(o); }
  Texture& operator=(Texture&& o) noexcept;
  /// GL_LINEAR or GL_NEAREST filtering, GL_CLAMP_TO_EDGE or GL_REPEAT wrapping.
  void set_sampling(GLenum filter, GLenum wrap) const;
  /// RGBA float readback (half textures convert exactly) into width * height * 4 floats at out.
  void read(float* out) const;
  std::vector<float> read() const;
};

struct Framebuffer {
  GLuint id = 0;
  Framebuffer(const Texture& c0, const Texture* c1 = nullptr);
  ~Framebuffer();
  Framebuffer(const Framebuffer&) = delete;
  Framebuffer& operator=(const Framebuffer&) = delete;
};

struct Program {
  GLuint id = 0;
  Program() = default;
  ~Program();
  Program(Program&& o) noexcept { *this = std::move(o); }
  Program& operator=(Program&& o) noexcept;
  void set(const char* name, float v) const;
  void set(const char* name, int v) const;
  void set(const char* name, int x, int y) const;
};

/// Compiles a stage: the entry file (fragment_main.glsl or compute_main.glsl), common.glsl and
/// the stage file, after `#version 430 core` and `defines` (one "NAME VALUE" per entry), with
/// `fault`'s source edits applied to the stage file (fault_patches.h).
Program build_program(bool compute, const std::string& stage_file,
                      const std::vector<std::string>& defines, Fault fault = Fault::none);

}  // namespace bloomref::gpu
