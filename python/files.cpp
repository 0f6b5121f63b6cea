#include "files.h"

#include "arrays.h"
#include "bloomref/io.h"
#include "keywords.h"

namespace py = pybind11;

namespace bloomref::python {

namespace {
std::string required_path(const py::object& path, const char* fn) {
  const std::string p = path_string(path);
  if (p.empty()) throw py::value_error(std::string(fn) + ": path must be a str or os.PathLike");
  return p;
}
}  // namespace

py::array load(const py::object& path) {
  const std::string p = required_path(path, "bloomref.load");
  LoadedImage in;
  {
    py::gil_scoped_release unlocked;
    in = load_image(p);  // InputError naming the file: ValueError
  }
  return to_array(std::move(in.image));
}

void save(const py::object& path, const py::object& image) {
  const std::string p = required_path(path, "bloomref.save");
  const SceneArray s = scene_array(image, "bloomref.save: image");
  py::gil_scoped_release unlocked;
  save_image(p, s.view);
}

}  // namespace bloomref::python
