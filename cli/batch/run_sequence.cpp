#include "batch/run_sequence.h"
#include "escape.h"

#include <ImfHeader.h>
#include <ImfInputFile.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <set>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "bloomref/parallel.h"
#include "bloomref/plan.h"
#include "json_out.h"

namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace bloomref::cli {
namespace {

using batch::FramePattern;

// The patterns of a run, checked: every destination names a file per frame.
struct Patterns {
  FramePattern input;
  std::vector<FramePattern> outputs;
  FramePattern dump;
  const FramePattern& first_wildcard() const {
    if (input.has_wildcard()) return input;
    for (const FramePattern& o : outputs)
      if (o.has_wildcard()) return o;
    return dump;
  }
  FrameFiles files(int frame, int threads) const {
    FrameFiles f;
    if (!input.text().empty()) f.input = input.name(frame);
    for (const FramePattern& o : outputs) f.outputs.push_back(o.name(frame));
    if (!dump.text().empty()) f.dump_dir = dump.name(frame);
    f.threads = threads;
    return f;
  }
};

Patterns check_patterns(const RunSequenceArgs& a) {
  Patterns p;
  p.input = FramePattern::parse(a.input);
  if (!a.input.empty() && !p.input.has_wildcard())
    throw ParamError("IN '" + a.input +
                     "' names one file for every frame: give a pattern such as "
                     "shot.####.exr (or no IN for the built-in scene)");
  if (a.input.empty() && a.sequence.frames.empty())
    throw ParamError("a sequence of the built-in scene needs --frames (e.g. --frames 1-10)");
  for (const std::string& o : a.outputs) {
    p.outputs.push_back(FramePattern::parse(o));
    if (!p.outputs.back().has_wildcard())
      throw ParamError("-o '" + o +
                       "' names one file for every frame: give a pattern such as "
                       "out.####.exr");
  }
  if (!a.dump_dir.empty()) {
    p.dump = FramePattern::parse(a.dump_dir);
    if (!p.dump.has_wildcard())
      throw ParamError("--dump-stages '" + a.dump_dir +
                       "' names one folder for every frame: give "
                       "a pattern such as stages.####/");
  }
  if (batch::has_frame_wildcard(a.json_path))
    throw ParamError("--json '" + a.json_path +
                     "': a sequence writes one results file; give a "
                     "name without a frame wildcard");
  if (a.outputs.empty() && a.dump_dir.empty() && a.json_path.empty())
    throw ParamError("nothing to write: give -o 'out.####.exr' (or --dump-stages, --json)");
  return p;
}

// Before any frame runs: no output pattern is the input's, none is named twice, and the results
// file is none of a frame's files (checked on the first frame's names).
void check_destinations(const Patterns& p, const RunSequenceArgs& a, int frame) {
  const FrameFiles f = p.files(frame, 0);
  std::vector<std::string> dest = f.outputs;
  if (!f.dump_dir.empty()) dest.push_back(f.dump_dir);
  if (!a.json_path.empty()) dest.push_back(a.json_path);
  for (const std::string& o : f.outputs) {  // a missing folder would fail every frame
    const fs::path dir = fs::path(o).parent_path();
    std::error_code ec;
    if (!dir.empty() && !fs::is_directory(dir, ec))
      throw InputError(o, "cannot be written: the folder " + dir.string() + " does not exist");
  }
  std::set<fs::path> seen;
  for (const std::string& d : dest) {
    if (!f.input.empty()) refuse_overwrite(d, f.input);
    std::error_code ec;
    if (!seen.insert(fs::weakly_canonical(d, ec)).second)
      throw InputError(d, "is named twice as an output");
  }
  if (!a.json_path.empty() && !a.input.empty() && p.input.frame_of(a.json_path))
    throw InputError(a.json_path, "is a frame of the input sequence");
}

// Whether a frame's outputs exist whole (--resume): every output file, and every stage file of
// its --dump-stages folder (the stages of its size, read from the dumped input stage's header).
bool frame_complete(const FrameFiles& f, const BloomParams& params) {
  for (const std::string& o : f.outputs)
    if (!image_complete(o)) return false;
  if (f.dump_dir.empty()) return !f.outputs.empty();
  const fs::path dir(f.dump_dir);
  const std::string input = (dir / "input.exr").string();
  if (!image_complete(input)) return false;
  int w = 0, h = 0;
  try {
    Imf::InputFile file(input.c_str(), 1);
    const Imath::Box2i dw = file.header().dataWindow();
    w = dw.max.x - dw.min.x + 1;
    h = dw.max.y - dw.min.y + 1;
  } catch (const std::exception&) {
    return false;
  }
  for (const std::string& s : stage_names(params, w, h))
    if (!image_complete((dir / (s + ".exr")).string())) return false;
  return true;
}

}  // namespace

bool is_run_sequence(const RunSequenceArgs& a) {
  if (a.sequence.any()) return true;
  if (batch::has_frame_wildcard(a.input) || batch::has_frame_wildcard(a.dump_dir)) return true;
  for (const std::string& o : a.outputs)
    if (batch::has_frame_wildcard(o)) return true;
  return false;
}

// The results document (--json) of a sequence run: an item per frame run so far (frames not
// run yet are left out: merge reports them missing), the counts and the rates.
ordered_json sequence_results(const RunSequenceArgs& a, const Patterns& p,
                              const std::vector<int>& frames, const std::vector<std::string>& ids,
                              const ItemSelection& sel, const std::vector<ItemOutcome>& outcomes,
                              bool finished, bool interrupted, int code,
                              std::chrono::steady_clock::time_point t0) {
  ordered_json items = ordered_json::array();
  std::size_t counts[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < outcomes.size(); ++i) {
    const ItemOutcome& o = outcomes[i];
    ++counts[static_cast<int>(o.status)];
    if (o.status == ItemOutcome::Status::not_run) continue;  // merge reports it missing
    const int f = frames[sel.mine[i]];
    const FrameFiles files = p.files(f, 0);
    ordered_json item = {
        {"id", ids[sel.mine[i]]},
        {"frame", f},
        {"status", to_string(o.status)},
        {"input", files.input.empty() ? ordered_json(nullptr) : ordered_json(files.input)},
        {"outputs", files.outputs},
        {"dump_stages",
         files.dump_dir.empty() ? ordered_json(nullptr) : ordered_json(files.dump_dir)},
        {"wall_ms", o.ms},
        {"error", o.status == ItemOutcome::Status::error ? ordered_json(o.message)
                                                         : ordered_json(nullptr)}};
    if (o.status == ItemOutcome::Status::error) item["exit_code"] = o.exit_code;
    for (const auto& [k, v] : o.record.items()) item[k] = v;
    items.push_back(std::move(item));
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ordered_json{
      {"version", 1},
      {"tool", "bloomref run"},
      {"kind", "sequence"},
      {"params", params_json(a.params)},
      {"input", a.input.empty() ? ordered_json(nullptr) : ordered_json(a.input)},
      {"outputs", a.outputs},
      {"dump_stages", a.dump_dir.empty() ? ordered_json(nullptr) : ordered_json(a.dump_dir)},
      {"frames", batch::format_frame_list(frames)},
      {"batch", sel.json(finished, interrupted)},
      {"exit_code", code},
      {"summary",
       {{"done", counts[0]},
        {"resumed", counts[1]},
        {"error", counts[2]},
        {"not_run", counts[3]}}},
      {"wall_ms", 1000 * wall},
      {"frames_per_second", wall > 0 ? (counts[0] + counts[2]) / wall : 0.0},
      {"items", items}};
}

// The line a sequence run ends with: frames done, resumed and failed (named), time and rate.
void print_sequence_summary(const std::vector<ItemOutcome>& outcomes,
                            const std::vector<int>& frames, const ItemSelection& sel,
                            std::chrono::steady_clock::time_point t0, bool interrupted) {
  std::size_t done = 0, resumed = 0, failed = 0;
  std::vector<int> failed_frames;
  for (std::size_t i = 0; i < outcomes.size(); ++i) {
    done += outcomes[i].status == ItemOutcome::Status::done;
    resumed += outcomes[i].status == ItemOutcome::Status::resumed;
    if (outcomes[i].status == ItemOutcome::Status::error) {
      ++failed;
      failed_frames.push_back(frames[sel.mine[i]]);
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%zu frames: %zu done, %zu resumed (outputs existed), %zu failed", outcomes.size(),
              done, resumed, failed);
  if (!failed_frames.empty())
    std::printf(" (frame%s %s)", failed_frames.size() > 1 ? "s" : "",
                batch::format_frame_list(failed_frames).c_str());
  std::printf("; %.1f s, %.2f frames/s%s\n", wall, wall > 0 ? (done + failed) / wall : 0.0,
              interrupted ? "; interrupted" : "");
}

int run_sequence(const RunSequenceArgs& a, const RunFrame& frame) {
  const Patterns p = check_patterns(a);
  const std::vector<int> frames = sequence_frames(a.sequence, p.input, "IN");
  std::vector<std::string> ids;
  for (int f : frames) ids.push_back(p.first_wildcard().frame_text(f));
  const ItemSelection sel = select_items(ids, a.sequence);
  check_destinations(p, a, frames.front());
  if (!a.json_path.empty()) {
    const fs::path dir = fs::path(a.json_path).parent_path();
    std::error_code ec;
    if (!dir.empty() && !fs::is_directory(dir, ec))
      throw InputError(a.json_path,
                       "cannot be written: the folder " + dir.string() + " does not exist");
  }
  if (!a.quiet && sel.shard)
    std::printf("shard %s (%s): %zu of %zu frames\n", sel.shard->label().c_str(),
                sel.shard->source.c_str(), sel.mine.size(), ids.size());

  const auto t0 = std::chrono::steady_clock::now();
  auto results = [&](const std::vector<ItemOutcome>& outcomes, bool finished, bool interrupted,
                     int code) {
    return sequence_results(a, p, frames, ids, sel, outcomes, finished, interrupted, code, t0);
  };
  auto save = [&](const ordered_json& j) {
    if (!a.json_path.empty()) save_text(a.json_path, escape::json_text(j) + "\n");
  };

  if (sel.mine.empty()) {
    std::fprintf(stderr,
                 "bloomref: shard %s has no frame (%zu frames in %d shards): nothing to do\n",
                 sel.shard->label().c_str(), ids.size(), sel.shard->count);
    save(results({}, true, false, 5));
    return 5;
  }

  std::vector<std::string> labels;
  for (std::size_t i : sel.mine) labels.push_back(ids[i]);
  BatchLoop loop;
  loop.jobs = a.sequence.jobs;
  loop.threads = a.params.threads;
  loop.progress = a.sequence.progress;
  loop.quiet = a.quiet;
  loop.fn = [&](std::size_t i, int threads) {
    const FrameFiles files = p.files(frames[sel.mine[i]], threads);
    ItemOutcome o;
    if (a.sequence.resume && frame_complete(files, a.params)) {
      o.status = ItemOutcome::Status::resumed;
      o.message = "outputs exist";
      return o;
    }
    frame(files, o.record);
    o.status = ItemOutcome::Status::done;
    return o;
  };
  loop.checkpoint = [&](const std::vector<ItemOutcome>& outcomes) {
    save(results(outcomes, false, false, 0));
  };
  bool interrupted = false;
  std::vector<ItemOutcome> outcomes = loop.run(labels, interrupted);
  const int code = batch_exit_code(outcomes, interrupted);
  bool finished = !interrupted;
  save(results(outcomes, finished, interrupted, code));

  if (!a.quiet) print_sequence_summary(outcomes, frames, sel, t0, interrupted);
  return code;
}

}  // namespace bloomref::cli
