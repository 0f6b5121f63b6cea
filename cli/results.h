// check's results in every form they are written: from the one JSON document of a run
// (docs/schemas/check-result.v1.json), or of sharded runs merged (batch/merge.h), to the
// console's table, JUnit XML (a testsuite per item, a testcase per stage) and a Markdown summary
// for a CI job's page. The command and `merge` write through these (the Python module returns
// the document itself); every name from a user is escaped by escape.h.
//
// A document from another version, or a merge of hand-edited files, may lack fields or hold
// them with other types: what is not there is left out, never an error.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace bloomref::results {

/// What `bloomref check` prints: per item its stages' table, what failed and why, what the
/// verdict could see, and the verdict.
std::string console(const nlohmann::ordered_json& doc);

/// JUnit XML. A merged document's missing items and items run twice are errors of their own.
std::string junit(const nlohmann::ordered_json& doc);

/// A short Markdown summary: the verdict, the counts, a row per item, what each verdict could
/// see; a merged document's problems first.
std::string markdown(const nlohmann::ordered_json& doc);

/// What an item's verdict could see (its "sensitivity"), in words: "a bloom gain of 1.05x (at
/// blur.10), a shift of 1 texel(s) (at blur.10), a spread 5% wider (at blur.10)".
std::string sensitivity_line(const nlohmann::ordered_json& sensitivity);
/// What an error entering at one stage would have shown (a stage's "sensitivity").
std::string stage_sensitivity_line(const nlohmann::ordered_json& sensitivity);
/// What a stage's isolated bound carries from stages without capture, in words: "78% of its
/// bound is what input, down.1 (not captured) may carry"; "" when it reads only captures.
std::string carried_line(const nlohmann::ordered_json& stage);
/// Why a weak verdict is weak, and what would strengthen it.
std::string weak_line(const nlohmann::ordered_json& sensitivity);

}  // namespace bloomref::results
