// Many items in one process, for `run` (frames) and `check` (frames or manifest items): the
// options they share, the item list after --frames and --shard, and the loop that runs the
// items one after another (or --jobs at once) with progress, Ctrl-C and a results file kept up
// to date.
//
// Items run in the order of the sorted item list. A failing item is recorded and the rest go
// on; the exit code says what went wrong: 2 when an item had bad input (a missing frame), 4 for
// an internal error, 130 when SIGINT or SIGTERM stopped the run (after the items in flight, so
// no file is left half-written), 5 when the shard was given no item.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "batch/frames.h"
#include "batch/shard.h"

namespace bloomref::cli {

struct SequenceOptions {
  std::string frames;  ///< --frames, "" when not given
  std::string shard;   ///< --shard K/N | auto
  int shard_count = 0;
  bool resume = false;
  int jobs = 1;
  std::string progress = "auto";  ///< auto | bar | lines | none

  /// `for_run`: also --resume and --jobs (frames written as files); check takes the others.
  void add_to(CLI::App& app, bool for_run);
  /// Whether any of the options was given.
  bool any() const { return !frames.empty() || !shard.empty() || resume; }
};

/// The process environment as a map (for batch::resolve_shard).
batch::Environment process_environment();

/// The frames of a sequence: --frames when given, else the numbers of the files that match
/// `pattern` in its folder (sorted; ParamError when none does).
std::vector<int> sequence_frames(const SequenceOptions& o, const batch::FramePattern& pattern,
                                 const std::string& what);

/// The items this process runs: the whole sorted list's ids, the shard (resolved, printed by
/// the caller) and the positions it takes.
struct ItemSelection {
  std::vector<std::string> ids;
  std::optional<batch::Shard> shard;
  std::vector<std::size_t> mine;
  /// The "batch" object of a results file: items_total, item_ids, shard, items_in_shard, and the
  /// given state (finished: every item of the shard was tried; interrupted: stopped by a signal).
  nlohmann::ordered_json json(bool finished, bool interrupted) const;
};

/// Resolves --shard (ParamError) and selects; touches Bazel's TEST_SHARD_STATUS_FILE.
ItemSelection select_items(std::vector<std::string> ids, const SequenceOptions& o);

/// What became of one item.
struct ItemOutcome {
  enum class Status { done, resumed, error, not_run };
  Status status = Status::not_run;
  std::string message;            ///< the error, or a short note for the per-item line
  int exit_code = 0;              ///< of an error: 2 bad input, 4 internal
  double ms = 0;                  ///< wall time of the item, I/O included
  nlohmann::ordered_json record;  ///< what the command records of the item
};
const char* to_string(ItemOutcome::Status s);

/// Runs fn(i, threads) for i in [0, count): `jobs` at a time, each with `threads` worker threads
/// (the caller's pipeline threads divided among the jobs). InputError and other exceptions of
/// one item become its outcome (2, or 4); ParamError and GlUnavailable stop the run (they would
/// fail every item). Between items, stops on SIGINT/SIGTERM (the handlers are installed for the
/// call and restored after). `checkpoint(outcomes)` is called at most every 2 s after an item and
/// at the end, under the loop's lock; `labels[i]` names item i in progress lines.
struct BatchLoop {
  int jobs = 1;
  int threads = 0;
  std::string progress = "auto";
  bool quiet = false;
  std::string noun = "frames";
  std::function<ItemOutcome(std::size_t, int)> fn;
  std::function<void(const std::vector<ItemOutcome>&)> checkpoint;

  /// Returns the outcomes; `interrupted` tells whether a signal stopped the loop.
  std::vector<ItemOutcome> run(const std::vector<std::string>& labels, bool& interrupted);
};

/// The exit code of a batch: 130 interrupted, else the worst item error (4 over 2), else 0.
int batch_exit_code(const std::vector<ItemOutcome>& outcomes, bool interrupted);

/// Whether an image file is whole: a scanline EXR whose every chunk lies within the file, or a
/// PNG that ends with its IEND chunk.
bool image_complete(const std::string& path);

}  // namespace bloomref::cli
