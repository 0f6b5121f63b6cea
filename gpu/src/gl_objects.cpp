#include "gl_objects.h"

#include "bloomref/gpu/context.h"
#include "fault_patches.h"
#include "shader_sources.h"

namespace bloomref::gpu {

Texture::Texture(int w, int h, GLenum internal_format, const float* data)
    : width(w), height(h), format(internal_format) {
  glGenTextures(1, &id);
  glBindTexture(GL_TEXTURE_2D, id);
  glTexStorage2D(GL_TEXTURE_2D, 1, internal_format, w, h);
  if (data) {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGBA, GL_FLOAT, data);
  }
  set_sampling(GL_LINEAR, GL_CLAMP_TO_EDGE);
}

Texture::~Texture() {
  if (id) glDeleteTextures(1, &id);
}

Texture& Texture::operator=(Texture&& o) noexcept {
  std::swap(id, o.id);
  width = o.width;
  height = o.height;
  format = o.format;
  return *this;
}

void Texture::set_sampling(GLenum filter, GLenum wrap) const {
  glBindTexture(GL_TEXTURE_2D, id);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, wrap);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, wrap);
}

void Texture::read(float* out) const {
  glBindTexture(GL_TEXTURE_2D, id);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, out);
}

std::vector<float> Texture::read() const {
  std::vector<float> out(static_cast<std::size_t>(width) * height * 4);
  read(out.data());
  return out;
}

Framebuffer::Framebuffer(const Texture& c0, const Texture* c1) {
  glGenFramebuffers(1, &id);
  glBindFramebuffer(GL_FRAMEBUFFER, id);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, c0.id, 0);
  if (c1) glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, c1->id, 0);
  const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glDrawBuffers(c1 ? 2 : 1, bufs);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw GlError("framebuffer incomplete (status 0x" + std::to_string(status) + ")");
}

Framebuffer::~Framebuffer() {
  if (id) glDeleteFramebuffers(1, &id);
}

Program::~Program() {
  if (id) glDeleteProgram(id);
}

Program& Program::operator=(Program&& o) noexcept {
  std::swap(id, o.id);
  return *this;
}

void Program::set(const char* name, float v) const {
  glProgramUniform1f(id, glGetUniformLocation(id, name), v);
}
void Program::set(const char* name, int v) const {
  glProgramUniform1i(id, glGetUniformLocation(id, name), v);
}
void Program::set(const char* name, int x, int y) const {
  glProgramUniform2i(id, glGetUniformLocation(id, name), x, y);
}

namespace {

const std::string& source(const std::string& file) {
  const auto& all = shader_sources();
  const auto it = all.find(file);
  if (it == all.end()) throw GlError("shader " + file + " is not embedded");
  return it->second;
}

GLuint compile(GLenum type, const std::string& text, const std::string& name) {
  const GLuint s = glCreateShader(type);
  const char* p = text.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    throw GlError("shader " + name + " does not compile: " + log);
  }
  return s;
}

}  // namespace

Program build_program(bool compute, const std::string& stage_file,
                      const std::vector<std::string>& defines, Fault fault) {
  std::string head = "#version 430 core\n";
  for (const std::string& d : defines) head += "#define " + d + "\n";
  const std::string text = head + source(compute ? "compute_main.glsl" : "fragment_main.glsl") +
                           source("common.glsl") + apply_fault(fault, stage_file, source(stage_file));
  Program prog;
  prog.id = glCreateProgram();
  std::vector<GLuint> shaders;
  if (compute) {
    shaders.push_back(compile(GL_COMPUTE_SHADER, text, stage_file));
  } else {
    shaders.push_back(compile(GL_VERTEX_SHADER, "#version 430 core\n" + source("fullscreen.vert"),
                              "fullscreen.vert"));
    shaders.push_back(compile(GL_FRAGMENT_SHADER, text, stage_file));
  }
  for (GLuint s : shaders) glAttachShader(prog.id, s);
  glLinkProgram(prog.id);
  for (GLuint s : shaders) glDeleteShader(s);
  GLint ok = 0;
  glGetProgramiv(prog.id, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetProgramInfoLog(prog.id, sizeof log, nullptr, log);
    throw GlError("program " + stage_file + " does not link: " + log);
  }
  return prog;
}

}  // namespace bloomref::gpu
