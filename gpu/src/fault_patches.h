// How `compare --inject-fault` changes the shaders: each fault is a set of exact text edits of
// one shader file, applied to the embedded source before it is compiled, so the files in
// gpu/shaders read as the effect only. An edit whose anchor is not in the file exactly once
// throws (naming the fault and the anchor): a shader edit cannot silently disable a fault.
#pragma once

#include <string>
#include <vector>

#include "bloomref/gpu/gl_executor.h"

namespace bloomref::gpu {

/// Replace `anchor` (found exactly once in shader file `file`) with `replacement`.
struct SourcePatch {
  std::string file;
  std::string anchor;
  std::string replacement;
};

/// The shader edits that inject `f`; empty for the faults the host injects (wrap mode, a skipped
/// pass, texture format, level size).
const std::vector<SourcePatch>& fault_patches(Fault f);

/// `source`, the text of shader file `file`, with every edit of `f` for that file applied.
/// Throws std::logic_error naming the fault and the anchor when an anchor is not found exactly
/// once.
std::string apply_fault(Fault f, const std::string& file, std::string source);

}  // namespace bloomref::gpu
