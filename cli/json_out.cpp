#include "json_out.h"

#include <charconv>
#include <string>

#include "bloomref/memory_budget.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"

namespace bloomref::cli {
namespace {
// A float parameter as the shortest decimal that reads back to it (2.2f -> 2.2, not
// 2.200000047683716).
double shortest(float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::stod(std::string(buf, r.ptr));
}
}  // namespace

nlohmann::ordered_json params_json(const BloomParams& p) {
  std::vector<double> factors;
  for (float f : p.level_factors) factors.push_back(shortest(f));
  std::vector<double> sigmas;
  for (float s : p.level_sigmas) sigmas.push_back(shortest(s));
  return {{"method", to_string(p.method)},       {"threshold", shortest(p.threshold)},
          {"exposure", shortest(p.exposure)},              {"gamma", shortest(p.gamma)},
          {"strength", shortest(p.strength)},              {"passes", p.passes},
          {"kernel", to_string(p.kernel)},       {"storage", to_string(p.storage)},
          {"precision", to_string(p.precision)}, {"nonfinite", to_string(p.nonfinite)},
          {"subtexel_bits", p.subtexel_bits},    {"threads", resolve_threads(p.threads)},
          {"plan", to_string(p.plan)},          {"blur", to_string(p.blur)},
          {"levels", p.levels},             {"karis", p.karis},
          {"composite", to_string(p.composite)}, {"composite_mode", to_string(p.composite_mode)},
          {"first_axis", to_string(p.first_axis)},
          {"luma", to_string(p.luma)},
          {"luma_space", to_string(p.luma_space)},
          {"prefilter", to_string(p.prefilter)}, {"karis_form", to_string(p.karis_form)},
          {"texel_step", to_string(p.texel_step)}, {"upsample_radius", shortest(p.upsample_radius)},
          {"bloom_upscale", to_string(p.bloom_upscale)},
          {"chain_storage", to_string(p.level_storage())},
          {"first_level_height", p.first_level_height},
          {"knee", shortest(p.knee)},
          {"level_combine", to_string(p.level_combine)},
          {"level_weights", to_string(p.level_weights)},
          {"level_weight", shortest(p.level_weight)},
          {"knee_form", to_string(p.knee_form)},
          {"clamp_max", shortest(p.clamp_max)},
          {"first_downsample", to_string(p.first_downsample)},
          {"downsample", to_string(p.downsample)},
          {"upsample", to_string(p.upsample)},
          {"level_count", to_string(p.level_count)},
          {"smooth_width", shortest(p.smooth_width)},
          {"level_kernels", p.level_kernels},
          {"level_sigmas", sigmas},
          {"level_normalise", p.level_normalise},
          {"level_factors", factors},
          {"level_radius", shortest(p.level_radius)},
          {"level_strength", shortest(p.level_strength)}};
}

std::string cpu_renderer(const BloomParams& p) {
  const bool f32 = p.precision == Precision::f32;
  std::string blur = "reference blur";
  if (f32 && p.blur == BlurImpl::fast) blur = "fast blur, " + blur_isa_name();
  if (f32 && p.blur == BlurImpl::approx)
    blur = "approximate blur, " + (blur_isa_name() != "generic" ? blur_isa_name() + "+fma" : "generic");
  return "cpu: bloomref " + to_string(p.precision) + " (" + blur + "), " +
         std::to_string(resolve_threads(p.threads)) +
         (resolve_threads(p.threads) == 1 ? " thread" : " threads");
}

nlohmann::ordered_json counts_json(const NonFiniteCounts& c) {
  return {{"nan", c.nan}, {"pos_inf", c.pos_inf}, {"neg_inf", c.neg_inf},
          {"beyond_2^120_clamped", c.out_of_range}};
}

nlohmann::ordered_json run_json(const Plan& plan, const StageTrace& trace) {
  nlohmann::ordered_json timings = nlohmann::ordered_json::object();
  for (const auto& [name, ms] : trace.timings) timings[name] = ms;
  timings["total"] = trace.total_ms;
  nlohmann::ordered_json device = nlohmann::ordered_json::object();
  double device_total = 0;
  for (const auto& [name, ms] : trace.device_timings) {
    device[name] = ms;
    device_total += ms;
  }
  if (!trace.device_timings.empty()) device["total"] = device_total;
  return {{"params", params_json(plan.params)},
          {"renderer", cpu_renderer(plan.params)},
          {"timings_ms", timings},
          {"device_timings_ms", device},
          {"skipped", plan.skipped_names()},
          {"skipped_texel_fraction", [&] {
             nlohmann::ordered_json f = nlohmann::ordered_json::object();
             for (const auto& [name, frac] : trace.skipped_fraction) f[name] = frac;
             return f;
           }()},
          {"nonfinite", counts_json(plan.facts.nonfinite)},
          {"bright_pixels", plan.facts.bright_pixels},
          // The adaptive plan's verdict on the scene: blurred whole, no support tracked.
          {"dense_scene", plan.dense_scene},
          {"small_scene", plan.small_scene},
          {"mip_levels_used", plan.levels.size()},
          {"peak_rss_bytes", peak_rss_bytes()},
          {"width", plan.facts.width},
          {"height", plan.facts.height}};
}

}  // namespace bloomref::cli
