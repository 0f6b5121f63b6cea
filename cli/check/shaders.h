// bloomref check --shaders PRESET: the user's own GLSL, run headless, read back pass by pass and
// handed to check as captured stages (docs/check.md, "Your own shaders").
#pragma once

#include <filesystem>
#include <string>

#include "options.h"

namespace bloomref::cli {

struct ShaderArgs {
  std::string preset;  ///< "learnopengl"
  std::string blur_fs, final_fs, blur_vs, final_vs, bright_fs;
  std::string target_format, filter = "linear", wrap = "clamp-to-edge", final_target = "same";
  std::string layout;  ///< a layout file: the names the shaders use (check/layout.h)
  bool any() const { return !preset.empty(); }
};

/// A folder of the process's own under the system temporary folder, removed with its files
/// when the run ends (normally or by an exception).
class ScratchDir {
 public:
  ScratchDir();
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// Loads the user's shader files (InputError naming a missing one), runs them on `scene` through
/// the preset in a headless GL context (GlUnavailable where there is none: exit 3), and writes
/// every pass the user's shaders drew (blur.1 ... blur.N, output) into `dir` as float EXR (an
/// 8-bit final target's output as an 8-bit linear PNG: its codes), named as --dump-stages names
/// them. Returns a one-line description of the GL device; `software`
/// says whether it is a software renderer (llvmpipe).
std::string run_user_shaders(const ShaderArgs& s, const std::string& scene_path,
                             const PipelineOptions& pipeline, const std::filesystem::path& dir,
                             bool& software);

}  // namespace bloomref::cli
