// bloomref check: what one run judges and what it found, shared by the command, the manifest
// reader and the writers of its results (console, JSON, JUnit, Markdown).
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "bloomref/params.h"
#include "bloomref/parity/compare.h"
#include "check/stage_images.h"

namespace bloomref::cli {

/// What the results say ran the images (recorded, never used to judge).
struct DeviceKeys {
  std::string api, vendor, renderer, driver;
  bool any() const { return !(api.empty() && vendor.empty() && renderer.empty() && driver.empty()); }
};

/// One scene and its captured stages.
struct CheckItem {
  std::string id;
  std::string scene;       ///< image path; empty: the built-in --scene
  std::string stages_dir;  ///< a folder of <stage>.<ext> files, or
  std::string from;        ///< what the results call the stages' origin (default: stages_dir)
  std::vector<StageFile> files;  ///< the files one by one (a manifest's stage map)
  StageFile defaults;      ///< encoding, origin, channels for a folder's files
  std::map<std::string, std::string> aliases;  ///< a folder's file names -> stage names
  bool scratch = false;  ///< the files are bloomref's, in a temporary folder (--shaders)
  /// In memory (the Python module): the scene itself, `scene` the caller's name for it.
  const ConstImageView* scene_image = nullptr;
};

/// A known deviation (--expectations): stages matching `stage` in items matching `item`
/// (shell patterns), on devices whose key contains `device` (empty: any), are expected to fail.
struct Expectation {
  std::string item = "*", stage = "*", device, reason;
  bool used = false;
};

/// The outcome of one stage after expectations: pass, warn, fail, expected-fail (failed as a
/// known deviation says), fixed (a known deviation that now passes: reported, not a failure).
struct StageOutcome {
  std::string status;
  std::optional<Expectation> expectation;  ///< a copy: the result outlives the list it came from
};

struct ItemResult {
  std::string id, source, stages_from;
  int width = 0, height = 0;
  std::map<std::string, std::string> file_of;  ///< stage -> the file it came from
  std::vector<std::string> ignored;            ///< files of the folder that are no stage
  parity::ParityResult parity;
  std::vector<StageOutcome> outcomes;          ///< per isolated stage, after expectations
  std::string verdict;                         ///< PASS, WARN, FAIL (after expectations), NOTHING,
                                               ///< or ERROR: the item could not be judged
  std::string error;                           ///< why (ERROR: a missing scene or folder)
  std::string report_error;                    ///< why --report could not be written for it
  double load_ms = 0, oracle_ms = 0, judge_ms = 0, sensitivity_ms = 0;
  /// What the verdict could have seen (a verdict that does not fail), the bloom gain it had to
  /// see, and what would strengthen it (more captures, or the device's sub-texel bits
  /// declared); weak(): it could not see that gain.
  std::optional<parity::Sensitivity> sensitivity;
  double required_gain = 0;
  std::string strengthen;
  /// The first judged stage where NaN or Inf stand against the oracle's finite values (or the
  /// other way round), and how many: where a non-finite value entered the capture.
  std::string first_nonfinite() const {
    for (const parity::StageComparison& s : parity.isolated)
      if (s.nonfinite_mismatch > 0) return s.stage;
    return "";
  }
  /// For a stage that fails in isolation but passes end to end, the failing stage before it:
  /// its capture is right, and it failed only because it was judged from that stage's wrong
  /// capture. "" otherwise.
  std::string follows_from(std::size_t i) const {
    if (i >= parity.isolated.size() || i >= parity.end_to_end.size() ||
        parity.isolated[i].verdict == parity::Verdict::pass ||
        parity.end_to_end[i].verdict != parity::Verdict::pass)
      return "";
    for (std::size_t j = i; j-- > 0;)
      if (parity.isolated[j].verdict == parity::Verdict::fail) return parity.isolated[j].stage;
    return "";
  }
  /// The first line said of stage i: what to change (action_line), or what it follows from.
  std::string first_line(std::size_t i, const std::string& action) const {
    const std::string from = follows_from(i);
    if (from.empty()) return action;
    const parity::StageComparison& s = parity.isolated[i];
    return s.stage + ": " + parity::to_string(s.verdict) + " \u2014 follows from " + from +
           ": judged from that stage's capture; end to end this stage is right";
  }
  bool weak() const {
    return sensitivity && (sensitivity->gain == 0 || sensitivity->gain > required_gain * (1 + 1e-9));
  }
};

struct CheckRun {
  BloomParams params;
  parity::DeviceProfile profile;
  DeviceKeys device;
  bool warn_as_error = false;
  std::vector<ItemResult> items;
  std::string verdict;  ///< PASS, WARN, FAIL, NOTHING (nothing compared), ERROR (an item unread)
  int exit_code = 0;
  /// Frames, manifests and shards: the whole item list, the shard and its state
  /// (ItemSelection::json); null for one item.
  nlohmann::ordered_json batch;
  std::optional<std::string> expectations_file;
  std::vector<Expectation> unused_expectations;  ///< known deviations that matched no stage
  std::string report_dir;  ///< --report, where the failing stages' images are
  /// Outputs that could not be written (option, path, why); the others were written.
  struct OutputError {
    std::string option, path, why;
  };
  std::vector<OutputError> output_errors;
};

}  // namespace bloomref::cli
