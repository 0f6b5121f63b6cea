// The pipeline options shared by `run` and (later) `compare`, bound to one BloomParams.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "bloomref/io.h"
#include "bloomref/params.h"

namespace bloomref::cli {

struct PipelineOptions {
  BloomParams params;
  std::string method = "gaussian", kernel = "discrete9", storage = "f32", precision = "f32",
              nonfinite = "zero", plan = "adaptive", blur = "fast",
              composite = "before-tonemap";
  std::string scene = "demo";
  std::string size;  ///< "WxH" for built-in scenes

  void add_to(CLI::App& app);
  /// Parses the enum names into `params` and validates; throws ParamError.
  void finish();
  void scene_size(int& w, int& h) const;
  /// Loads IN, or builds --scene at --size when IN is empty; `source` names it in messages.
  LoadedImage load_input(const std::string& input, std::string& source) const;
};

/// Parses "WxH"; throws ParamError.
void parse_size(const std::string& s, int& w, int& h);

}  // namespace bloomref::cli
