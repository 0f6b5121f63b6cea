// bloomref compare --report DIR: per-stage images (oracle, the device's, signed difference, error/bound
// heat map, pass/fail mask; PNG for the eye, EXR for the numbers), worst values with their bound
// terms, the causes tested on a failing stage, f16-ULP histograms, and one self-contained index.html opening on the first divergent
// stage.
#pragma once

#include <map>
#include <string>

#include "bloomref/executor.h"
#include "bloomref/parity/compare.h"

namespace bloomref::cli {

/// The best-supported cause of a stage's failure, in one line ("" when the stage passed).
std::string cause_line(const parity::StageComparison& s);

/// What a person acts on, first: "blur.1: FAIL — taps 2x as far apart on x (...), explains
/// 99.8%" ("" when the stage passed). The console, JUnit, Markdown and the report open with it.
std::string action_line(const parity::StageComparison& s);

/// The user's own files of the stages under test (stage -> path): the report links to them
/// instead of writing a copy (<stage>.device.exr) of each.
using CapturedFiles = std::map<std::string, std::string>;

/// Whether a report may write a file of this name into its folder (index.html, and each stage's
/// <stage>.oracle|device|diff|ratio.exr|png and <stage>.mask.png): an input of that name there would
/// be replaced, so the caller refuses the folder first.
bool report_may_write(const std::string& filename);

/// Builds the report in a hidden folder beside `dir` and moves it into place when complete
/// (StagedFolder): an interrupted run leaves no half-written report.
void write_report(const std::string& dir, const std::string& source, const std::string& renderer,
                  const Plan& plan, const StageTrace& gl, const parity::ParityResult& r,
                  const std::string& fault, const CapturedFiles& files = {});
/// The report's files, written into the existing folder `dir` (a staged one, beside the
/// report's final name: links to `files` are relative to its parent).
void write_report_files(const std::string& dir, const std::string& source,
                        const std::string& renderer, const Plan& plan, const StageTrace& gl,
                        const parity::ParityResult& r, const std::string& fault,
                        const CapturedFiles& files = {});

}  // namespace bloomref::cli
