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
#include <optional>
#include <set>

#include "batch/sequence.h"
#include "escape.h"
#include "bloomref/error.h"
#include "bloomref/io.h"
#include "bloomref/memory_budget.h"
#include "bloomref/output_files.h"
#include "bloomref/parity/compare.h"
#include "bloomref/pixel_memory.h"
#include "check/command.h"
#include "check/manifest.h"
#include "check/output.h"
#include "check/shaders.h"
#include "presets.h"
#include "check/types.h"
#include "commands.h"
#include "options.h"
#include "report.h"
#include "results.h"

namespace fs = std::filesystem;

namespace bloomref::cli {
namespace {

bool is_profile_file(const CheckRequest& a) {
  return a.profile.size() > 5 && a.profile.substr(a.profile.size() - 5) == ".json";
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The captures that would let a weak verdict see more: the bloom's stages before the last one
// captured that are not captured (each is then judged from the one before it, where a
// device's legitimate freedom is smallest), or, with no bloom stage captured, the last one.
std::string strengthening_captures(const Plan& plan, const std::vector<std::string>& names) {
  auto captured = [&names](const std::string& n) {
    return std::find(names.begin(), names.end(), n) != names.end();
  };
  std::vector<std::string> bloom, missing;
  for (const StageSpec& s : plan.stages)
    if (s.kind == StageKind::blur || s.kind == StageKind::down || s.kind == StageKind::up ||
        s.kind == StageKind::bloom)
      bloom.push_back(s.name);
  std::size_t last = 0;
  for (std::size_t i = 0; i < bloom.size(); ++i)
    if (captured(bloom[i])) last = i + 1;
  if (last == 0) return bloom.empty() ? "" : "the bloom stages (" + bloom.front() + " ... " + bloom.back() + ")";
  for (std::size_t i = 0; i < last; ++i)
    if (!captured(bloom[i])) missing.push_back(bloom[i]);
  if (missing.empty()) return "";
  if (missing.size() > 6) return missing.front() + " ... " + missing.back();
  std::string out;
  for (const std::string& m : missing) out += (out.empty() ? "" : ", ") + m;
  return out;
}

ItemResult check_item(const CheckItem& item, const CheckRequest& a, const parity::DeviceProfile& profile,
                      bool causes) {
  ItemResult r;
  r.id = item.id;
  const auto t0 = std::chrono::steady_clock::now();
  std::string source;
  LoadedImage scene;
  if (item.scene_image) {  // in memory: the caller's array, under the caller's name
    const ConstImageView& v = *item.scene_image;
    a.pipeline.check_memory(item.scene, v.width, v.height, false);
    scene.image = Image::uninitialised(v.width, v.height);
    for (int y = 0; y < v.height; ++y)
      std::copy(v.row(y), v.row(y) + std::size_t(v.width) * kChannels, scene.image.view().row(y));
    source = item.scene;
  } else {
    scene = a.pipeline.load_input(item.scene, source);
  }
  r.source = source;
  const Plan plan = parity::plan_for_device(a.pipeline.params, scene.image.cview(), profile, source);
  r.width = plan.facts.width;
  r.height = plan.facts.height;
  std::vector<StageFile> files = item.files;
  if (!item.stages_dir.empty()) {
    r.stages_from = item.from.empty() ? item.stages_dir : item.from;
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
  std::map<std::string, int> codes;  // each capture's 8-bit codes (-8: sRGB), for sensitivity
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
    codes[stage] = l.srgb ? -l.code_bits : l.code_bits;
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
  // What this verdict could have seen: only asked of one that does not fail (a failure's
  // evidence is the stage that failed).
  if (a.sensitivity != "none" && a.require_sensitivity > 0 &&
      r.parity.verdict != parity::Verdict::fail) {
    const auto t2 = std::chrono::steady_clock::now();
    r.sensitivity = parity::sensitivity(plan, scene.image.cview(), names, codes, profile, co,
                                        a.require_sensitivity, a.sensitivity != "gain",
                                        a.sensitivity == "stages");
    r.required_gain = a.require_sensitivity;
    r.strengthen = strengthening_captures(plan, names);
    if (!r.strengthen.empty()) r.strengthen = "capture " + r.strengthen;
    else if (profile.subtexel_bits_min > 0 && profile.subtexel_bits_min < profile.subtexel_bits)
      r.strengthen = "declare the device's sub-texel bits (a profile file's subtexel_bits_min; the "
                     "profile allows " + std::to_string(profile.subtexel_bits_min) + ")";
    r.sensitivity_ms = ms_since(t2);
  }
  const std::string report_dir = a.report_dir + (item.id.empty() ? "" : "/" + item.id);
  if (!a.report_dir.empty()) {
    // The report shows the captures of the stages it holds images of: read again.
    StageTrace trace;
    for (const parity::StageComparison& s : r.parity.isolated)
      if (!s.oracle.empty()) trace.stages.push_back({s.stage, read(s.stage).image, 0, false});
    try {  // the verdict stands, and the other outputs are written, without the report
      write_report(report_dir, source,
                   "captured stages: " + (r.stages_from.empty() ? item.id : r.stages_from), plan,
                   trace, r.parity, "none", item.scratch ? CapturedFiles{} : r.file_of);
    } catch (const Error& e) {
      r.report_error = e.what();
    }
  }
  if (item.scratch) {
    // The passes' readbacks are in a temporary folder, gone at exit: the results name the
    // report's copies (<stage>.device.exr), or no file.
    for (auto& [stage, path] : r.file_of) {
      path.clear();
      if (a.report_dir.empty()) continue;
      for (const parity::StageComparison& s : r.parity.isolated)
        if (s.stage == stage && !s.oracle.empty())
          path = report_dir + "/" + stage + ".device.exr";
    }
  }
  return r;
}

parity::DeviceProfile chosen_profile(const CheckRequest& a) {
  return is_profile_file(a) ? read_profile_file(a.profile) : parity::profile_named(a.profile);
}

// Keys given on the command line win over the manifest's, one by one.
DeviceKeys merged_device(const DeviceKeys& manifest, const DeviceKeys& cli) {
  DeviceKeys d = manifest;
  if (!cli.api.empty()) d.api = cli.api;
  if (!cli.vendor.empty()) d.vendor = cli.vendor;
  if (!cli.renderer.empty()) d.renderer = cli.renderer;
  if (!cli.driver.empty()) d.driver = cli.driver;
  return d;
}

// --shaders: the user's shaders run first (refusals: exit 2, no GL: exit 3); what they drew is
// then checked as captured stages from the scratch folder.
CheckItem shaders_item(const CheckRequest& a, CheckRun& run, ScratchDir& scratch) {
  if (!a.report_dir.empty()) require_writable_dir(a.report_dir, "--report");
  for (const std::string* p : {&a.outputs.json, &a.outputs.junit, &a.outputs.markdown})
    if (!p->empty()) require_writable_file(*p, "output");
  bool software = false;
  const std::string gl = run_user_shaders_bounded(a.shaders, a.scene, a.pipeline, scratch.path(), software);
  // Without --profile, the device's own: llvmpipe's measured facts, or NVIDIA-like hardware.
  const bool vk = a.shaders.backend == "vulkan";
  if (a.given.count("--profile") == 0)
    run.profile = !software ? parity::profile_nvidia_like()
                  : vk      ? parity::profile_lavapipe()
                            : parity::profile_llvmpipe();
  if (run.device.renderer.empty()) run.device.renderer = gl;
  if (run.device.api.empty()) run.device.api = vk ? "Vulkan (compute)" : "OpenGL (headless EGL)";
  CheckItem item;
  item.scene = a.scene;
  item.stages_dir = scratch.path().string();
  item.from = "the passes of " + a.shaders.files() +
              (a.shaders.layout.empty() ? "" : " (names: " + a.shaders.layout + ")");
  item.id = a.shaders.preset;
  item.scratch = true;
  return item;
}

// One item from a folder, or from stage images one by one (in memory or files).
CheckItem folder_item(const CheckRequest& a) {
  CheckItem item;
  item.scene = a.scene;
  item.scene_image = a.scene_image;
  item.stages_dir = a.stages_dir;
  if (a.stages) item.files = *a.stages;
  item.id = a.stages_dir.empty() ? "stages" : folder_item_id(a.stages_dir);
  item.defaults.encoding = parse_encoding(a.encoding);
  item.defaults.origin = parse_origin(a.origin);
  item.defaults.channels = parse_channel_order(a.channels);
  item.defaults.format = parse_raw_format(a.raw_format);
  return item;
}

// What one item's results hold in memory until the results are written, measured (4.7 KiB an
// item over 50,000 missing frames), with room: a list whose results would not fit --max-memory
// is refused before any work, pointing to --shard.
constexpr std::uint64_t kResultBytesPerItem = 8 << 10;
constexpr std::uint64_t kListBytesPerItem = 1 << 10;  // an item to take: names and paths

// `listed` items, `run` of them taken by this process.
void require_results_fit(const CheckRequest& a, std::size_t listed, std::size_t run) {
  const std::uint64_t budget = a.pipeline.memory_budget();
  const std::uint64_t need = std::uint64_t(listed) * kListBytesPerItem +
                             std::uint64_t(run) * kResultBytesPerItem;
  if (need > budget)
    throw ParamError(std::to_string(listed) + " items" +
                     (run != listed ? run ? " (" + std::to_string(run) + " taken here)" : " (the list alone)" : "") +
                     ": their results need about " + byte_size_text(need) +
                     ", over the memory limit (" + byte_size_text(budget) +
                     ", --max-memory): split the list with --shard K/N");
}

// SCENE 'scene.####.exr' --stages 'stages.####/': an item per frame, named by its number.
std::vector<CheckItem> sequence_items(const CheckRequest& a) {
  const batch::FramePattern scene = batch::FramePattern::parse(a.scene);
  const batch::FramePattern stages = batch::FramePattern::parse(a.stages_dir);
  if (!a.scene.empty() && !scene.has_wildcard())
    throw ParamError("SCENE '" + a.scene + "' names one file for every frame: give a pattern such "
                     "as scene.####.exr");
  if (!stages.has_wildcard())
    throw ParamError("--stages '" + a.stages_dir + "' names one folder for every frame: give a "
                     "pattern such as stages.####/");
  const batch::FramePattern& first = scene.has_wildcard() ? scene : stages;
  std::vector<CheckItem> items;
  const std::vector<int> frames =
      sequence_frames(a.sequence, first, scene.has_wildcard() ? "SCENE" : "--stages");
  // Before the list is made: with --shard, only a part is taken (checked again once known).
  require_results_fit(a, frames.size(), a.sequence.shard.empty() ? frames.size() : 0);
  for (int f : frames) {
    CheckItem item = folder_item(a);
    item.scene = scene.name(f);
    item.stages_dir = stages.name(f);
    item.id = first.frame_text(f);
    items.push_back(std::move(item));
  }
  return items;
}

// Frames, manifests and shards: the items this process takes (in their own order), and the
// whole list's ids, sorted, for the results.
ItemSelection select_check_items(const CheckRequest& a, std::vector<CheckItem>& items) {
  std::vector<std::string> ids;
  for (const CheckItem& it : items) ids.push_back(it.id);
  if (!a.manifest.empty()) std::sort(ids.begin(), ids.end());  // frames are sorted already
  ItemSelection sel = select_items(ids, a.sequence);
  std::set<std::string> mine;
  for (std::size_t i : sel.mine) mine.insert(sel.ids[i]);
  std::vector<CheckItem> kept;
  for (CheckItem& it : items)
    if (mine.count(it.id)) kept.push_back(std::move(it));
  items = std::move(kept);
  if (a.print_results && sel.shard)
    std::printf("shard %s (%s): %zu of %zu items\n", sel.shard->label().c_str(),
                sel.shard->source.c_str(), sel.mine.size(), sel.ids.size());
  return sel;
}

// Every item of a batch, one after another: an item that cannot be read (a missing frame) is
// recorded as an ERROR and the others go on. Returns the batch's exit code (batch_exit_code).
int check_batch(const CheckRequest& a, const std::vector<CheckItem>& items, CheckRun& run,
                std::vector<Expectation>& expectations, bool& interrupted) {
  std::vector<ItemResult> results(items.size());
  std::vector<std::string> labels;
  for (const CheckItem& it : items) labels.push_back(it.id);
  BatchLoop loop;
  loop.threads = a.pipeline.params.threads;
  loop.progress = a.sequence.progress;
  loop.quiet = !a.print_results;
  loop.noun = a.manifest.empty() && !a.stages_dir.empty() && batch::has_frame_wildcard(a.stages_dir) ? "frames" : "items";
  loop.fn = [&](std::size_t i, int) {
    ItemResult r = check_item(items[i], a, run.profile, a.causes);
    apply_expectations(r, expectations, run.device);
    ItemOutcome o;
    o.status = ItemOutcome::Status::done;
    o.message = r.verdict;
    results[i] = std::move(r);
    return o;
  };
  const std::vector<ItemOutcome> outcomes = loop.run(labels, interrupted);
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (outcomes[i].status == ItemOutcome::Status::not_run) continue;  // merge reports it missing
    if (outcomes[i].status == ItemOutcome::Status::error) {
      results[i] = ItemResult{};
      results[i].id = items[i].id;
      results[i].source = items[i].scene.empty() ? "scene:" + a.pipeline.scene : items[i].scene;
      results[i].stages_from = items[i].stages_dir;
      results[i].verdict = "ERROR";
      results[i].error = outcomes[i].message;
    }
    run.items.push_back(std::move(results[i]));
  }
  return batch_exit_code(outcomes, interrupted);
}

// Every destination is checked before any work, and none may be an input.
void require_destinations(const CheckRequest& a, const std::vector<CheckItem>& items) {
  std::vector<std::string> inputs;
  for (const CheckItem& it : items) {
    if (!it.scene.empty()) inputs.push_back(it.scene);
    for (const StageFile& f : it.files) inputs.push_back(f.path);
    if (it.stages_dir.empty()) continue;
    std::error_code ec;  // a folder's files are inputs too, whatever their names
    for (const auto& e : fs::directory_iterator(it.stages_dir, ec)) inputs.push_back(e.path().string());
  }
  for (const std::string* in : {&a.manifest, &a.expectations})
    if (!in->empty()) inputs.push_back(*in);
  if (is_profile_file(a)) inputs.push_back(a.profile);
  const std::pair<const std::string*, const char*> outs[] = {
      {&a.outputs.json, "--json"}, {&a.outputs.junit, "--junit"}, {&a.outputs.markdown, "--markdown"}};
  std::set<fs::path> seen;
  for (const auto& [path, option] : outs) {
    if (path->empty()) continue;
    require_writable_file(*path, option);
    for (const std::string& in : inputs) refuse_overwrite(*path, in);
    std::error_code ec;
    if (!seen.insert(fs::weakly_canonical(*path, ec)).second)
      throw InputError(*path, "is named twice as an output");
  }
  if (a.report_dir.empty()) return;
  require_writable_dir(a.report_dir, "--report");
  // A report replaces files of its names in REPORT/<id>: none of them may be an input.
  for (const CheckItem& it : items) {
    if (it.scratch) continue;
    std::error_code ec;
    const fs::path folder = fs::weakly_canonical(fs::path(a.report_dir) / it.id, ec);
    std::vector<std::string> mine = {it.scene};
    for (const StageFile& f : it.files) mine.push_back(f.path);
    if (!it.stages_dir.empty())
      for (const auto& e : fs::directory_iterator(it.stages_dir, ec)) mine.push_back(e.path().string());
    for (const std::string& in : mine) {
      if (in.empty()) continue;
      const fs::path p = fs::weakly_canonical(in, ec);
      if (!ec && p.parent_path() == folder && report_may_write(p.filename().string()))
        throw InputError(in, "would be replaced by the report written to " +
                                 (fs::path(a.report_dir) / it.id).string() +
                                 ": give --report another folder");
    }
  }
}

// Each output is written or fails on its own: a report that could not be written leaves the
// JSON, JUnit and Markdown to be written, and the other way round. Any failure: exit 6, each
// named on stderr (and in the JSON's "output_errors", for those before it).
void write_outputs(const CheckRequest& a, CheckRun& run) {
  for (const ItemResult& r : run.items)
    if (!r.report_error.empty())
      run.output_errors.push_back({"--report", a.report_dir, r.id + ": " + r.report_error});
  const bool any_before = !run.output_errors.empty();
  if (any_before) run.exit_code = 6;
  auto attempt = [&run](const char* option, const std::string& path, auto write) {
    if (path.empty()) return;
    try {
      write();
    } catch (const std::exception& e) {
      run.output_errors.push_back({option, path, e.what()});
      run.exit_code = 6;
    }
  };
  const CheckOutputs& o = a.outputs;
  attempt("--json", o.json, [&] { save_text(o.json, escape::json_text(check_json(run)) + "\n"); });
  // JUnit and Markdown say what the JSON says: written from it, as merge writes them, the
  // document made once and only when one of them is asked for.
  std::optional<nlohmann::ordered_json> doc;
  auto document = [&]() -> const nlohmann::ordered_json& {
    if (!doc) doc = check_json(run);
    return *doc;
  };
  attempt("--junit", o.junit, [&] { save_text(o.junit, results::junit(document())); });
  attempt("--markdown", o.markdown, [&] { save_text(o.markdown, results::markdown(document())); });
  if (a.print_notes)
    for (const CheckRun::OutputError& e : run.output_errors)
      std::fprintf(stderr, "bloomref: %s %s was not written: %s\n", e.option.c_str(),
                   e.path.c_str(), e.why.c_str());
}

}  // namespace

CheckRun check(CheckRequest a) {
  // --max-memory bounds check by the images it holds: measured at 1920x1080 with every stage
  // captured, about twelve stage-sized images at once (the oracle's, the capture's, bounds and
  // deviations); the model of a run keeping every stage (sixteen) is above it.
  a.pipeline.kept_traces = 1;
  a.pipeline.gl = a.shaders.any();
  // A manifest's params may give the mode an option on the command line needs: its reading
  // refuses what is still ignored then.
  a.pipeline.finish(a.manifest.empty());
  // Stage-sized buffers are allocated and freed stage after stage. glibc's dynamic mmap
  // threshold rises to the largest block freed (up to 32 MiB), after which images just below
  // it (1920x1080 RGBA float: 31.6 MiB) come from the heap and stay there, fragmented: measured
  // here, 2.6 GB resident for 0.8 GB allocated at once. Mapping every block from 1 MiB gives
  // each back when freed.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  // Image buffers, each written whole, are kept when freed for the next image of their size,
  // and faulted in at once when new (docs/design.md, "check keeps its images' memory"); a
  // quarter of the memory limit at most.
  const PixelPolicyScope pixels(
      {std::min<std::size_t>(PixelPolicy::kMostKept, a.pipeline.memory_budget() / 4), true});
  if (a.artifacts != "fail" && a.artifacts != "all" && a.artifacts != "none")
    throw ParamError("--artifacts '" + a.artifacts + "' is not one of: fail, all, none");
  const bool listed = !a.stages_dir.empty() || a.stages;
  if (int(listed) + int(!a.manifest.empty()) + int(a.shaders.any()) != 1 ||
      (!a.stages_dir.empty() && a.stages))
    throw ParamError(a.stages
                         ? "stages are given one by one: no --stages, --manifest or --shaders"
                         : "give one of --stages DIR, --manifest FILE or --shaders PRESET");
  if (a.scene_image && !listed)
    throw ParamError("a scene in memory is judged with its stages (a folder, or images one by "
                     "one): not with --manifest or --shaders");
  if (a.shaders.backend != "gl" && a.shaders.preset != "pipeline")
    throw ParamError("--backend vulkan runs the passes of a pipeline description: it needs "
                     "--shaders pipeline --pipeline FILE");
  if (!a.shaders.layout.empty() && !a.shaders.any())
    throw ParamError("--layout names what --shaders learnopengl binds: give --shaders too");
  if (!a.manifest.empty() && !a.scene.empty())
    throw ParamError("with --manifest the scenes are the manifest's items; give no SCENE");
  const bool frames = !a.scene_image && !a.stages &&
                     (batch::has_frame_wildcard(a.scene) || batch::has_frame_wildcard(a.stages_dir) ||
                      !a.sequence.frames.empty());
  if (frames && a.stages_dir.empty())
    throw ParamError("a frame sequence is checked from stage folders: give --stages "
                     "'stages.####/' (a manifest lists its items itself)");

  CheckRun run;
  run.warn_as_error = a.warn_as_error;
  run.device = a.device;
  run.profile = chosen_profile(a);
  run.report_dir = a.report_dir;
  std::unique_ptr<ScratchDir> scratch;  // --shaders: the passes the user's shaders drew
  std::vector<CheckItem> items;
  if (!a.manifest.empty()) {
    const Manifest m = read_manifest(a.manifest, a.given, a.pipeline);
    items = m.items;
    run.device = a.device.any() ? merged_device(m.device, a.device) : m.device;
  } else if (a.shaders.any()) {
    scratch = std::make_unique<ScratchDir>();
    items.push_back(shaders_item(a, run, *scratch));
  } else if (frames) {
    items = sequence_items(a);
  } else {
    items.push_back(folder_item(a));
  }
  const bool batch = frames || !a.manifest.empty() || !a.sequence.shard.empty();
  ItemSelection selection;
  if (batch) {
    selection = select_check_items(a, items);
    require_results_fit(a, selection.ids.size(), items.size());
  }
  run.params = a.pipeline.params;
  std::vector<Expectation> expectations;
  if (!a.expectations.empty()) {
    expectations = read_expectations(a.expectations);
    run.expectations_file = a.expectations;
  }
  require_destinations(a, items);

  int batch_code = 0;
  bool interrupted = false;
  if (!batch) {
    for (const CheckItem& item : items) {
      ItemResult r = check_item(item, a, run.profile, a.causes);
      apply_expectations(r, expectations, run.device);
      run.items.push_back(std::move(r));
    }
  } else if (!items.empty()) {
    batch_code = check_batch(a, items, run, expectations, interrupted);
  }
  if (batch) run.batch = selection.json(!interrupted, interrupted);
  finish_run(run);
  if (batch_code == 130 || batch_code == 4) run.exit_code = batch_code;  // over the verdict's
  for (const Expectation& e : expectations)
    if (!e.used) run.unused_expectations.push_back(e);
  if (a.print_results) std::fputs(results::console(check_json(run)).c_str(), stdout);
  if (!a.print_notes) {
  } else if (batch && selection.shard && selection.mine.empty())
    std::fprintf(stderr, "bloomref: shard %s has no item (%zu items in %d shards): nothing to do\n",
                 selection.shard->label().c_str(), selection.ids.size(), selection.shard->count);
  else if (run.verdict == "NOTHING")
    std::fprintf(stderr, "bloomref: nothing compared: no stage image matched in %s\n",
                 !a.manifest.empty()   ? a.manifest.c_str()
                 : a.stages_dir.empty() ? "the stages given"
                                        : a.stages_dir.c_str());
  write_outputs(a, run);
  return run;
}

namespace {


// A check's command line: the request it fills, and what only the command line says.
struct CheckCommandLine {
  CheckRequest request;
  bool quiet = false, no_causes = false;
  CLI::App* sub = nullptr;

  /// The request once parsed: the options given, and what the flags say.
  CheckRequest finished() const {
    CheckRequest r = request;
    for (const CLI::Option* o : sub->get_options())
      if (o->count() > 0)
        for (const std::string& name : o->get_lnames()) r.given.insert("--" + name);
    r.causes = !no_causes;
    r.print_results = !quiet;
    r.print_notes = true;
    return r;
  }
};

// The subcommand and its options, bound to `args` (the command line's and
// parse_check_request's).
void add_check_options(CLI::App& app, const std::shared_ptr<CheckCommandLine>& args) {
  CLI::App* sub = app.add_subcommand(
      "check", "judge anyone's bloom, captured as stage images, against the CPU oracle");
  args->sub = sub;
  sub->add_option("SCENE", args->request.scene, "the scene the stages were rendered from; none = --scene");
  sub->add_option("--stages", args->request.stages_dir,
                  "folder of stage images named as --dump-stages names them (any subset)");
  sub->add_option("--manifest", args->request.manifest, "JSON manifest of items (docs/check.md)");
  sub->add_option_function<std::string>(
      "--shaders",
      [args](const std::string& preset) {
        args->request.shaders.preset = preset;
        // The preset's pipeline is what the shaders are judged against: its parameters, under
        // any option given beside it (learnopengl keeps bloomref's defaults).
        if (preset == "learnopengl-pbb" && args->request.pipeline.preset.empty()) {
          try {
            apply_preset(preset, args->request.pipeline, [args](const std::string& key) {
              return args->sub->count("--" + key) > 0;
            });
          } catch (const Error& e) {
            throw CLI::ValidationError("--shaders", e.what());
          }
        }
      },
      "run your own GLSL headless the way a preset's host code does: learnopengl | "
      "learnopengl-pbb | pipeline (any host code, described in a --pipeline file)");
  sub->add_option("--pipeline", args->request.shaders.pipeline,
                  "--shaders pipeline: the JSON description of your host code: textures, "
                  "programs, passes (docs/check.md)");
  sub->add_option("--backend", args->request.shaders.backend,
                  "--shaders pipeline: run the passes as GL fragment passes (gl) or as Vulkan "
                  "compute shaders (vulkan)")
      ->check(CLI::IsMember({"gl", "vulkan"}))
      ->capture_default_str();
  sub->add_option("--downsample-fs", args->request.shaders.downsample_fs,
                  "--shaders learnopengl-pbb: the downsample fragment shader");
  sub->add_option("--upsample-fs", args->request.shaders.upsample_fs,
                  "--shaders learnopengl-pbb: the upsample fragment shader");
  sub->add_option("--downsample-vs", args->request.shaders.downsample_vs,
                  "--shaders learnopengl-pbb: the downsample vertex shader (default: a pass-through quad)");
  sub->add_option("--upsample-vs", args->request.shaders.upsample_vs,
                  "--shaders learnopengl-pbb: the upsample vertex shader");
  sub->add_option("--blur-fs", args->request.shaders.blur_fs, "--shaders: the blur fragment shader");
  sub->add_option("--final-fs", args->request.shaders.final_fs, "--shaders: the final (composite) fragment shader");
  sub->add_option("--blur-vs", args->request.shaders.blur_vs, "--shaders: the blur vertex shader (default: a pass-through quad)");
  sub->add_option("--final-vs", args->request.shaders.final_vs, "--shaders: the final vertex shader");
  sub->add_option("--bright-fs", args->request.shaders.bright_fs,
                  "--shaders: your bright-pass fragment shader (default: the oracle's bright image)");
  sub->add_option("--target-format", args->request.shaders.target_format,
                  "--shaders: render targets RGBA16F | RGB16F | RGBA32F | R11F_G11F_B10F | RGBA8 (default: from --storage)");
  sub->add_option("--filter", args->request.shaders.filter, "--shaders: texture filter linear | nearest");
  sub->add_option("--wrap", args->request.shaders.wrap,
                  "--shaders: texture wrap clamp-to-edge | repeat | mirrored-repeat | clamp-to-border");
  sub->add_option("--layout", args->request.shaders.layout,
                  "--shaders: JSON file of the names your shaders use for the preset's samplers, "
                  "uniforms and attributes (docs/check.md)");
  sub->add_option("--final-target", args->request.shaders.final_target,
                  "--shaders: the final pass draws into a target like the others (same) or an "
                  "8-bit one like the tutorial's window (rgba8)")
      ->capture_default_str();
  sub->add_option("--shader-timeout", args->request.shaders.timeout_s,
                  "--shaders: seconds the passes may take, compiling included, before they are "
                  "stopped (exit 2; default: 120 and 20 per million texels of the scene)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--shader-memory", args->request.shaders.max_memory,
                  "--shaders: memory the passes may use, e.g. 2G (exit 2 past it; default: 1 GiB "
                  "and 24 float images of the scene, at most --max-memory)");
  sub->add_option("--profile", args->request.profile,
                  "device precision profile: " + parity::profile_names() +
                      ", or a profile file NAME.json (docs/check.md); default nvidia, and with "
                      "--shaders the device's own (llvmpipe on a software renderer)");
  sub->add_option("--json", args->request.outputs.json, "write the results as JSON (version 1)");
  sub->add_option("--junit", args->request.outputs.junit, "write JUnit XML (a testsuite per item)");
  sub->add_option("--markdown", args->request.outputs.markdown, "write a short Markdown summary (CI job summary)");
  sub->add_option("--report", args->request.report_dir, "write the HTML report (images, worst values) to DIR");
  sub->add_option("--artifacts", args->request.artifacts,
                  "with --report: images of the failing stages (fail), of every stage (all), or none")
      ->capture_default_str();
  sub->add_option("--expectations", args->request.expectations,
                  "JSON file of known deviations (docs/check.md)");
  sub->add_option("--encoding", args->request.encoding,
                  "--stages files: auto | exr | png-linear | png-srgb | raw")
      ->capture_default_str();
  sub->add_option("--origin", args->request.origin, "--stages files: top | bottom (row order)")
      ->capture_default_str();
  sub->add_option("--channels", args->request.channels, "--stages files: RGBA | BGRA | RGB")
      ->capture_default_str();
  sub->add_option("--raw-format", args->request.raw_format, "--stages raw files: f32 | f16")
      ->capture_default_str();
  sub->add_option("--device-api", args->request.device.api, "recorded: e.g. OpenGL 4.6, Vulkan 1.3");
  sub->add_option("--device-vendor", args->request.device.vendor, "recorded: e.g. NVIDIA");
  sub->add_option("--device-renderer", args->request.device.renderer, "recorded: e.g. RTX 4090");
  sub->add_option("--device-driver", args->request.device.driver, "recorded: e.g. 550.54");
  sub->add_flag("--warn-as-error", args->request.warn_as_error, "a WARN stage fails the check (exit 1)");
  sub->add_flag("--no-causes", args->no_causes, "do not test the usual causes of a failure");
  sub->add_option("--require-sensitivity", args->request.require_sensitivity,
                  "the bloom gain a verdict must be able to see; one that cannot is WARN: weak "
                  "verdict (default 1.05; 0: do not measure what the verdict could see)")
      ->check(CLI::Range(0.0, 4.0));
  sub->add_option("--sensitivity", args->request.sensitivity,
                  "what a verdict that does not fail measures it could have seen: gain (the "
                  "default), full (also a shift and a wider spread), stages (full, and each "
                  "of them entering at each captured stage: about 7 checks a stage), none")
      ->check(CLI::IsMember({"gain", "full", "stages", "none"}));
  sub->add_flag("-q,--quiet", args->quiet, "print nothing");
  args->request.pipeline.add_to(*sub);
  args->request.sequence.add_to(*sub, false);
}

}  // namespace

std::function<int()> add_check(CLI::App& app) {
  auto args = std::make_shared<CheckCommandLine>();
  add_check_options(app, args);
  return [args]() -> int {
    if (!args->sub->parsed()) return -1;
    return check(args->finished()).exit_code;
  };
}

CheckRequest parse_check_request(const std::vector<std::string>& args) {
  CLI::App app{"bloomref"};
  app.require_subcommand(1);
  auto a = std::make_shared<CheckCommandLine>();
  add_check_options(app, a);
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11's order
  reversed.push_back("check");
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw ParamError(e.what());
  }
  return a->finished();
}

}  // namespace bloomref::cli
