// The pipeline options shared by `run` and (later) `compare`, bound to one BloomParams.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

#include "bloomref/io.h"
#include "bloomref/params.h"

namespace bloomref::cli {

struct PipelineOptions {
  BloomParams params;
  std::string method = "gaussian", kernel = "discrete9", storage = "f32", precision = "f32",
              nonfinite = "zero", plan = "adaptive", blur = "fast",
              composite = "before-tonemap", composite_mode = "add", prefilter = "per-lookup",
              first_axis = "horizontal", luma = "rec709", luma_space = "linear",
              karis_form = "per-tap", texel_step = "texture", bloom_upscale = "tent",
              level_combine = "add", level_weights = "one", knee_form = "bevy",
              first_downsample = "13-tap", downsample = "13-tap", upsample = "tent",
              level_count = "fixed";
  std::string chain_storage;  ///< empty: the levels are stored as --storage says
  std::string preset;         ///< the preset applied, if any
  std::string scene = "demo";
  std::string size;  ///< "WxH" for built-in scenes
  std::string max_memory;  ///< --max-memory; empty: default_memory_budget()
  /// Set by the command before load_input: images kept per stage (working_set's kept_traces)
  /// and whether it runs GL.
  int kept_traces = 0;
  bool gl = false;
  /// Whether the user gave an option ("--knee"): the command line's options as parsed (add_to),
  /// and a manifest's keys. finish() refuses a given option that its mode would ignore.
  OptionGiven given;

  void add_to(CLI::App& app);
  /// Parses the enum names into `params` and validates; throws ParamError.
  /// `refuse_ignored`: false where more options are still to come (a manifest's params, whose
  /// reading finishes again).
  void finish(bool refuse_ignored = true);
  void scene_size(int& w, int& h) const;
  /// Loads IN, or builds --scene at --size when IN is empty; `source` names it in messages.
  /// Refuses (InputError, ParamError for a scene) an image whose run would need more memory
  /// than --max-memory (working_set), before its pixels are allocated.
  LoadedImage load_input(const std::string& input, std::string& source) const;
  /// --max-memory in bytes, or its default (default_memory_budget).
  std::uint64_t memory_budget() const;
  /// Throws unless a run over width x height fits --max-memory; `what` names the image.
  void check_memory(const std::string& what, int width, int height, bool is_file) const;
};

/// Parses "WxH"; throws ParamError.
void parse_size(const std::string& s, int& w, int& h);

}  // namespace bloomref::cli
