// bloomref check SCENE --stages DIR | --manifest FILE: anyone's bloom, captured as stage images,
// judged stage by stage against the CPU oracle (parity/), with the likely cause of a failure.
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <map>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <set>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "bloomref/output_files.h"
#include "bloomref/parity/compare.h"
#include "check_manifest.h"
#include "check_output.h"
#include "check_shaders.h"
#include "check_types.h"
#include "commands.h"
#include "options.h"
#include "report.h"

namespace fs = std::filesystem;

namespace bloomref::cli {
namespace {

struct CheckArgs {
  std::string scene, stages_dir, manifest, profile = "nvidia";
  std::string json_path, junit_path, markdown_path, report_dir, expectations;
  std::string encoding = "auto", origin = "top", channels = "RGBA", raw_format = "f32";
  std::string artifacts = "fail";
  DeviceKeys device;
  bool warn_as_error = false, quiet = false, no_causes = false;
  PipelineOptions pipeline;
  ShaderArgs shaders;
  CLI::App* sub = nullptr;
};

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

ItemResult check_item(const CheckItem& item, const CheckArgs& a, const parity::DeviceProfile& profile,
                      bool causes) {
  ItemResult r;
  r.id = item.id;
  const auto t0 = std::chrono::steady_clock::now();
  std::string source;
  const LoadedImage scene = a.pipeline.load_input(item.scene, source);
  r.source = source;
  const Plan plan = parity::plan_for_device(a.pipeline.params, scene.image.cview(), profile, source);
  r.width = plan.facts.width;
  r.height = plan.facts.height;
  std::vector<StageFile> files = item.files;
  if (!item.stages_dir.empty()) {
    r.stages_from = item.stages_dir;
    files = find_stage_files(item.stages_dir, plan, item.defaults, item.aliases, r.ignored);
  }
  for (const StageFile& f : files) require_stage_in_plan(f, plan);
  for (const StageFile& f : files) r.file_of[f.stage] = f.path;
  r.load_ms = ms_since(t0);
  if (files.empty()) return r;  // nothing compared: the caller says so
  // Files are read in plan order as the comparison reaches them, the next one on another
  // thread meanwhile (OpenEXR decodes each on all threads), and released when no later stage
  // reads them.
  std::vector<std::string> names;
  std::map<std::string, const StageFile*> by_stage;
  for (const StageSpec& s : plan.stages)
    for (const StageFile& f : files)
      if (f.stage == s.name) {
        names.push_back(s.name);
        by_stage[s.name] = &f;
      }
  auto read = [&plan, &by_stage](const std::string& stage) {
    int w = 0, h = 0;
    stage_size(plan, stage, w, h);
    return load_stage(*by_stage.at(stage), w, h);
  };
  std::map<std::string, std::future<LoadedStage>> ahead;
  double load_ms = 0;
  auto loader = [&](const std::string& stage) {
    const auto t = std::chrono::steady_clock::now();
    auto it = ahead.find(stage);
    LoadedStage l = it != ahead.end() ? it->second.get() : read(stage);
    if (it != ahead.end()) ahead.erase(it);
    const auto next = std::find(names.begin(), names.end(), stage) + 1;
    if (next != names.end() && !ahead.count(*next))
      ahead[*next] = std::async(std::launch::async, read, *next);
    load_ms += ms_since(t);
    return parity::OwnedCapture{std::move(l.image), l.code_bits, l.srgb};
  };
  parity::CompareOptions co;
  co.causes = causes;
  co.keep_images = !a.report_dir.empty() && a.artifacts != "none";
  co.keep_failing_only = a.artifacts == "fail";
  const auto t1 = std::chrono::steady_clock::now();
  r.parity = parity::compare_streamed(plan, scene.image.cview(), names, loader, profile, co,
                                      &r.oracle_ms);
  r.load_ms += load_ms;
  r.judge_ms = ms_since(t1) - r.oracle_ms - load_ms;
  if (!a.report_dir.empty()) {
    // The report shows the captures of the stages it holds images of: read again.
    StageTrace trace;
    for (const parity::StageComparison& s : r.parity.isolated)
      if (!s.oracle.empty()) trace.stages.push_back({s.stage, read(s.stage).image, 0, false});
    const std::string dir = a.report_dir + (item.id.empty() ? "" : "/" + item.id);
    write_report(dir, source, "captured stages: " + (r.stages_from.empty() ? item.id : r.stages_from),
                 plan, trace, r.parity, "none");
  }
  return r;
}

void print_item(const ItemResult& r, const parity::DeviceProfile& profile) {
  std::printf("%s: %s %dx%d, profile %s, %zu stage image(s)%s%s\n", r.id.c_str(), r.source.c_str(),
              r.width, r.height, profile.name.c_str(), r.file_of.size(),
              r.stages_from.empty() ? "" : " from ", r.stages_from.c_str());
  if (!r.ignored.empty()) {
    std::printf("  ignored (not a stage name):");
    for (const std::string& f : r.ignored) std::printf(" %s", f.c_str());
    std::printf("\n");
  }
  if (r.parity.isolated.empty()) return;
  std::printf("  %-10s %-13s %-10s %-8s %-10s %s\n", "stage", "isolated", "err/bound", "end2end",
              "err/bound", "file");
  for (std::size_t i = 0; i < r.parity.isolated.size(); ++i) {
    const auto& s = r.parity.isolated[i];
    const auto& e = r.parity.end_to_end[i];
    std::string status = i < r.outcomes.size() ? r.outcomes[i].status : parity::to_string(s.verdict);
    status = status == "expected-fail" ? "XFAIL (known)" : status == "fixed" ? "FIXED (known)" : status;
    for (char& ch : status)
      if (ch >= 'a' && ch <= 'z') ch = static_cast<char>(ch - 'a' + 'A');
    const auto f = r.file_of.find(s.stage);
    std::printf("  %-10s %-13s %-10.3g %-8s %-10.3g %s\n", s.stage.c_str(), status.c_str(),
                s.max_ratio, parity::to_string(e.verdict).c_str(), e.max_ratio,
                f == r.file_of.end() ? "" : fs::path(f->second).filename().c_str());
    if (s.verdict != parity::Verdict::pass) {
      std::printf("             %s\n", s.reason.c_str());
      const std::string cause = cause_line(s);
      if (!cause.empty()) std::printf("             %s\n", cause.c_str());
    }
  }
  std::printf("  verdict %s; first divergent stage: %s\n", r.verdict.c_str(),
              r.parity.first_divergent_stage ? r.parity.first_divergent_stage->c_str() : "none");
}

int check_cmd(CheckArgs& a) {
  // Stage-sized buffers are allocated and freed stage after stage. glibc's dynamic mmap
  // threshold rises to the largest block freed (up to 32 MiB), after which images just below
  // it (1920x1080 RGBA float: 31.6 MiB) come from the heap and stay there, fragmented: measured
  // here, 2.6 GB resident for 0.8 GB allocated at once. Mapping every block from 1 MiB gives
  // each back when freed.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  if (a.artifacts != "fail" && a.artifacts != "all" && a.artifacts != "none")
    throw ParamError("--artifacts '" + a.artifacts + "' is not one of: fail, all, none");
  if (int(!a.stages_dir.empty()) + int(!a.manifest.empty()) + int(a.shaders.any()) != 1)
    throw ParamError("give one of --stages DIR, --manifest FILE or --shaders learnopengl");
  if (!a.manifest.empty() && !a.scene.empty())
    throw ParamError("with --manifest the scenes are the manifest's items; give no SCENE");
  const bool profile_file = a.profile.size() > 5 && a.profile.substr(a.profile.size() - 5) == ".json";
  parity::DeviceProfile profile =
      profile_file ? read_profile_file(a.profile) : parity::profile_named(a.profile);

  std::unique_ptr<ScratchDir> scratch;  // --shaders: the passes the user's shaders drew
  CheckRun run;
  run.warn_as_error = a.warn_as_error;
  run.device = a.device;
  run.profile = profile;
  run.report_dir = a.report_dir;
  std::vector<CheckItem> items;
  if (!a.manifest.empty()) {
    const Manifest m = read_manifest(a.manifest, *a.sub, a.pipeline);
    items = m.items;
    if (!run.device.any()) run.device = m.device;
    else {
      // Keys given on the command line win, one by one.
      DeviceKeys d = m.device;
      if (!a.device.api.empty()) d.api = a.device.api;
      if (!a.device.vendor.empty()) d.vendor = a.device.vendor;
      if (!a.device.renderer.empty()) d.renderer = a.device.renderer;
      if (!a.device.driver.empty()) d.driver = a.device.driver;
      run.device = d;
    }
  } else if (a.shaders.any()) {
    // The user's shaders run first (refusals: exit 2, no GL: exit 3); what they drew is then
    // checked as captured stages.
    if (!a.report_dir.empty()) require_writable_dir(a.report_dir, "--report");
    for (const std::string* p : {&a.json_path, &a.junit_path, &a.markdown_path})
      if (!p->empty()) require_writable_file(*p, "output");
    scratch = std::make_unique<ScratchDir>();
    bool software = false;
    const std::string gl =
        run_user_shaders(a.shaders, a.scene, a.pipeline, scratch->path(), software);
    // Without --profile, the device's own: llvmpipe's measured facts, or NVIDIA-like hardware.
    if (a.sub->count("--profile") == 0) {
      profile = software ? parity::profile_llvmpipe() : parity::profile_nvidia_like();
      run.profile = profile;
    }
    if (run.device.renderer.empty()) run.device.renderer = gl;
    if (run.device.api.empty()) run.device.api = "OpenGL (headless EGL)";
    CheckItem item;
    item.scene = a.scene;
    item.stages_dir = scratch->path().string();
    item.id = "learnopengl";
    items.push_back(item);
  } else {
    CheckItem item;
    item.scene = a.scene;
    item.stages_dir = a.stages_dir;
    item.id = fs::path(a.stages_dir).lexically_normal().filename().string();
    if (item.id.empty() || item.id == ".") item.id = "stages";
    item.defaults.encoding = parse_encoding(a.encoding);
    item.defaults.origin = parse_origin(a.origin);
    item.defaults.channels = parse_channel_order(a.channels);
    item.defaults.format = parse_raw_format(a.raw_format);
    items.push_back(item);
  }
  run.params = a.pipeline.params;
  std::vector<Expectation> expectations;
  if (!a.expectations.empty()) {
    expectations = read_expectations(a.expectations);
    run.expectations_file = a.expectations;
  }

  // Every destination is checked before any work, and none may be an input.
  std::vector<std::string> inputs;
  for (const CheckItem& it : items) {
    if (!it.scene.empty()) inputs.push_back(it.scene);
    for (const StageFile& f : it.files) inputs.push_back(f.path);
  }
  for (const CheckItem& it : items)  // a folder's files are inputs too, whatever their names
    if (!it.stages_dir.empty()) {
      std::error_code ec;
      for (const auto& e : fs::directory_iterator(it.stages_dir, ec))
        inputs.push_back(e.path().string());
    }
  if (!a.manifest.empty()) inputs.push_back(a.manifest);
  if (!a.expectations.empty()) inputs.push_back(a.expectations);
  if (profile_file) inputs.push_back(a.profile);
  const std::pair<const std::string*, const char*> outs[] = {
      {&a.json_path, "--json"}, {&a.junit_path, "--junit"}, {&a.markdown_path, "--markdown"}};
  std::set<fs::path> seen;
  for (const auto& [path, option] : outs) {
    if (path->empty()) continue;
    require_writable_file(*path, option);
    for (const std::string& in : inputs) refuse_overwrite(*path, in);
    std::error_code ec;
    if (!seen.insert(fs::weakly_canonical(*path, ec)).second)
      throw InputError(*path, "is named twice as an output");
  }
  if (!a.report_dir.empty()) require_writable_dir(a.report_dir, "--report");

  for (const CheckItem& item : items) {
    ItemResult r = check_item(item, a, profile, !a.no_causes);
    apply_expectations(r, expectations, run.device);
    run.items.push_back(std::move(r));
  }
  finish_run(run);
  for (const Expectation& e : expectations)
    if (!e.used && !a.quiet)
      std::printf("note: expectation (item %s, stage %s) matched no stage\n", e.item.c_str(),
                  e.stage.c_str());

  if (!a.quiet) {
    for (const ItemResult& r : run.items) print_item(r, profile);
    if (run.verdict == "NOTHING")
      std::printf("nothing compared: no stage image found (names as --dump-stages writes them: "
                  "bright.exr, blur.1.exr ... output.exr)\n");
    else if (run.items.size() > 1)
      std::printf("%zu items: verdict %s\n", run.items.size(), run.verdict.c_str());
  }
  if (run.verdict == "NOTHING")
    std::fprintf(stderr, "bloomref: nothing compared: no stage image matched in %s\n",
                 a.manifest.empty() ? a.stages_dir.c_str() : a.manifest.c_str());
  if (!a.json_path.empty()) save_text(a.json_path, check_json(run).dump(2) + "\n");
  if (!a.junit_path.empty()) save_text(a.junit_path, junit_xml(run));
  if (!a.markdown_path.empty()) save_text(a.markdown_path, markdown_summary(run));
  return run.exit_code;
}

}  // namespace

std::function<int()> add_check(CLI::App& app) {
  auto args = std::make_shared<CheckArgs>();
  CLI::App* sub = app.add_subcommand(
      "check", "judge anyone's bloom, captured as stage images, against the CPU oracle");
  args->sub = sub;
  sub->add_option("SCENE", args->scene, "the scene the stages were rendered from; none = --scene");
  sub->add_option("--stages", args->stages_dir,
                  "folder of stage images named as --dump-stages names them (any subset)");
  sub->add_option("--manifest", args->manifest, "JSON manifest of items (docs/check.md)");
  sub->add_option("--shaders", args->shaders.preset,
                  "run your own GLSL headless the way a preset's host code does: learnopengl");
  sub->add_option("--blur-fs", args->shaders.blur_fs, "--shaders: the blur fragment shader");
  sub->add_option("--final-fs", args->shaders.final_fs, "--shaders: the final (composite) fragment shader");
  sub->add_option("--blur-vs", args->shaders.blur_vs, "--shaders: the blur vertex shader (default: a pass-through quad)");
  sub->add_option("--final-vs", args->shaders.final_vs, "--shaders: the final vertex shader");
  sub->add_option("--bright-fs", args->shaders.bright_fs,
                  "--shaders: your bright-pass fragment shader (default: the oracle's bright image)");
  sub->add_option("--target-format", args->shaders.target_format,
                  "--shaders: render targets RGBA16F | RGB16F | RGBA32F (default: from --storage)");
  sub->add_option("--filter", args->shaders.filter, "--shaders: texture filter linear | nearest");
  sub->add_option("--wrap", args->shaders.wrap,
                  "--shaders: texture wrap clamp-to-edge | repeat | mirrored-repeat");
  sub->add_option("--profile", args->profile,
                  "device precision profile: " + parity::profile_names() +
                      ", or a profile file NAME.json (docs/check.md)")
      ->capture_default_str();
  sub->add_option("--json", args->json_path, "write the results as JSON (version 1)");
  sub->add_option("--junit", args->junit_path, "write JUnit XML (a testsuite per item)");
  sub->add_option("--markdown", args->markdown_path, "write a short Markdown summary (CI job summary)");
  sub->add_option("--report", args->report_dir, "write the HTML report (images, worst values) to DIR");
  sub->add_option("--artifacts", args->artifacts,
                  "with --report: images of the failing stages (fail), of every stage (all), or none")
      ->capture_default_str();
  sub->add_option("--expectations", args->expectations,
                  "JSON file of known deviations (docs/check.md)");
  sub->add_option("--encoding", args->encoding,
                  "--stages files: auto | exr | png-linear | png-srgb | raw")
      ->capture_default_str();
  sub->add_option("--origin", args->origin, "--stages files: top | bottom (row order)")
      ->capture_default_str();
  sub->add_option("--channels", args->channels, "--stages files: RGBA | BGRA | RGB")
      ->capture_default_str();
  sub->add_option("--raw-format", args->raw_format, "--stages raw files: f32 | f16")
      ->capture_default_str();
  sub->add_option("--device-api", args->device.api, "recorded: e.g. OpenGL 4.6, Vulkan 1.3");
  sub->add_option("--device-vendor", args->device.vendor, "recorded: e.g. NVIDIA");
  sub->add_option("--device-renderer", args->device.renderer, "recorded: e.g. RTX 4090");
  sub->add_option("--device-driver", args->device.driver, "recorded: e.g. 550.54");
  sub->add_flag("--warn-as-error", args->warn_as_error, "a WARN stage fails the check (exit 1)");
  sub->add_flag("--no-causes", args->no_causes, "do not test the usual causes of a failure");
  sub->add_flag("-q,--quiet", args->quiet, "print nothing");
  args->pipeline.add_to(*sub);
  return [args, sub]() -> int {
    if (!sub->parsed()) return -1;
    args->pipeline.finish();
    return check_cmd(*args);
  };
}

}  // namespace bloomref::cli
