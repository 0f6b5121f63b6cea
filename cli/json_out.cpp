#include "json_out.h"

#include "bloomref/parallel.h"

namespace bloomref::cli {

nlohmann::json params_json(const BloomParams& p) {
  return {{"method", to_string(p.method)},       {"threshold", p.threshold},
          {"exposure", p.exposure},              {"gamma", p.gamma},
          {"strength", p.strength},              {"passes", p.passes},
          {"kernel", to_string(p.kernel)},       {"storage", to_string(p.storage)},
          {"precision", to_string(p.precision)}, {"nonfinite", to_string(p.nonfinite)},
          {"subtexel_bits", p.subtexel_bits},    {"threads", resolve_threads(p.threads)},
          {"plan", to_string(p.plan)}};
}

nlohmann::json counts_json(const NonFiniteCounts& c) {
  return {{"nan", c.nan}, {"pos_inf", c.pos_inf}, {"neg_inf", c.neg_inf}};
}

nlohmann::json run_json(const Plan& plan, const StageTrace& trace) {
  nlohmann::json timings = nlohmann::json::object();
  for (const auto& [name, ms] : trace.timings) timings[name] = ms;
  timings["total"] = trace.total_ms;
  return {{"params", params_json(plan.params)},
          {"renderer", "cpu: bloomref reference (" + to_string(plan.params.precision) + ", " +
                           std::to_string(resolve_threads(plan.params.threads)) + " threads)"},
          {"timings_ms", timings},
          {"skipped", plan.skipped_names()},
          {"nonfinite", counts_json(plan.facts.nonfinite)},
          {"bright_pixels", plan.facts.bright_pixels},
          {"width", plan.facts.width},
          {"height", plan.facts.height}};
}

}  // namespace bloomref::cli
