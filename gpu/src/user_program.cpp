#include "user_program.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "shader_sources.h"

namespace bloomref::gpu {
namespace {

struct GlType {
  GLenum type;
  const char* name;
  int components;  // values glGetUniformfv writes for one element
};

// The uniform and attribute types a fragment or vertex shader of GLSL 3.30 can declare.
// clang-format off
constexpr GlType kTypes[] = {
    {GL_FLOAT, "float", 1},         {GL_FLOAT_VEC2, "vec2", 2},
    {GL_FLOAT_VEC3, "vec3", 3},     {GL_FLOAT_VEC4, "vec4", 4},
    {GL_INT, "int", 1},             {GL_INT_VEC2, "ivec2", 2},
    {GL_INT_VEC3, "ivec3", 3},      {GL_INT_VEC4, "ivec4", 4},
    {GL_UNSIGNED_INT, "uint", 1},   {GL_UNSIGNED_INT_VEC2, "uvec2", 2},
    {GL_UNSIGNED_INT_VEC3, "uvec3", 3}, {GL_UNSIGNED_INT_VEC4, "uvec4", 4},
    {GL_BOOL, "bool", 1},           {GL_BOOL_VEC2, "bvec2", 2},
    {GL_BOOL_VEC3, "bvec3", 3},     {GL_BOOL_VEC4, "bvec4", 4},
    {GL_FLOAT_MAT2, "mat2", 4},     {GL_FLOAT_MAT3, "mat3", 9},
    {GL_FLOAT_MAT4, "mat4", 16},    {GL_FLOAT_MAT2x3, "mat2x3", 6},
    {GL_FLOAT_MAT2x4, "mat2x4", 8}, {GL_FLOAT_MAT3x2, "mat3x2", 6},
    {GL_FLOAT_MAT3x4, "mat3x4", 12}, {GL_FLOAT_MAT4x2, "mat4x2", 8},
    {GL_FLOAT_MAT4x3, "mat4x3", 12}, {GL_SAMPLER_2D, "sampler2D", 1},
};
// clang-format on

std::string type_name(GLenum t) {
  for (const GlType& g : kTypes)
    if (g.type == t) return g.name;
  char buf[32];
  std::snprintf(buf, sizeof buf, "GL type 0x%04x", t);
  return buf;
}

int components(GLenum t) {
  for (const GlType& g : kTypes)
    if (g.type == t) return g.components;
  return 0;
}

// Sampler types of every dimensionality and return type (GLSL 3.30 and later).
// clang-format off
bool is_sampler(GLenum t) {
  switch (t) {
    case GL_SAMPLER_1D: case GL_SAMPLER_2D: case GL_SAMPLER_3D: case GL_SAMPLER_CUBE:
    case GL_SAMPLER_1D_SHADOW: case GL_SAMPLER_2D_SHADOW: case GL_SAMPLER_1D_ARRAY:
    case GL_SAMPLER_2D_ARRAY: case GL_SAMPLER_2D_RECT: case GL_SAMPLER_BUFFER:
    case GL_SAMPLER_2D_MULTISAMPLE: case GL_INT_SAMPLER_2D: case GL_UNSIGNED_INT_SAMPLER_2D:
    case GL_SAMPLER_CUBE_SHADOW: case GL_SAMPLER_2D_ARRAY_SHADOW: case GL_INT_SAMPLER_3D:
    case GL_UNSIGNED_INT_SAMPLER_3D: case GL_INT_SAMPLER_2D_ARRAY:
    case GL_UNSIGNED_INT_SAMPLER_2D_ARRAY:
      return true;
    default:
      return false;
  }
}
// clang-format on

bool is_flag_type(GLenum t) {
  return t == GL_BOOL || t == GL_INT || t == GL_UNSIGNED_INT;
}

std::string info_log(GLuint object, bool program) {
  GLint n = 0;
  if (program)
    glGetProgramiv(object, GL_INFO_LOG_LENGTH, &n);
  else
    glGetShaderiv(object, GL_INFO_LOG_LENGTH, &n);
  if (n <= 1) return "";
  std::string log(static_cast<std::size_t>(n), '\0');
  if (program)
    glGetProgramInfoLog(object, n, nullptr, log.data());
  else
    glGetShaderInfoLog(object, n, nullptr, log.data());
  log.resize(std::strlen(log.c_str()));
  while (!log.empty() && (log.back() == '\n' || log.back() == ' ')) log.pop_back();
  return log;
}

// Compiles one shader from the user's text as it is. The log (warnings) goes to `log`.
GLuint compile(GLenum stage, const ShaderSource& s, std::string& log) {
  const GLuint id = glCreateShader(stage);
  const char* text = s.text.c_str();
  const GLint length = static_cast<GLint>(s.text.size());
  glShaderSource(id, 1, &text, &length);
  glCompileShader(id);
  GLint ok = 0;
  glGetShaderiv(id, GL_COMPILE_STATUS, &ok);
  const std::string messages = info_log(id, false);
  if (!ok) {
    glDeleteShader(id);
    throw UserShaderError(s.path, std::string(stage == GL_VERTEX_SHADER ? "vertex" : "fragment") +
                                      " shader does not compile:\n" +
                                      (messages.empty() ? "(the compiler gave no log)" : messages));
  }
  if (!messages.empty()) log += s.path + ": " + messages + "\n";
  return id;
}

std::string strip_array_suffix(std::string name) {
  if (name.size() > 3 && name.compare(name.size() - 3, 3, "[0]") == 0) name.resize(name.size() - 3);
  return name;
}

// Whether any component of any element of a uniform holds a non-zero value after linking.
bool initialised(GLuint prog, const std::string& name, GLenum type, int size) {
  const int n = components(type);
  if (n == 0) return false;
  for (int i = 0; i < size; ++i) {
    const std::string element = size > 1 ? name + "[" + std::to_string(i) + "]" : name;
    const GLint loc = glGetUniformLocation(prog, element.c_str());
    if (loc < 0) continue;
    float v[16] = {};
    glGetUniformfv(prog, loc, v);
    for (int c = 0; c < n; ++c)
      if (v[c] != 0.0f) return true;
  }
  return false;
}

std::string kind_name(const HostUniform& h) {
  switch (h.kind) {
    case HostUniform::sampler:
      return "sampler2D";
    case HostUniform::flag:
      return "bool";
    case HostUniform::number:
      return "float";
    case HostUniform::vector:
      return h.components == 1 ? "float" : "vec" + std::to_string(h.components);
    case HostUniform::integer:
      return "int";
  }
  return "?";
}

// The GL type a float vector of n components is declared as.
GLenum vector_type(int n) {
  return n == 2 ? GL_FLOAT_VEC2 : n == 3 ? GL_FLOAT_VEC3 : n == 4 ? GL_FLOAT_VEC4 : GL_FLOAT;
}

// The file to name for a uniform: the user's vertex shader when only it mentions the name.
struct Files {
  const ShaderSource* vs;
  const ShaderSource& fs;
  const std::string& of(const std::string& name) const {
    if (vs && vs->text.find(name) != std::string::npos && fs.text.find(name) == std::string::npos)
      return vs->path;
    return fs.path;
  }
};

void check_uniforms(UserProgram& up, const Files& files, const std::vector<HostUniform>& host,
                    const std::string& preset) {
  const GLuint prog = up.program.id;
  GLint count = 0, blocks = 0;
  glGetProgramiv(prog, GL_ACTIVE_UNIFORMS, &count);
  glGetProgramiv(prog, GL_ACTIVE_UNIFORM_BLOCKS, &blocks);
  if (blocks > 0) {
    char name[256] = {};
    glGetActiveUniformBlockName(prog, 0, sizeof name, nullptr, name);
    throw UserShaderError(files.of(name), std::string("uniform block '") + name +
                                              "' is not set by the " + preset + " preset's host code");
  }
  std::vector<std::string> seen;
  for (GLint i = 0; i < count; ++i) {
    char buf[256] = {};
    GLint size = 0;
    GLenum type = 0;
    glGetActiveUniform(prog, static_cast<GLuint>(i), sizeof buf, nullptr, &size, &type, buf);
    const std::string name = strip_array_suffix(buf);
    if (name.rfind("gl_", 0) == 0) continue;  // built-in state (gl_DepthRange)
    ActiveVariable v{name, type_name(type), size, glGetUniformLocation(prog, buf), ""};
    const std::string& file = files.of(name);
    const auto it = std::find_if(host.begin(), host.end(),
                                 [&](const HostUniform& h) { return h.name == name; });
    if (it != host.end()) {
      const bool ok = size == 1 && (it->kind == HostUniform::sampler ? type == GL_SAMPLER_2D
                                    : it->kind == HostUniform::flag  ? is_flag_type(type)
                                    : it->kind == HostUniform::integer ? type == GL_INT
                                    : it->kind == HostUniform::vector
                                        ? type == vector_type(it->components)
                                        : type == GL_FLOAT);
      if (!ok)
        throw UserShaderError(file, (is_sampler(type) ? "sampler '" : "uniform '") + name +
                                        "' is declared " + v.type +
                                        (size > 1 ? "[" + std::to_string(size) + "]" : "") +
                                        "; the " + preset + " preset sets a " + kind_name(*it) +
                                        " (" + it->role + ")");
      v.role = "set by the host: " + it->role;
      seen.push_back(name);
    } else if (is_sampler(type)) {
      throw UserShaderError(file, "sampler '" + name + "' (" + v.type +
                                      ") is not one the " + preset + " preset binds here; it "
                                      "would read texture unit 0");
    } else if (!initialised(prog, name, type, size)) {
      throw UserShaderError(file, "uniform '" + name + "' (" + v.type + ") is not set by the " +
                                      preset + " preset's host code and has no non-zero "
                                      "initialiser, so it would be used at 0" +
                                      (preset == "learnopengl"
                                           ? " (a --layout file's \"set\" gives it a value)"
                                           : ""));
    } else {
      v.role = "not set by the host: kept at its initialiser";
    }
    up.interface.uniforms.push_back(std::move(v));
  }
  for (const HostUniform& h : host) {
    if (!h.required || std::find(seen.begin(), seen.end(), h.name) != seen.end()) continue;
    throw UserShaderError(files.fs.path,
                          std::string(h.kind == HostUniform::sampler ? "sampler '" : "uniform '") +
                              h.name + "' (" + kind_name(h) + ", " + h.role +
                              ") is missing: the preset requires it. A uniform the shader "
                              "declares but never reads is removed by the compiler and "
                              "counts as missing");
  }
}

void check_attributes(UserProgram& up, const std::string& file, const VertexNames& names,
                      const std::string& preset) {
  const GLuint prog = up.program.id;
  GLint count = 0;
  glGetProgramiv(prog, GL_ACTIVE_ATTRIBUTES, &count);
  for (GLint i = 0; i < count; ++i) {
    char buf[256] = {};
    GLint size = 0;
    GLenum type = 0;
    glGetActiveAttrib(prog, static_cast<GLuint>(i), sizeof buf, nullptr, &size, &type, buf);
    const std::string name = strip_array_suffix(buf);
    if (name.rfind("gl_", 0) == 0) continue;  // gl_VertexID and friends
    const GLint loc = glGetAttribLocation(prog, buf);
    ActiveVariable v{name, type_name(type), size, loc, ""};
    const bool vector =
        type == GL_FLOAT || type == GL_FLOAT_VEC2 || type == GL_FLOAT_VEC3 || type == GL_FLOAT_VEC4;
    if ((loc != 0 && loc != 1) || !vector || size != 1)
      throw UserShaderError(file, "attribute '" + name + "' (" + v.type + ", location " +
                                      std::to_string(loc) +
                                      ") is not one the " + preset + " preset feeds: it feeds "
                                      "location 0 " + names.position + " (vec3) and location 1 " +
                                      names.texcoords + " (vec2)");
    v.role = loc == 0 ? "fed by the host: the quad's corner (x, y, 0)"
                      : "fed by the host: the quad's texture coordinate (s, t)";
    up.interface.attributes.push_back(std::move(v));
  }
}

void read_outputs(UserProgram& up, const std::string& file) {
  const GLuint prog = up.program.id;
  GLint count = 0;
  glGetProgramInterfaceiv(prog, GL_PROGRAM_OUTPUT, GL_ACTIVE_RESOURCES, &count);
  for (GLint i = 0; i < count; ++i) {
    const GLenum prop = GL_LOCATION;
    GLint loc = -1;
    glGetProgramResourceiv(prog, GL_PROGRAM_OUTPUT, static_cast<GLuint>(i), 1, &prop, 1, nullptr,
                           &loc);
    if (loc >= 0) up.output_locations.push_back(loc);
  }
  if (!up.has_output(0))
    throw UserShaderError(file, "the fragment shader has no output at location 0");
}

}  // namespace

GLint UserProgram::location(const std::string& uniform) const {
  return glGetUniformLocation(program.id, uniform.c_str());
}

void UserProgram::set_flag(const std::string& uniform, bool v) const {
  const GLint loc = location(uniform);
  if (loc < 0) return;
  GLint size = 0;
  GLenum type = 0;
  GLuint index = 0;
  const char* name = uniform.c_str();
  glGetUniformIndices(program.id, 1, &name, &index);
  glGetActiveUniform(program.id, index, 0, nullptr, &size, &type, nullptr);
  if (type == GL_UNSIGNED_INT)
    glProgramUniform1ui(program.id, loc, v ? 1u : 0u);
  else
    glProgramUniform1i(program.id, loc, v ? 1 : 0);
}

void UserProgram::set_number(const std::string& uniform, float v) const {
  const GLint loc = location(uniform);
  if (loc >= 0) glProgramUniform1f(program.id, loc, v);
}

void UserProgram::set_integer(const std::string& uniform, int v) const {
  const GLint loc = location(uniform);
  if (loc >= 0) glProgramUniform1i(program.id, loc, v);
}

float UserProgram::number(const std::string& uniform) const {
  const GLint loc = location(uniform);
  if (loc < 0) return NAN;
  float v = NAN;
  glGetUniformfv(program.id, loc, &v);
  return v;
}

void UserProgram::set_sampler(const std::string& uniform, int unit) const {
  const GLint loc = location(uniform);
  if (loc >= 0) glProgramUniform1i(program.id, loc, unit);
}

void UserProgram::set_vector(const std::string& uniform, const std::vector<float>& v) const {
  const GLint loc = location(uniform);
  if (loc < 0) return;
  switch (v.size()) {
    case 1: glProgramUniform1fv(program.id, loc, 1, v.data()); break;
    case 2: glProgramUniform2fv(program.id, loc, 1, v.data()); break;
    case 3: glProgramUniform3fv(program.id, loc, 1, v.data()); break;
    case 4: glProgramUniform4fv(program.id, loc, 1, v.data()); break;
    default: break;
  }
}

bool UserProgram::has_output(int loc) const {
  return std::find(output_locations.begin(), output_locations.end(), loc) != output_locations.end();
}

namespace {

// GLSL text without its comments and preprocessor lines.
std::string code_of(const std::string& text) {
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    if (text.compare(i, 2, "//") == 0) {
      i = text.find('\n', i);
      if (i == std::string::npos) break;
    } else if (text.compare(i, 2, "/*") == 0) {
      const std::size_t end = text.find("*/", i + 2);
      if (end == std::string::npos) break;
      out += ' ';
      i = end + 2;
    } else if (text[i] == '#' && (out.empty() || out.back() == '\n')) {
      i = text.find('\n', i);
      if (i == std::string::npos) break;
    } else {
      out += text[i++];
    }
  }
  return out;
}

bool ident_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

// The identifiers of a piece of text, in order.
std::vector<std::string> identifiers(const std::string& s) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < s.size();) {
    if (!ident_char(s[i])) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < s.size() && ident_char(s[j])) ++j;
    out.push_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

// The variables a shader declares at global scope with one of `qualifiers` (`in` and
// `varying` for a fragment shader's inputs, `out` and `varying` for a vertex shader's outputs):
// `[layout(...)] [interpolation] in TYPE NAME [, NAME ...];`. `blocks` is set when an interface
// block carries one of them (then its members are not listed).
std::vector<std::string> interface_names(const std::string& text,
                                         const std::vector<std::string>& qualifiers, bool& blocks) {
  const std::string code = code_of(text);
  std::vector<std::string> names;
  std::string statement;
  int depth = 0;
  auto qualified = [&](const std::vector<std::string>& ids) {
    for (const std::string& q : qualifiers)
      if (std::find(ids.begin(), ids.end(), q) != ids.end()) return true;
    return false;
  };
  for (char c : code) {
    if (c == '{') {
      if (depth++ == 0 && qualified(identifiers(statement))) blocks = true;
      continue;
    }
    if (c == '}') {
      if (--depth == 0 && statement.find('(') != std::string::npos) statement.clear();  // a body
      continue;
    }
    if (depth > 0) continue;
    if (c != ';') {
      statement += c;
      continue;
    }
    // layout(...) is a qualifier; any other parenthesis makes it no plain declaration.
    std::string plain = statement;
    statement.clear();
    for (std::size_t at = plain.find("layout"); at != std::string::npos; at = plain.find("layout")) {
      const std::size_t close = plain.find(')', at);
      if (close == std::string::npos) break;
      plain.erase(at, close - at + 1);
    }
    if (plain.find('(') != std::string::npos || plain.find('{') != std::string::npos) continue;
    std::vector<std::string> parts;
    std::size_t from = 0;
    for (std::size_t comma = plain.find(','); ; comma = plain.find(',', from)) {
      parts.push_back(plain.substr(from, comma == std::string::npos ? std::string::npos : comma - from));
      if (comma == std::string::npos) break;
      from = comma + 1;
    }
    const std::vector<std::string> first = identifiers(parts[0].substr(0, parts[0].find('[')));
    if (first.size() < 3 || !qualified(first)) continue;  // qualifier, type, name at least
    names.push_back(first.back());
    for (std::size_t k = 1; k < parts.size(); ++k) {
      const std::vector<std::string> more = identifiers(parts[k].substr(0, parts[k].find('[')));
      if (!more.empty()) names.push_back(more.front());
    }
  }
  return names;
}

// Whether `name` appears in the code more than once (its declaration and a use).
bool used(const std::string& text, const std::string& name) {
  const std::vector<std::string> ids = identifiers(code_of(text));
  return std::count(ids.begin(), ids.end(), name) > 1;
}

// Refuses a fragment shader input that the vertex shader does not write: GL leaves it undefined
// (llvmpipe links such a program and reads 0), so every pass would be judged on garbage. Where
// either side uses an interface block or a macro (which may hide a qualifier or a name), the
// names are not compared.
void check_varyings(const ShaderSource& vertex, bool own_vertex, const std::string& varying,
                    const ShaderSource& fs) {
  for (const ShaderSource* s : {&vertex, &fs})
    if (s->text.find("#define") != std::string::npos) return;
  bool blocks = false;
  const std::vector<std::string> outs = interface_names(vertex.text, {"out", "varying"}, blocks);
  const std::vector<std::string> ins = interface_names(fs.text, {"in", "varying"}, blocks);
  if (blocks) return;
  for (const std::string& in : ins) {
    if (std::find(outs.begin(), outs.end(), in) != outs.end() || !used(fs.text, in)) continue;
    throw UserShaderError(
        fs.path, "input '" + in + "' is not written by " +
                     (own_vertex ? "bloomref's pass-through vertex shader, which writes '" +
                                       varying + "' (a --layout file's \"varying\" names it)"
                                 : "the vertex shader " + vertex.path) +
                     ": it would be undefined in every pass");
  }
}

// bloomref's pass-through vertex shader, writing the texture coordinate as `varying`.
ShaderSource pass_through(const std::string& varying) {
  std::string text = shader_sources().at("user_quad.vert");
  for (const std::string from : {"out vec2 TexCoords;", "  TexCoords = aTexCoords;"}) {
    const std::size_t at = text.find(from);
    if (at == std::string::npos) continue;
    std::string to = from;
    to.replace(to.find("TexCoords"), 9, varying);
    text.replace(at, from.size(), to);
  }
  return {"bloomref's user_quad.vert", text};
}

}  // namespace

UserProgram build_user_program(const std::string& name, const ShaderSource* vs,
                               const ShaderSource& fs, const std::vector<HostUniform>& host,
                               const VertexNames& names, const std::string& preset) {
  const ShaderSource own = pass_through(names.varying);
  const ShaderSource& vertex = vs ? *vs : own;
  UserProgram up;
  up.interface.program = name;
  up.interface.vertex_file = vs ? vs->path : "";
  up.interface.fragment_file = fs.path;
  std::string log;
  const GLuint v = compile(GL_VERTEX_SHADER, vertex, log);
  GLuint f = 0;
  try {
    f = compile(GL_FRAGMENT_SHADER, fs, log);
  } catch (...) {
    glDeleteShader(v);
    throw;
  }
  up.program.id = glCreateProgram();
  glAttachShader(up.program.id, v);
  glAttachShader(up.program.id, f);
  // bloomref's own vertex shader declares the tutorial's attributes at locations 0 and 1.
  glBindAttribLocation(up.program.id, 0, vs ? names.position.c_str() : "aPos");
  glBindAttribLocation(up.program.id, 1, vs ? names.texcoords.c_str() : "aTexCoords");
  glLinkProgram(up.program.id);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(up.program.id, GL_LINK_STATUS, &ok);
  const std::string messages = info_log(up.program.id, true);
  if (!ok)
    throw UserShaderError(vertex.path + " + " + fs.path,
                          "the " + name + " program does not link:\n" +
                              (messages.empty() ? "(the linker gave no log)" : messages));
  if (!messages.empty()) log += name + " program: " + messages + "\n";
  up.interface.log = log;
  check_varyings(vertex, vs == nullptr, names.varying, fs);
  check_uniforms(up, Files{vs, fs}, host, preset);
  check_attributes(up, vs ? vs->path : fs.path,
                   vs ? names : VertexNames{"aPos", "aTexCoords", names.varying}, preset);
  read_outputs(up, fs.path);
  return up;
}

}  // namespace bloomref::gpu
