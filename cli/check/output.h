// The results of bloomref check as files: JSON (version 1, docs/schemas/check-result.v1.json),
// JUnit XML (a testsuite per item, a testcase per stage), and a short Markdown summary for a
// CI job's summary page.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "check/types.h"

namespace bloomref::cli {

nlohmann::ordered_json check_json(const CheckRun& run);
std::string junit_xml(const CheckRun& run);
std::string markdown_summary(const CheckRun& run);

/// What an item's verdict could see, in words ("a bloom gain of 1.05x (at blur.10), a shift of
/// 1 texel (at blur.10), a spread 5% wider (at blur.10)"), and why a weak one is weak.
std::string sensitivity_line(const ItemResult& r);
std::string weak_line(const ItemResult& r);
/// What an error entering at one stage would have shown, in the same words.
std::string stage_sensitivity_line(const parity::StageSensitivity& s);

}  // namespace bloomref::cli
