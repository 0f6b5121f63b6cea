// bloomref check --shaders PRESET: the user's own GLSL, run headless, read back pass by pass and
// handed to check as captured stages (docs/check.md, "Your own shaders").
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "bloomref/output_files.h"
#include "options.h"

namespace bloomref::cli {

struct ShaderArgs {
  std::string preset;  ///< "learnopengl", "learnopengl-pbb" or "pipeline"
  std::string blur_fs, final_fs, blur_vs, final_vs, bright_fs;
  std::string downsample_fs, upsample_fs, downsample_vs, upsample_vs;  ///< learnopengl-pbb
  std::string target_format, filter = "linear", wrap = "clamp-to-edge", final_target = "same";
  std::string layout;  ///< a layout file: the names the shaders use (check/layout.h)
  std::string pipeline;  ///< --shaders pipeline: the description file (check/pipeline.h)
  /// --shaders pipeline only: "gl" (fragment passes, headless EGL) or "vulkan" (each pass a
  /// compute shader, vulkan/described.h).
  std::string backend = "gl";
  /// What running them may cost: seconds of wall time (0: shader_timeout's default) and bytes
  /// of resident memory (0: shader_memory's default), compiling and linking included.
  double timeout_s = 0;
  std::string max_memory;
  bool any() const { return !preset.empty(); }
  /// The user's shader files given, in pipeline order.
  std::vector<std::string> given() const;
  /// The same as "a, b and c" (what the results say the stages came from).
  std::string files() const;
};

/// The folder the user's passes are read back into (removed at exit and on SIGINT/SIGTERM).
using ScratchDir = ScratchFolder;  // bloomref/output_files.h

/// Loads the user's shader files (InputError naming a missing one), runs them on `scene` through
/// the preset in a headless GL context (GlUnavailable where there is none: exit 3), and writes
/// every pass the user's shaders drew (blur.1 ... blur.N, output) into `dir` as float EXR (an
/// 8-bit final target's output as an 8-bit linear PNG: its codes), named as --dump-stages names
/// them. Returns a one-line description of the GL device; `software`
/// says whether it is a software renderer (llvmpipe).
/// The default time limit of the user's passes: 120 s, and 20 s per million texels of the scene
/// (a normal run at 1920x1080 on llvmpipe takes a few seconds).
double shader_timeout(int width, int height);

/// The default memory limit of the user's passes: 1 GiB and 24 float RGBA images of the scene's
/// size (the targets, the readbacks and the driver's copies), never over --max-memory.
std::uint64_t shader_memory(int width, int height, std::uint64_t max_memory);

/// run_user_shaders in a child process, watched: one whose resident memory passes the limit or
/// that runs past the time limit is ended (compiling, linking or drawing), and InputError names
/// the shaders and the limit (exit 2). What the child throws is thrown here as it was
/// (GlUnavailable: exit 3). The child ends with this process. It is started before this process
/// reads any image or starts any thread (a forked child has none of its parent's threads, and
/// a thread pool started before the fork would wait for them); it reads the scene itself and
/// sends its size back first, from which the default limits follow.
std::string run_user_shaders_bounded(const ShaderArgs& s, const std::string& scene_path,
                                     const PipelineOptions& pipeline,
                                     const std::filesystem::path& dir, bool& software);

std::string run_user_shaders(const ShaderArgs& s, const std::string& scene_path,
                             const PipelineOptions& pipeline, const std::filesystem::path& dir,
                             bool& software,
                             const std::function<void(int width, int height)>& on_scene = {});

}  // namespace bloomref::cli
