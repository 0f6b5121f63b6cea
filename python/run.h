// bloomref.run (module.cpp documents it for Python).
#pragma once

#include <pybind11/pybind11.h>

namespace bloomref::python {

/// The output (float32 H x W x 4), or with `keep_stages` a dict of every stage's image in plan
/// order. `image`: an array (scene_array), an image path, or None for the built-in `scene`.
/// `out`: None, or an array (arrays.h, out_array) the output is written into and returned.
pybind11::object run(const pybind11::object& image, bool keep_stages, const pybind11::object& out,
                     const pybind11::kwargs& kwargs);

}  // namespace bloomref::python
