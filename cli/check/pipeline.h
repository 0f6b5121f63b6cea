// check --shaders pipeline --pipeline FILE: a pipeline description (docs/check.md, "Any host
// code: a pipeline description"; docs/schemas/pipeline.v1.json) read into what the GL side runs.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "bloomref/gpu/described_pipeline.h"

namespace bloomref::cli {

/// Reads and checks a description: an unknown key, a missing or misnamed field, a texture or
/// program a pass names that is not declared (before it, for sizes), a "for" whose range is not
/// two integers: InputError naming the file and the field (exit 2). Shader paths are taken
/// relative to the description's folder. "for" blocks are expanded: "{k}", "{k-1}", "{k+2}"
/// in their strings become the loop's numbers.
gpu::PipelineDescription read_pipeline(const std::string& path);

/// `d` (built-in fragment programs only, as gpu::preset_description makes them) as the files
/// that describe it: (path, text) of the description at `path` first, then each program's
/// shader in the folder named as the description without its extension, beside it. What
/// read_pipeline reads back as the same description. ParamError for a program that is not a
/// built-in fragment one.
std::vector<std::pair<std::string, std::string>> pipeline_files(
    const gpu::PipelineDescription& d, const std::string& path, const std::string& title,
    const std::string& source);

}  // namespace bloomref::cli
