// bloomref run [IN] -o OUT.exr|OUT.png ... : the main job.
#include <filesystem>
#include <stdexcept>
#include <iostream>
#include <memory>
#include <optional>

#include "bloomref/error.h"
#include "escape.h"
#include "bloomref/executor.h"
#include "bloomref/gpu/gl_executor.h"
#include "bloomref/io.h"
#include "bloomref/output_files.h"
#include "bloomref/parallel.h"
#include "bloomref/scenes.h"
#include "bloomref/vulkan/executor.h"
#include "batch/run_sequence.h"
#include "commands.h"
#include "json_out.h"
#include "options.h"
#include "timing.h"

namespace bloomref::cli {
namespace {

struct RunArgs {
  std::string input;
  std::vector<std::string> outputs;
  std::string backend = "cpu";
  std::string gl_shaders = "fragment";
  std::string fault = "none";  // --inject-fault (GL backend)
  std::string dump_dir;
  std::string dump_compression = "none";
  std::string json_path;
  bool quiet = false;
  int repeat = 1;
  PipelineOptions pipeline;
  SequenceOptions sequence;  ///< --frames, --shard, --resume, --jobs (batch/run_sequence.h)
};

constexpr int kMaxRepeat = 100000;

/// Runs 2..repeat of the CPU pipeline in this process. The first run (the trace given) pays a
/// page fault for every page its buffers touch; later runs reuse what earlier ones freed as far
/// as the C library's allocator keeps it (glibc gives large buffers back to the kernel for the
/// first few runs, which are then slower than the later ones). Each run gets its own copy of the
/// input, made outside the timer, and must give the first run's output bits. Each run makes its
/// plan again (its scan of the scene is timed as the stage "plan"). Returns the JSON entry.
nlohmann::ordered_json repeat_runs(const Plan& plan, const Image& input, const StageTrace& first,
                                   int repeat) {
  // The same parameters and scene each time, so every run's timings list the same stages in the
  // same order.
  std::vector<std::vector<double>> stage_ms(first.timings.size());
  std::vector<double> totals{first.total_ms};
  for (int r = 1; r < repeat; ++r) {
    Image copy = input;
    const StageTrace t = execute(make_plan(plan.params, input.cview()), std::move(copy), ExecuteOptions{});
    if (!same_bits(t.final_image(), first.final_image()))
      throw std::runtime_error("run " + std::to_string(r + 1) +
                               " of --repeat gave other bits than the first");
    totals.push_back(t.total_ms);
    for (std::size_t i = 0; i < stage_ms.size(); ++i) stage_ms[i].push_back(t.timings[i].second);
  }
  nlohmann::ordered_json warm = nlohmann::ordered_json::object();
  for (std::size_t i = 0; i < stage_ms.size(); ++i)
    warm[first.timings[i].first] = median(stage_ms[i]);
  warm["total"] = median(std::vector<double>(totals.begin() + 1, totals.end()));
  return {{"runs", repeat},
          {"total_ms", totals},
          {"first_ms", first.total_ms},
          {"warm_median_ms", warm},
          {"same_bits", true}};
}

// The options that do not go together, or leave nothing to write: exit 2 before any work.
void check_run_args(const RunArgs& a, bool records) {
  if (a.backend != "cpu" && a.backend != "gl" && a.backend != "vulkan")
    throw ParamError("--backend '" + a.backend + "' is not one of: cpu, gl, vulkan");
  if (a.repeat < 1) throw ParamError("--repeat must be >= 1");
  if (a.fault != "none" && a.backend != "gl") throw ParamError("--inject-fault needs --backend gl");
  if (a.fault != "none") gpu::parse_fault(a.fault);  // an unknown name before any work
  // Every run's timings are kept for the medians and listed in the JSON: bounded memory.
  if (a.repeat > kMaxRepeat)
    throw ParamError("--repeat must be at most " + std::to_string(kMaxRepeat) +
                     " (every run's timings are kept for the medians and the JSON)");
  if (a.repeat > 1 && a.backend != "cpu") throw ParamError("--repeat times the CPU backend only");
  if (a.repeat > 1 && !a.dump_dir.empty())
    throw ParamError("--repeat and --dump-stages do not go together (stages kept change the timings)");
  if (a.outputs.empty() && a.dump_dir.empty() && a.json_path.empty() && !records)
    throw ParamError("nothing to write: give -o OUT.exr and/or -o OUT.png (or --dump-stages, --json)");
}

// The console's summary of one run.
void print_run(const RunArgs& a, const std::string& source, const Plan& plan,
               const StageTrace& trace, const nlohmann::ordered_json& repeated) {
  const NonFiniteCounts& c = plan.facts.nonfinite;
  std::cout << source << ": " << plan.facts.width << "x" << plan.facts.height << ", "
            << plan.facts.bright_pixels << " bright pixels, " << c.total()
            << " non-finite values (" << to_string(plan.params.nonfinite) << "), "
            << trace.total_ms << " ms";
  if (!repeated.is_null())
    std::cout << " (first of " << a.repeat << " runs; the others' median "
              << repeated["warm_median_ms"]["total"].get<double>() << " ms)";
  const auto skipped = plan.skipped_names();
  if (!skipped.empty()) std::cout << ", skipped " << skipped.size() << " stage(s)";
  for (const std::string& o : a.outputs) std::cout << "\n  wrote " << o;
  if (!a.dump_dir.empty())
    std::cout << "\n  wrote " << trace.stages.size() << " stages to " << a.dump_dir << "/";
  std::cout << "\n";
}

// `record` (sequences): the frame's size, counts and pipeline time.
int run(const RunArgs& a, nlohmann::ordered_json* record = nullptr) {
  check_run_args(a, record != nullptr);
  // Every destination is checked before the (possibly long) work starts, and the outputs are
  // published together at the end (OutputSet): a refusal or a failure leaves every destination
  // as it was. The input is never a destination, and no file is written twice.
  namespace fs = std::filesystem;
  OutputSet outs;
  outs.protect(a.input);
  for (const std::string& o : a.outputs) {
    const std::string e = fs::path(o).extension().string();
    if (e != ".exr" && e != ".png" && e != ".EXR" && e != ".PNG")
      throw InputError(o, (e.empty() ? std::string("has no extension") : "cannot write '" + e + "' files") +
                              ": the output must end in .exr or .png");
    outs.add_file(o, "-o");
  }
  if (!a.json_path.empty()) outs.add_file(a.json_path, "--json");
  if (!a.dump_dir.empty()) outs.add_folder(a.dump_dir, "--dump-stages", /*whole=*/false);
  // The CPU pipeline's threads start while the input is read.
  std::optional<ThreadsStarting> starting;
  if (a.backend == "cpu") starting.emplace(a.pipeline.params.threads);
  std::string source;
  LoadedImage in = a.pipeline.load_input(a.input, source);
  if (!a.dump_dir.empty())
    for (const std::string& name :
         stage_names(a.pipeline.params, in.image.width(), in.image.height()))
      outs.add_file((fs::path(a.dump_dir) / (name + ".exr")).string(), "--dump-stages");

  const Plan plan = make_plan(a.pipeline.params, in.image.cview(), source);
  StageTrace trace;
  nlohmann::ordered_json repeated;  // --repeat's entry in the JSON
  std::string renderer = "cpu";
  if (a.backend == "gl") {
    auto ctx = gpu::GlContext::create();  // GlUnavailable -> exit 3
    gpu::GlOptions go;
    go.shaders = gpu::parse_shader_kind(a.gl_shaders);
    go.keep_all = !a.dump_dir.empty();
    go.fault = a.fault == "none" ? gpu::Fault::none : gpu::parse_fault(a.fault);
    trace = gpu::execute_gl(*ctx, plan, in.image.cview(), go);
    renderer = "gl (" + gpu::to_string(go.shaders) + " shaders): " + ctx->info().renderer +
               ", " + ctx->info().version;
  } else if (a.backend == "vulkan") {
    auto ctx = vulkan::Context::create();  // VulkanUnavailable -> exit 3
    trace = vulkan::execute_vulkan(*ctx, plan, in.image.cview());
    renderer = "vulkan (compute, bloomref's stage shaders): " + ctx->info().name + ", " +
               ctx->info().driver_info;
  } else {
    ExecuteOptions eo;
    eo.keep_all = !a.dump_dir.empty();
    if (a.repeat > 1) {
      Image copy = in.image;  // kept for the repeated runs
      trace = execute(plan, std::move(copy), eo);
      repeated = repeat_runs(plan, in.image, trace, a.repeat);
    } else {
      trace = execute(plan, std::move(in.image), eo);  // the input is not needed afterwards
    }
  }

  const ImageInfo* windows = a.input.empty() ? nullptr : &in.info;
  for (const std::string& o : a.outputs) outs.write_image(o, trace.final_image().cview(), windows);
  if (!a.dump_dir.empty())
    for (const StageResult& s : trace.stages)
      outs.write_image((fs::path(a.dump_dir) / (s.name + ".exr")).string(), s.image.cview(),
                       windows, parse_exr_compression(a.dump_compression, "--dump-compression"));
  if (!a.json_path.empty()) {
    nlohmann::ordered_json j = run_json(plan, trace);
    if (a.backend != "cpu") j["renderer"] = renderer;
    j["input"] = {{"path", in.info.path},     {"format", in.info.format},
                  {"layout", in.info.layout}, {"channels", in.info.channels},
                  {"has_alpha", in.info.has_alpha}};
    j["outputs"] = a.outputs;
    if (!repeated.is_null()) j["repeat"] = repeated;
    outs.write_text(a.json_path, escape::json_text(j) + "\n");
  }
  outs.publish();
  if (record)
    *record = {{"width", plan.facts.width}, {"height", plan.facts.height},
               {"bright_pixels", plan.facts.bright_pixels},
               {"nonfinite", plan.facts.nonfinite.total()}, {"pipeline_ms", trace.total_ms}};
  if (!a.quiet) print_run(a, source, plan, trace, repeated);
  return 0;
}

}  // namespace

std::function<int()> add_run(CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* sub = app.add_subcommand("run", "apply bloom to an image or a frame sequence (or a built-in scene)");
  sub->add_option("IN", args->input, "input image (EXR, HDR, PNG, TIFF...); none = --scene");
  sub->add_option("-o,--output", args->outputs, "output .exr (float, display-referred) or .png; repeatable");
  sub->add_option("--backend", args->backend,
                  "cpu | gl | vulkan (Vulkan compute: gaussian and seed 002's chain)")
      ->capture_default_str();
  sub->add_option("--gl-shaders", args->gl_shaders, "fragment | compute (GL backend)")
      ->capture_default_str();
  sub->add_option("--inject-fault", args->fault,
                  "GL backend: a deliberate bug, as compare's (to see that a check catches it)")
      ->capture_default_str();
  sub->add_option("--dump-stages", args->dump_dir, "write DIR/<stage>.exr for every stage");
  sub->add_option("--dump-compression", args->dump_compression,
                  "--dump-stages files, all lossless: none (fastest to write and to check, 16 "
                  "bytes a texel) | rle | zips | zip (about a fifth of the size, check slower) | "
                  "piz (smallest on grainy images)")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "rle", "zips", "zip", "piz"}));
  sub->add_option("--json", args->json_path, "write parameters, timings and counts as JSON");
  sub->add_flag("-q,--quiet", args->quiet, "print nothing on success");
  sub->add_option("--repeat", args->repeat,
                  "run the CPU pipeline N times in this process, each output checked against the "
                  "first; --json gets the first run's timings and the others' medians")
      ->capture_default_str();
  args->pipeline.add_to(*sub);
  args->sequence.add_to(*sub, true);
  return [args, sub]() -> int {
    if (!sub->parsed()) return -1;
    args->pipeline.finish();
    args->pipeline.kept_traces = args->dump_dir.empty() ? 0 : 1;
    args->pipeline.gl = args->backend == "gl";
    const RunSequenceArgs seq{args->input,     args->outputs, args->dump_dir,
                              args->json_path, args->quiet,   args->pipeline.params,
                              args->sequence};
    if (!is_run_sequence(seq)) return run(*args);
    if (args->repeat > 1) throw ParamError("--repeat times one image, not a sequence");
    return run_sequence(seq, [&args](const FrameFiles& f, nlohmann::ordered_json& record) {
      RunArgs a = *args;  // one frame: its own files, no results file, nothing printed
      a.input = f.input;
      a.outputs = f.outputs;
      a.dump_dir = f.dump_dir;
      a.json_path.clear();
      a.quiet = true;
      a.pipeline.params.threads = f.threads;
      run(a, &record);
    });
  };
}

}  // namespace bloomref::cli
