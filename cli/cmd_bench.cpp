// bloomref bench: per-stage and total times of the CPU path (thread wedge 1, 2, all; full and
// adaptive plans), the GL path (glFinish after every stage; renderer recorded) and the Vulkan
// path (a submit and wait per stage), the GPU paths' device time from timer queries beside
// their wall time, over sizes, medians after a warm-up, every timed output checked in the same
// run: CPU runs must give the 1-thread full plan's bits; GPU runs must stay within 2e-3 of the
// CPU display output (parity finds llvmpipe within 2e-7; 2e-3 is one 8-bit code's half).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <sstream>

#include "bloomref/error.h"
#include "escape.h"
#include "bloomref/executor.h"
#include "bloomref/gpu/gl_executor.h"
#include "bloomref/vulkan/executor.h"
#include "bloomref/io.h"
#include "bloomref/parallel.h"
#include "bloomref/scenes.h"
#include "bloomref/machine_ceiling.h"
#include "commands.h"
#include "json_out.h"
#include "options.h"
#include "pass_probe.h"
#include "timing.h"

namespace bloomref::cli {
namespace {

struct Row {
  std::string size, backend, plan;
  int threads = 0;
  long long pixels = 0;
  double total_ms = 0, blur_ms = 0;
  std::vector<std::pair<std::string, double>> stages;
  bool checked = false;
  std::string check;
  /// GPU backends: the device's own time (timer queries), median total and the last run's
  /// stages; negative where there is none (the CPU, a device without timers).
  double device_ms = -1;
  std::vector<std::pair<std::string, double>> device_stages;
};

void progress(int done, int total, const std::string& what) {
  if (!isatty(STDERR_FILENO)) return;
  const int width = 30, filled = total ? done * width / total : width;
  std::fprintf(stderr, "\r[%s%s] %d/%d %-40s", std::string(filled, '#').c_str(),
               std::string(width - filled, '.').c_str(), done, total, what.c_str());
  if (done == total) std::fprintf(stderr, "\n");
}

std::vector<std::pair<int, int>> parse_sizes(const std::string& s) {
  std::vector<std::pair<int, int>> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    int w = 0, h = 0;
    parse_size(item, w, h);
    out.emplace_back(w, h);
  }
  return out;
}

// Time spent in the blur (gaussian passes, or the mip chain and its full-size bloom). Where the
// dense f32 plan runs the bright stage and the finishing stages inside the fused blur (one
// timing, `bright+blur.1-10+composite+tonemap+output`), they are counted with it: they cannot
// be timed apart.
double blur_ms(const StageTrace& t) {
  double b = 0;
  for (const auto& [n, ms] : t.timings)
    if (n.rfind("blur.", 0) == 0 || n.rfind("bright+blur.", 0) == 0 || n.rfind("down.", 0) == 0 ||
        n.rfind("up.", 0) == 0 || n == "bloom")
      b += ms;
  return b;
}

struct BenchArgs {
  std::string sizes = "256x256,1024x1024,1920x1080,3840x2160";
  std::string out_dir;
  int repeat = 5;
  bool no_gl = false, no_vulkan = false, pass_probe = false;
  PipelineOptions pipeline;
};

// The GL context (none with --no-gl or when GL is unavailable) and the renderer's description.
std::string open_gl(bool no_gl, std::unique_ptr<gpu::GlContext>& ctx) {
  if (no_gl) return "none";
  try {
    ctx = gpu::GlContext::create();
    return ctx->info().renderer + ", " + ctx->info().version;
  } catch (const gpu::GlUnavailable& e) {
    return std::string("unavailable: ") + e.what();
  }
}

// Thread counts timed: 1, 2, and every thread when there are more.
std::vector<int> thread_wedge(int all) {
  std::vector<int> wedge = {1};
  if (all >= 2) wedge.push_back(2);
  if (all > 2) wedge.push_back(all);
  return wedge;
}

struct Progress {
  int done = 0, total = 0;
  void step(const std::string& what) { progress(++done, total, what); }
};

// One CPU configuration: a warm-up, then `repeat` timed runs; medians of the totals, blur times
// and stage times. Its output must have the bits of `reference` (the first configuration's, the
// 1-thread full plan, which sets it).
Row time_cpu(const BenchArgs& a, const std::string& size, const Image& scene, int threads,
             PlanMode mode, Image& reference) {
  BloomParams p = a.pipeline.params;
  p.threads = threads;
  p.plan = mode;
  // Each run is handed its own copy of the scene, made outside the timer, as `bloomref
  // run` hands over the image it read: what is timed starts from an image in memory, and
  // its plan's scan of the scene (the stage "plan").
  execute(make_plan(p, scene.cview()), Image(scene));  // warm-up, outside the timer
  std::vector<double> totals, blurs;
  std::vector<std::vector<double>> per_stage;
  StageTrace last;
  for (int r = 0; r < a.repeat; ++r) {
    Image copy(scene);
    last = execute(make_plan(p, scene.cview()), std::move(copy));
    totals.push_back(last.total_ms);
    blurs.push_back(blur_ms(last));
    per_stage.resize(last.timings.size());
    for (std::size_t i = 0; i < last.timings.size(); ++i)
      per_stage[i].push_back(last.timings[i].second);
  }
  Row row{size,
          "cpu",
          to_string(mode),
          threads,
          (long long)scene.width() * scene.height(),
          median(totals),
          median(blurs),
          {},
          true,
          "",
          -1.0,
          {}};
  for (std::size_t i = 0; i < last.timings.size(); ++i)
    row.stages.emplace_back(last.timings[i].first, median(per_stage[i]));
  if (reference.empty()) reference = last.final_image();
  const bool same = same_bits(reference, last.final_image());
  row.check = same ? "bit-identical to 1-thread full" : "DIFFERS from 1-thread full";
  row.checked = same;
  return row;
}

// A GPU backend's runs (`run_once` gives one run's trace): a warm-up (compiles the shaders),
// then `repeat` timed runs; its output within 2e-3 of the CPU reference's. Wall and device
// times apart: the device's from its timer queries.
template <class RunOnce>
Row time_device(const BenchArgs& a, const std::string& size, const Image& scene,
                const std::string& backend, const Image& reference, RunOnce run_once) {
  run_once();  // warm-up
  std::vector<double> totals, blurs, device;
  StageTrace last;
  for (int r = 0; r < a.repeat; ++r) {
    last = run_once();
    totals.push_back(last.total_ms);
    blurs.push_back(blur_ms(last));
    double d = 0;
    for (const auto& [n, ms] : last.device_timings) d += ms;
    if (!last.device_timings.empty()) device.push_back(d);
  }
  double worst = 0;
  for (std::size_t i = 0; i < reference.values().size(); ++i)
    if (i % 4 != 3)
      worst = std::max(worst,
                       double(std::fabs(reference.values()[i] - last.final_image().values()[i])));
  char b[48];
  std::snprintf(b, sizeof b, "max |%s - cpu| output %.3g", backend.c_str(), worst);
  return Row{size,
             backend,
             "full",
             0,
             (long long)scene.width() * scene.height(),
             median(totals),
             median(blurs),
             last.timings,
             worst <= 2e-3,
             b,
             device.empty() ? -1.0 : median(device),
             device.empty() ? std::vector<std::pair<std::string, double>>{} : last.device_timings};
}

Row time_gl(const BenchArgs& a, gpu::GlContext& ctx, const std::string& size, const Image& scene,
            gpu::ShaderKind k, const Image& reference) {
  gpu::GlOptions go;
  go.shaders = k;
  return time_device(a, size, scene, "gl-" + gpu::to_string(k), reference, [&] {
    return gpu::execute_gl(ctx, make_plan(a.pipeline.params, scene.cview()), scene.cview(), go);
  });
}

Row time_vulkan(const BenchArgs& a, vulkan::Context& ctx, const std::string& size,
                const Image& scene, const Image& reference) {
  return time_device(a, size, scene, "vulkan", reference, [&] {
    BloomParams p = a.pipeline.params;
    p.plan = PlanMode::full;  // the Vulkan run computes every stage whole
    return vulkan::execute_vulkan(ctx, make_plan(p, scene.cview()), scene.cview());
  });
}

// The Vulkan device (none with --no-vulkan or when there is none) and its description.
std::string open_vulkan(bool no_vulkan, std::unique_ptr<vulkan::Context>& ctx) {
  if (no_vulkan) return "none";
  try {
    ctx = vulkan::Context::create();
    return ctx->info().name + ", " + ctx->info().driver_info;
  } catch (const vulkan::VulkanUnavailable& e) {
    return std::string("unavailable: ") + e.what();
  }
}

void print_rows(const std::vector<Row>& rows, const std::string& renderer, int all, int repeat) {
  std::printf("renderer: %s; CPU threads available: %d; %d timed runs each, median\n",
              renderer.c_str(), all, repeat);
  std::printf("%-10s %-13s %-8s %-7s %10s %10s %10s  %s\n", "size", "backend", "plan", "threads",
              "total ms", "blur ms", "device ms", "check");
  for (const Row& r : rows) {
    char device[16] = "-";
    if (r.device_ms >= 0) std::snprintf(device, sizeof device, "%.1f", r.device_ms);
    std::printf("%-10s %-13s %-8s %-7d %10.1f %10.1f %10s  %s\n", r.size.c_str(),
                r.backend.c_str(), r.plan.c_str(), r.threads, r.total_ms, r.blur_ms, device,
                r.check.c_str());
  }
}

nlohmann::ordered_json rows_json(const std::vector<Row>& rows) {
  nlohmann::ordered_json jr = nlohmann::ordered_json::array();
  for (const Row& r : rows) {
    nlohmann::ordered_json st = nlohmann::ordered_json::object();
    for (const auto& [n, ms] : r.stages) st[n] = ms;
    nlohmann::ordered_json dev = nlohmann::ordered_json::object();
    for (const auto& [n, ms] : r.device_stages) dev[n] = ms;
    jr.push_back({{"size", r.size},
                  {"pixels", r.pixels},
                  {"backend", r.backend},
                  {"plan", r.plan},
                  {"threads", r.threads},
                  {"total_ms", r.total_ms},
                  {"blur_ms", r.blur_ms},
                  {"stages_ms", st},
                  {"device_total_ms", r.device_ms >= 0 ? nlohmann::ordered_json(r.device_ms)
                                                       : nlohmann::ordered_json(nullptr)},
                  {"device_stages_ms", dev},
                  {"check", r.check},
                  {"check_ok", r.checked}});
  }
  return jr;
}

std::string rows_csv(const std::vector<Row>& rows) {
  std::ostringstream csv;
  csv << "size,pixels,backend,plan,threads,total_ms,blur_ms,check_ok,device_ms\n";
  for (const Row& r : rows) {
    csv << r.size << "," << r.pixels << "," << r.backend << "," << r.plan << "," << r.threads << ","
        << r.total_ms << "," << r.blur_ms << "," << (r.checked ? 1 : 0) << ",";
    if (r.device_ms >= 0) csv << r.device_ms;
    csv << "\n";
  }
  return csv.str();
}

// Least-squares fits t = a + b n of total time against pixels, per (backend, plan, threads),
// printed and returned.
nlohmann::ordered_json linear_fits(const std::vector<Row>& rows) {
  nlohmann::ordered_json fits = nlohmann::ordered_json::array();
  std::vector<std::tuple<std::string, std::string, int>> keys;
  for (const Row& r : rows)
    if (std::find(keys.begin(), keys.end(), std::tuple{r.backend, r.plan, r.threads}) == keys.end())
      keys.emplace_back(r.backend, r.plan, r.threads);
  for (const auto& [b, pl, t] : keys) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
    int n = 0;
    for (const Row& r : rows)
      if (r.backend == b && r.plan == pl && r.threads == t) {
        const double x = r.pixels / 1e6, y = r.total_ms;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        ++n;
      }
    if (n < 2) continue;
    const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx), icpt = (sy - slope * sx) / n;
    const double r2 = std::pow(n * sxy - sx * sy, 2) / ((n * sxx - sx * sx) * (n * syy - sy * sy));
    fits.push_back({{"backend", b},
                    {"plan", pl},
                    {"threads", t},
                    {"ms_per_megapixel", slope},
                    {"intercept_ms", icpt},
                    {"r2", r2}});
    std::printf("fit %-13s %-8s %dt: %.1f ms/Mpx + %.1f ms, R^2 %.4f\n", b.c_str(), pl.c_str(), t,
                slope, icpt, r2);
  }
  return fits;
}

// Two threads against one, per size and plan (printed and returned).
nlohmann::ordered_json two_thread_speedups(const std::vector<Row>& rows) {
  nlohmann::ordered_json scaling = nlohmann::ordered_json::array();
  for (const Row& one : rows) {
    if (one.backend != "cpu" || one.threads != 1) continue;
    for (const Row& two : rows)
      if (two.backend == "cpu" && two.threads == 2 && two.size == one.size &&
          two.plan == one.plan) {
        std::printf("2 threads vs 1, %-10s %-8s: total %.2fx, blur %.2fx\n", one.size.c_str(),
                    one.plan.c_str(), one.total_ms / two.total_ms, one.blur_ms / two.blur_ms);
        scaling.push_back({{"size", one.size},
                           {"plan", one.plan},
                           {"total_speedup", one.total_ms / two.total_ms},
                           {"blur_speedup", one.blur_ms / two.blur_ms}});
      }
  }
  return scaling;
}

nlohmann::ordered_json ceilings_json(const std::vector<ParallelCeiling>& ceilings) {
  nlohmann::ordered_json cj = nlohmann::ordered_json::array();
  for (const ParallelCeiling& c : ceilings)
    cj.push_back({{"threads", c.threads},
                  {"latency_bound_speedup", c.compute},
                  {"throughput_bound_speedup", c.throughput},
                  {"memory_copy_speedup", c.memory},
                  {"copy_gb_per_s_1", c.copy_gb_per_s_one},
                  {"copy_gb_per_s_all", c.copy_gb_per_s_all}});
  return cj;
}

}  // namespace

std::function<int()> add_bench(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  CLI::App* sub =
      app.add_subcommand("bench", "time CPU, GL and Vulkan per stage, checking every output");
  sub->add_option("--sizes", a->sizes, "comma-separated WxH list")->capture_default_str();
  sub->add_option("--repeat", a->repeat, "timed runs per configuration (median reported)")
      ->capture_default_str();
  sub->add_option("--out", a->out_dir, "write bench.csv and bench.json to DIR");
  sub->add_flag("--no-gl", a->no_gl, "no GL runs");
  sub->add_flag("--no-vulkan", a->no_vulkan, "no Vulkan runs");
  sub->add_flag("--pass-probe", a->pass_probe,
                "time one 9-tap pass per size as a GL fragment pass, a GL compute pass and a "
                "Vulkan dispatch (device time, GB/s, the device's compute units) instead");
  a->pipeline.add_to(*sub);
  return [a, sub]() -> int {
    if (!sub->parsed()) return -1;
    a->pipeline.finish();
    if (a->repeat < 1) throw ParamError("--repeat must be >= 1");
    const auto sizes = parse_sizes(a->sizes);
    std::unique_ptr<gpu::GlContext> ctx;
    const std::string renderer = open_gl(a->no_gl, ctx);
    std::unique_ptr<vulkan::Context> vk;
    const std::string vulkan_device = open_vulkan(a->no_vulkan, vk);
    if (a->pass_probe) {
      bool ok = true;
      nlohmann::ordered_json probes = nlohmann::ordered_json::array();
      for (auto [w, h] : sizes)
        probes.push_back(pass_probe(a->pipeline.params, a->pipeline.scene, w, h, a->repeat,
                                    ctx.get(), vk.get(), ok));
      std::printf("gl: %s\nvulkan: %s\n", renderer.c_str(), vulkan_device.c_str());
      if (!a->out_dir.empty()) {
        std::filesystem::create_directories(a->out_dir);
        save_text((std::filesystem::path(a->out_dir) / "pass-probe.json").string(),
                  escape::json_text(nlohmann::ordered_json{{"renderer", renderer},
                                                           {"vulkan_device", vulkan_device},
                                                           {"probes", probes}}) + "\n");
      }
      return ok ? 0 : 1;
    }
    const int all = resolve_threads(0);
    const std::vector<int> wedge = thread_wedge(all);
    // The machine's own ceilings for the thread wedge, before and after the timed runs (the
    // neighbours of a virtual machine come and go): register-only work, latency- and
    // throughput-bound, and memory copy.
    std::vector<ParallelCeiling> ceilings;
    if (all >= 2) ceilings.push_back(parallel_ceiling(2));
    const int per_size = static_cast<int>(wedge.size()) * 2 + (ctx ? 2 : 0) + (vk ? 1 : 0);
    Progress bar{0, per_size * static_cast<int>(sizes.size())};
    std::vector<Row> rows;
    for (auto [w, h] : sizes) {
      const std::string size = std::to_string(w) + "x" + std::to_string(h);
      const Image scene = make_scene(a->pipeline.scene, w, h);
      Image reference;  // the 1-thread full plan's output
      for (PlanMode mode : {PlanMode::full, PlanMode::adaptive})
        for (int t : wedge) {
          rows.push_back(time_cpu(*a, size, scene, t, mode, reference));
          bar.step(size + " cpu " + std::to_string(t) + "t " + to_string(mode));
        }
      if (ctx)
        for (gpu::ShaderKind k : {gpu::ShaderKind::fragment, gpu::ShaderKind::compute}) {
          rows.push_back(time_gl(*a, *ctx, size, scene, k, reference));
          bar.step(size + " gl " + gpu::to_string(k));
        }
      if (vk) {
        rows.push_back(time_vulkan(*a, *vk, size, scene, reference));
        bar.step(size + " vulkan");
      }
    }
    if (all >= 2) ceilings.push_back(parallel_ceiling(2));
    print_rows(rows, renderer, all, a->repeat);
    std::printf("vulkan: %s\n", vulkan_device.c_str());
    nlohmann::ordered_json j = {
        {"renderer", renderer},
        {"vulkan_device", vulkan_device},
        {"threads_available", all},
        {"repeat", a->repeat},
        {"params", params_json(a->pipeline.params)},
        {"timing", "CPU: steady_clock per stage; GL: glFinish after each stage, and the device's "
                   "time from GL_TIME_ELAPSED queries; Vulkan: a submit and wait per stage, and "
                   "the device's time from timestamps around each dispatch"}};
    const nlohmann::ordered_json fits = linear_fits(rows);
    nlohmann::ordered_json scaling = nlohmann::ordered_json::array();
    if (all >= 2) {
      for (const ParallelCeiling& c : ceilings) std::printf("%s\n", describe(c).c_str());
      scaling = two_thread_speedups(rows);
      j["machine_ceiling_before_after"] = ceilings_json(ceilings);
    }
    j["two_thread_speedup"] = scaling;
    j["rows"] = rows_json(rows);
    j["fits"] = fits;
    if (!a->out_dir.empty()) {
      std::filesystem::create_directories(a->out_dir);
      save_text((std::filesystem::path(a->out_dir) / "bench.json").string(), escape::json_text(j) + "\n");
      save_text((std::filesystem::path(a->out_dir) / "bench.csv").string(), rows_csv(rows));
    }
    bool all_ok = true;
    for (const Row& r : rows) all_ok &= r.checked;
    return all_ok ? 0 : 1;
  };
}

}  // namespace bloomref::cli
