// Machine-readable results (docs/usage.md; the schemas in docs/schemas/).
#pragma once

#include <nlohmann/json.hpp>

#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "bloomref/params.h"

namespace bloomref::cli {

nlohmann::ordered_json params_json(const BloomParams& p);

/// "cpu: bloomref f32 (fast blur, avx2), 2 threads" -- what computed a CPU run.
std::string cpu_renderer(const BloomParams& p);
nlohmann::ordered_json counts_json(const NonFiniteCounts& c);
/// params, renderer, timings_ms (stage -> ms, plus "total"), skipped, nonfinite, plan facts.
nlohmann::ordered_json run_json(const Plan& plan, const StageTrace& trace);

}  // namespace bloomref::cli
