// How the stages of a plan read one another (internal to parity): what compare_captured and the
// cause hypotheses both walk.
#pragma once

#include <string>
#include <vector>

#include "bloomref/plan.h"

namespace bloomref::parity::detail {

/// The stages `spec` reads, in the order its function takes them: blur.k reads the pass before
/// it (or bright), down.k the level above (or input), up.k the smaller level and down.k, bloom
/// up.1 (or the last down level), composite its base (input, or tonemap after the tone map) and
/// the bloom, tonemap and output the stage before them. `input` and `bright` read the scene
/// (bright reads it unrounded, as the seeds' MRT draw does), listed as nothing.
std::vector<std::string> stage_inputs(const Plan& plan, const StageSpec& spec);

/// The spec named `name`, or nullptr.
const StageSpec* find_stage(const Plan& plan, const std::string& name);

}  // namespace bloomref::parity::detail
