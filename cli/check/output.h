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

}  // namespace bloomref::cli
