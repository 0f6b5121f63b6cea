// bloomref check --shaders learnopengl --layout FILE: the names a user's shaders give what the
// preset's host code binds and sets (docs/check.md, "Shaders under other names").
#pragma once

#include <string>

#include "bloomref/gpu/user_pipeline.h"

namespace bloomref::cli {

/// Reads a layout file (JSON, version 1). Throws InputError naming the file and the field: not
/// JSON, another version, an unknown key, a name that is no GLSL identifier, a value that is not
/// 1 to 4 numbers or "texel-size" / "target-size".
gpu::PresetLayout read_layout(const std::string& path);

}  // namespace bloomref::cli
