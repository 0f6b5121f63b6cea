// bloomref check in this process, for callers that want its results as data (the Python module).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "check/types.h"

namespace bloomref::cli {

/// Runs `bloomref check ARGS` (the arguments after the word "check") and returns what its
/// --json writes (docs/schemas/check-result.v1.json): "verdict" is NOTHING and "exit_code" 5
/// when no stage image matched. The files named by --json, --junit, --markdown and --report are
/// written as the command writes them; the console's lines are printed unless -q is given.
/// Throws ParamError for a command line that does not parse (CLI11's message), and what the
/// command throws: InputError and ParamError (exit 2), gpu::GlUnavailable (exit 3).
/// `memory`, when given, is the one item: its scene and stage images in memory (or paths),
/// each under the caller's name, in place of SCENE and --stages; nothing is written for them.
nlohmann::ordered_json check_results(const std::vector<std::string>& args,
                                     const InMemoryItem* memory = nullptr);

}  // namespace bloomref::cli
