// bloomref.load and bloomref.save: image files as arrays, through bloomref's own readers and
// writers (io.h), as the command reads and writes them.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

namespace bloomref::python {

/// The image at `path` as a float32 H x W x 4 array (RGB files get alpha 1).
pybind11::array load(const pybind11::object& path);

/// Writes `image` (as run takes it) by the extension of `path`: .exr (32-bit float RGBA) or .png
/// (8-bit, round(clamp(x, 0, 1) * 255)); atomically.
void save(const pybind11::object& path, const pybind11::object& image);

}  // namespace bloomref::python
