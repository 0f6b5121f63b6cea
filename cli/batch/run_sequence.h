// bloomref run over a frame sequence: IN, -o and --dump-stages name frames ('shot.####.exr',
// 'out.%04d.exr', 'stages.####/'); --frames, --shard, --resume, --jobs. Each frame is one
// ordinary run (cmd_run.cpp) with its own file names; this file makes the names, skips the
// frames already done, and writes the results file (docs/cluster.md, "Results").
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "batch/sequence.h"
#include "bloomref/params.h"

namespace bloomref::cli {

/// One frame's files and threads, as the sequence hands them to the single-image run.
struct FrameFiles {
  std::string input;  ///< "" for the built-in scene
  std::vector<std::string> outputs;
  std::string dump_dir;
  int threads = 0;
};

/// Runs one frame; fills `record` (timings_ms, size, counts). Throws as `run` does.
using RunFrame = std::function<void(const FrameFiles&, nlohmann::ordered_json& record)>;

struct RunSequenceArgs {
  std::string input;  ///< a pattern, or "" for the built-in scene
  std::vector<std::string> outputs;
  std::string dump_dir, json_path;
  bool quiet = false;
  BloomParams params;
  SequenceOptions sequence;
};

/// Whether these arguments ask for a sequence: a frame wildcard in IN, an output or
/// --dump-stages, or any of --frames, --shard, --resume.
bool is_run_sequence(const RunSequenceArgs& a);

/// Runs the sequence; returns the exit code (sequence.h). ParamError for bad patterns, frame
/// lists, shard values, or outputs that would name one file for every frame.
int run_sequence(const RunSequenceArgs& a, const RunFrame& frame);

}  // namespace bloomref::cli
