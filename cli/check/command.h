// bloomref check's command line: the request it fills (check/check.h), for the command and for
// callers in this process that take the command's options (the Python module).
#pragma once

#include <string>
#include <vector>

#include "check/check.h"

namespace bloomref::cli {

/// The request `bloomref check ARGS` makes (ARGS: the arguments after the word "check"), with
/// the options given in `given`, the console quiet or not as -q says, and notes on stderr.
/// ParamError for a command line that does not parse (CLI11's message).
CheckRequest parse_check_request(const std::vector<std::string>& args);

}  // namespace bloomref::cli
