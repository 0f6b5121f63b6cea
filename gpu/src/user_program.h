// A user's program: compiled and linked from their unmodified text, then checked against what a
// preset's host code sets (user_pipeline.h says the rules).
#pragma once

#include <string>
#include <vector>

#include "bloomref/gpu/user_pipeline.h"
#include "gl_objects.h"

namespace bloomref::gpu {

/// A uniform the host sets. `flag`: bool (or int / uint) set to 0 or 1; `number`: float;
/// `vector`: float, vec2, vec3 or vec4 by `components`; `integer`: int.
struct HostUniform {
  enum Kind { sampler, flag, number, vector, integer };
  std::string name;
  Kind kind = number;
  bool required = true;
  std::string role;  ///< how the host sets it, for the interface report
  int components = 1;  ///< kind vector
};

/// The names a program's vertex stage uses: the attributes the host binds to locations 0 and 1
/// (of the user's vertex shader), and the texture coordinate bloomref's pass-through vertex
/// shader writes (when the user gives none).
struct VertexNames {
  std::string position = "aPos", texcoords = "aTexCoords", varying = "TexCoords";
};

struct UserProgram {
  Program program;
  ProgramInterface interface;
  std::vector<int> output_locations;  ///< locations of the fragment outputs
  GLint location(const std::string& uniform) const;
  /// Sets a host uniform when the program has it (flags as the type the shader declared).
  void set_flag(const std::string& uniform, bool v) const;
  void set_number(const std::string& uniform, float v) const;
  void set_sampler(const std::string& uniform, int unit) const;
  void set_vector(const std::string& uniform, const std::vector<float>& v) const;
  void set_integer(const std::string& uniform, int v) const;
  /// The value a float uniform holds now (its initialiser, before the host sets it), or NaN.
  float number(const std::string& uniform) const;
  bool has_output(int location) const;
};

/// Compiles `fs` (and `vs`, or bloomref's pass-through when null), binds the position attribute
/// to location 0 and the texture coordinate to 1, links, and checks the program's active
/// uniforms, attributes and outputs against `host`. Throws UserShaderError naming the file and
/// the uniform, sampler or attribute; `preset` names whose host code in the messages.
UserProgram build_user_program(const std::string& name, const ShaderSource* vs,
                               const ShaderSource& fs, const std::vector<HostUniform>& host,
                               const VertexNames& names = {},
                               const std::string& preset = "learnopengl");

}  // namespace bloomref::gpu
