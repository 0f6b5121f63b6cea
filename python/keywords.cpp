#include "keywords.h"

namespace py = pybind11;

namespace bloomref::python {

std::string path_string(const py::handle& obj) {
  if (py::isinstance<py::str>(obj)) return obj.cast<std::string>();
  if (py::isinstance<py::bytes>(obj)) return obj.cast<std::string>();
  if (py::hasattr(obj, "__fspath__")) {
    const py::object p = py::module_::import("os").attr("fspath")(obj);
    return py::isinstance<py::bytes>(p) || py::isinstance<py::str>(p) ? p.cast<std::string>() : "";
  }
  return "";
}

std::vector<std::string> option_arguments(const py::kwargs& kwargs) {
  std::vector<std::string> args;
  for (const auto& [key, value] : kwargs) {
    std::string name = "--" + key.cast<std::string>();
    for (char& c : name)
      if (c == '_') c = '-';
    if (value.is_none()) continue;
    if (py::isinstance<py::bool_>(value)) {
      if (value.cast<bool>()) args.push_back(name);
      continue;
    }
    const std::string path = path_string(value);
    args.push_back(name + "=" + (path.empty() ? std::string(py::str(value)) : path));
  }
  return args;
}

}  // namespace bloomref::python
