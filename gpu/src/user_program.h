// A user's program: compiled and linked from their unmodified text, then checked against what a
// preset's host code sets (user_pipeline.h says the rules).
#pragma once

#include <string>
#include <vector>

#include "bloomref/gpu/user_pipeline.h"
#include "gl_objects.h"

namespace bloomref::gpu {

/// A uniform the host sets. `flag`: bool (or int / uint) set to 0 or 1; `number`: float.
struct HostUniform {
  enum Kind { sampler, flag, number };
  std::string name;
  Kind kind = number;
  bool required = true;
  std::string role;  ///< how the host sets it, for the interface report
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
  bool has_output(int location) const;
};

/// Compiles `fs` (and `vs`, or bloomref's pass-through when null), binds aPos to attribute 0
/// and aTexCoords to 1, links, and checks the program's active uniforms, attributes and outputs
/// against `host`. Throws UserShaderError naming the file and the uniform, sampler or attribute.
UserProgram build_user_program(const std::string& name, const ShaderSource* vs,
                               const ShaderSource& fs, const std::vector<HostUniform>& host);

}  // namespace bloomref::gpu
