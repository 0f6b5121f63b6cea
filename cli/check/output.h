// The results of bloomref check as one JSON document (version 1,
// docs/schemas/check-result.v1.json): what the Python module returns and the --json file holds,
// and what the console, JUnit and Markdown are written from (results.h).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "check/types.h"

namespace bloomref::cli {

nlohmann::ordered_json check_json(const CheckRun& run);

}  // namespace bloomref::cli
