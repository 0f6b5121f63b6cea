// check --shaders pipeline --pipeline FILE: a pipeline description (docs/check.md, "Any host
// code: a pipeline description"; docs/schemas/pipeline.v1.json) read into what the GL side runs.
#pragma once

#include <string>

#include "bloomref/gpu/described_pipeline.h"

namespace bloomref::cli {

/// Reads and checks a description: an unknown key, a missing or misnamed field, a texture or
/// program a pass names that is not declared (before it, for sizes), a "for" whose range is not
/// two integers: InputError naming the file and the field (exit 2). Shader paths are taken
/// relative to the description's folder. "for" blocks are expanded: "{k}", "{k-1}", "{k+2}"
/// in their strings become the loop's numbers.
gpu::PipelineDescription read_pipeline(const std::string& path);

}  // namespace bloomref::cli
