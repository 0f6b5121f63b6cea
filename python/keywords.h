// Keyword options as the command line's: `passes=5` is `--passes=5`, `karis=True` is `--karis`.
#pragma once

#include <pybind11/pybind11.h>

#include <string>
#include <vector>

namespace bloomref::python {

/// The command-line arguments for `kwargs`, in their order: each name with its underscores
/// turned into dashes; True gives the bare flag, False and None nothing; a path (os.PathLike)
/// its file-system string; anything else str(value), as `--name=value` (so a value may begin
/// with a dash).
std::vector<std::string> option_arguments(const pybind11::kwargs& kwargs);

/// A path-like argument (str, bytes or os.PathLike) as a string, or "" when `obj` is none of
/// them.
std::string path_string(const pybind11::handle& obj);

}  // namespace bloomref::python
