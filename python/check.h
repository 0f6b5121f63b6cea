// bloomref.check (module.cpp documents it for Python).
#pragma once

#include <pybind11/pybind11.h>

namespace bloomref::python {

/// `bloomref check` on `scene` (an array, an image path, or None for the built-in --scene) and
/// `stages` (a folder, a dict from stage name to an array or an image path, or None with the
/// `manifest` or `shaders` option): its --json result as a dict.
pybind11::dict check(const pybind11::object& scene, const pybind11::object& stages,
                     const pybind11::kwargs& kwargs);

}  // namespace bloomref::python
