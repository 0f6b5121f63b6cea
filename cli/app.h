// The whole command line as a function, so that the executable, the Python module and tests
// run the same code: parses `args` (without the program name), runs the subcommand and returns
// its exit code (docs/check.md, "Exit codes": 0 success, 1 FAIL, 2 bad usage or input, 3 GL
// unavailable, 4 internal error, 5 nothing compared). Errors are printed to stderr as the CLI prints them.
#pragma once

#include <string>
#include <vector>

namespace bloomref::cli {

int run_command_line(const std::vector<std::string>& args);

}  // namespace bloomref::cli
