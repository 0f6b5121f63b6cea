// bloomref check's input files: the manifest (docs/schemas/check-manifest.v1.json) and the
// expectations (known deviations), and the verdict once expectations are applied.
#pragma once

#include <set>
#include <string>
#include <vector>

#include "check/types.h"
#include "options.h"

namespace bloomref::cli {

/// What is wrong with `id` as an item's id, or "" when nothing is: an id names the item's report
/// folder (REPORT/<id>), so it is not empty, at most 200 bytes, holds no '/', '\\' or control
/// character (NUL included) and does not start with '.'.
std::string item_id_problem(const std::string& id);

/// The id of an item read from the folder `dir`: the folder's own name (`..` and `.` resolved
/// to the folder they name), with what item_id_problem refuses replaced by '_'.
std::string folder_item_id(const std::string& dir);

struct Manifest {
  DeviceKeys device;
  std::vector<CheckItem> items;
};

/// Reads a manifest: its "params" are applied to `pipeline` except the options in `given`
/// ("--name", those the caller set), which win. InputError naming the file and the field for anything
/// malformed: a missing path, an unknown stage name, a bad encoding.
Manifest read_manifest(const std::string& path, const std::set<std::string>& given,
                       PipelineOptions& pipeline);

/// Reads an expectations file: {"version": 1, "expectations": [{"item", "stage", "device",
/// "reason"}]}. InputError naming the file and the field.
std::vector<Expectation> read_expectations(const std::string& path);

/// Reads a profile file (docs/check.md, "Profiles"): {"version": 1, "base": NAME, "name",
/// device fields, "gates", "stages": [{"pattern", "scale", "absolute", "gates"}]}. InputError
/// naming the file and the field.
parity::DeviceProfile read_profile_file(const std::string& path);

/// Fills r.outcomes and r.verdict: each isolated stage's status after the expectations that
/// match it (item and stage as shell patterns, device as a substring of any device key).
void apply_expectations(ItemResult& r, std::vector<Expectation>& expectations,
                        const DeviceKeys& device);

/// The run's verdict and exit code: ERROR (2) when an item could not be read (a frame's scene or
/// stage folder missing); FAIL (1) when a stage fails (or warns, with warn_as_error) without an
/// expectation; NOTHING (5) when no item compared a stage; else WARN or PASS (0).
void finish_run(CheckRun& run);

}  // namespace bloomref::cli
