#include "pass_probe.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "bloomref/executor.h"
#include "bloomref/gpu/gl_executor.h"
#include "bloomref/plan.h"
#include "bloomref/scenes.h"
#include "bloomref/vulkan/executor.h"
#include "timing.h"

namespace bloomref::cli {
namespace {

const StageResult* stage(const StageTrace& t, const std::string& name) {
  for (const StageResult& s : t.stages)
    if (s.name == name) return &s;
  return nullptr;
}

double time_of(const std::vector<std::pair<std::string, double>>& timings, const std::string& name) {
  for (const auto& [n, ms] : timings)
    if (n == name) return ms;
  return -1;
}

// The largest |device - cpu| over the magnitude max(1, |cpu|), colour channels only.
double relative_difference(const Image& device, const Image& cpu) {
  double worst = 0;
  const auto& a = device.values();
  const auto& b = cpu.values();
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    if (i % 4 != 3)
      worst = std::max(worst, std::fabs(double(a[i]) - double(b[i])) / std::max(1.0, std::fabs(double(b[i]))));
  return worst;
}

}  // namespace

nlohmann::ordered_json pass_probe(const BloomParams& params, const std::string& scene_name,
                                  int width, int height, int repeat, gpu::GlContext* gl,
                                  vulkan::Context* vk, bool& all_checked) {
  BloomParams p = params;
  p.method = Method::gaussian;
  p.passes = 1;
  p.plan = PlanMode::full;
  const Image scene = make_scene(scene_name, width, height);
  const Plan plan = make_plan(p, scene.cview());
  ExecuteOptions eo;
  eo.keep_all = true;
  const StageTrace cpu = execute(plan, scene.cview(), eo);
  const Image& reference = stage(cpu, "blur.1")->image;
  const double texel_bytes = p.storage == Storage::f32 ? 16.0 : p.storage == Storage::f16 ? 8.0 : 4.0;
  const double bytes = 2.0 * texel_bytes * double(width) * double(height);

  struct Api {
    std::string name;
    std::function<StageTrace()> run;
  };
  std::vector<Api> apis;
  if (gl)
    for (gpu::ShaderKind k : {gpu::ShaderKind::fragment, gpu::ShaderKind::compute})
      apis.push_back({"gl-" + gpu::to_string(k), [&, k] {
                        gpu::GlOptions go;
                        go.shaders = k;
                        go.keep_all = true;
                        return gpu::execute_gl(*gl, plan, scene.cview(), go);
                      }});
  if (vk) apis.push_back({"vulkan", [&] { return vulkan::execute_vulkan(*vk, plan, scene.cview()); }});

  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  std::printf("pass probe: one 9-tap pass (blur.1) at %dx%d, %s storage, medians of %d\n", width,
              height, to_string(p.storage).c_str(), repeat);
  std::printf("  %-12s %10s %10s %14s  %s\n", "api", "wall ms", "device ms", "GB/s (device)", "check");
  for (const Api& api : apis) {
    api.run();  // warm-up: compiling, first allocation
    std::vector<double> wall, device;
    StageTrace last;
    for (int r = 0; r < repeat; ++r) {
      last = api.run();
      wall.push_back(time_of(last.timings, "blur.1"));
      const double d = time_of(last.device_timings, "blur.1");
      if (d > 0) device.push_back(d);
    }
    // A device time for every run, each between 1% and 105% of the stage's wall time, or none:
    // llvmpipe's GL timer queries do not time compute dispatches (they give 1e-6 ms there).
    bool plausible = device.size() == wall.size();
    for (std::size_t r = 0; plausible && r < device.size(); ++r)
      plausible = device[r] >= 0.01 * wall[r] && device[r] <= 1.05 * wall[r];
    const double dev = plausible ? median(device) : -1;
    const StageResult* s = stage(last, "blur.1");
    const double diff = s ? relative_difference(s->image, reference) : INFINITY;
    const bool ok = diff <= 1e-3;
    all_checked &= ok;
    const double gbps = dev > 0 ? bytes / (dev * 1e-3) / 1e9 : -1;
    char dev_text[32] = "-", gbps_text[32] = "-";
    if (dev > 0) std::snprintf(dev_text, sizeof dev_text, "%.3f", dev);
    if (gbps > 0) std::snprintf(gbps_text, sizeof gbps_text, "%.2f", gbps);
    std::printf("  %-12s %10.3f %10s %14s  %s (max relative difference %.2g)\n", api.name.c_str(),
                median(wall), dev_text, gbps_text, ok ? "ok" : "FAILED", diff);
    rows.push_back({{"api", api.name},
                    {"wall_ms", median(wall)},
                    {"device_ms", dev > 0 ? nlohmann::ordered_json(dev) : nlohmann::ordered_json()},
                    {"device_gb_per_s", gbps > 0 ? nlohmann::ordered_json(gbps) : nlohmann::ordered_json()},
                    {"checked", ok},
                    {"max_relative_difference", diff}});
  }
  nlohmann::ordered_json j = {{"size", std::to_string(width) + "x" + std::to_string(height)},
                              {"storage", to_string(p.storage)},
                              {"repeat", repeat},
                              {"bytes_per_pass", bytes},
                              {"gl_renderer", gl ? gl->info().renderer : ""},
                              {"vulkan_device", vk ? vk->info().name : ""},
                              {"compute_units", vk ? vk->info().compute_units : 0},
                              {"compute_units_from", vk ? vk->info().compute_units_from : "no Vulkan device"},
                              {"rows", rows}};
  if (vk)
    std::printf("  Vulkan device %s: %u compute units (%s)\n", vk->info().name.c_str(),
                vk->info().compute_units, vk->info().compute_units_from.c_str());
  return j;
}

}  // namespace bloomref::cli
