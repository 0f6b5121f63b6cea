// bloomref CLI — presets: named parameter sets, one JSON file each in data/presets/ (built into
// the executable), or a user's file of the same form. A preset sets the pipeline options'
// starting values; every option given on the command line overrides its value.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace bloomref::cli {

struct PipelineOptions;

struct PresetInfo {
  std::string name, title, source;
};

/// The built-in presets, by name.
std::vector<PresetInfo> builtin_presets();

/// Sets `o`'s options from preset `name_or_file` (a built-in name, or a path ending in .json).
/// Throws ParamError naming the preset and the key for an unknown preset, an unreadable file,
/// an unknown key or a value of the wrong kind.
/// `given`, when set, says which keys the command line gave: those are left as they are.
void apply_preset(const std::string& name_or_file, PipelineOptions& o,
                  const std::function<bool(const std::string& key)>& given = {});

}  // namespace bloomref::cli
