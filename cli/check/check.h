// bloomref check as a library: a typed request in (files, or the scene and stage images in
// memory), a typed result out (CheckRun, check/types.h). The `check` command and the Python
// module are callers of it: the command fills a request from its command line
// (check/command.h), Python from its arguments, and both turn the result into the same JSON
// (check/output.h, check_json).
#pragma once

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "batch/sequence.h"
#include "check/shaders.h"
#include "check/types.h"
#include "options.h"

namespace bloomref::cli {

/// The files a check writes its results to once judged (results.h's writers); empty: not
/// written. Every one is checked before any work: writable, and none of them an input.
struct CheckOutputs {
  std::string json, junit, markdown;
};

/// What one check judges, and how. Exactly one source of stages: `stages_dir` or `stages` (one
/// item), `manifest` (its items), or `shaders` (the user's shaders, run here).
struct CheckRequest {
  /// The scene: an image path (a frame pattern such as scene.####.exr with a pattern
  /// `stages_dir`), or empty for the built-in scene `pipeline.scene`. With `scene_image`, the
  /// name the results give the image in memory.
  std::string scene;
  const ConstImageView* scene_image = nullptr;  ///< the scene in memory (the caller keeps it)
  std::string stages_dir;         ///< a folder of <stage>.<ext> files, or a pattern of folders
  /// Stage images one by one: in memory (`image`) or files (an empty list: nothing to compare).
  std::optional<std::vector<StageFile>> stages;
  std::string manifest;           ///< a manifest file (docs/check.md)
  ShaderArgs shaders;             ///< --shaders: the user's shaders and how to run them

  /// The pipeline the stages are judged against: numbers in `pipeline.params`, named choices
  /// (method, storage, luma, ...) in the strings as the command line gives them, which check
  /// parses into `params` (a choice set in `params` directly is replaced by its string's).
  PipelineOptions pipeline;
  /// Options the caller set itself, as "--name": they win over a manifest's "params", and a
  /// given "--profile" over the device's own profile with --shaders.
  std::set<std::string> given;
  std::string profile = "nvidia";  ///< a profile name, or a profile file NAME.json
  /// How a folder's files are read: encoding, row origin, channel order, raw sample format.
  std::string encoding = "auto", origin = "top", channels = "RGBA", raw_format = "f32";
  std::string expectations;  ///< a file of known deviations
  DeviceKeys device;         ///< recorded in the results, matched by expectations
  bool warn_as_error = false;
  bool causes = true;                 ///< test the usual causes of a failure
  double require_sensitivity = 1.05;  ///< the bloom gain a verdict must see (0: not measured)
  std::string sensitivity = "gain";   ///< gain, full, stages, none
  std::string report_dir;             ///< the HTML report's folder; empty: none
  std::string artifacts = "fail";     ///< the report's images: fail, all, none
  SequenceOptions sequence;           ///< frames and shards
  CheckOutputs outputs;
  /// Print the results' table and progress on stdout (the command without -q), and say on
  /// stderr what the results also say: nothing compared, an empty shard, an output not written.
  bool print_results = false, print_notes = false;
};

/// Judges what `request` names. ParamError (a usage error, exit 2) for a request that names no
/// source of stages or two; InputError (exit 2) for a file that cannot be read or an output
/// that would overwrite an input; gpu::GlUnavailable (exit 3) with --shaders and no GL device.
/// The run's verdict and exit code are in the result; its outputs are written (an output that
/// could not be written is in `output_errors`, exit 6).
CheckRun check(CheckRequest request);

}  // namespace bloomref::cli
