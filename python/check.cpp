// bloomref.check: the check library (cli/check/check.h) called in this process with the
// caller's arrays where it will read them: nothing is written to disk for them. Stages given as
// paths are read as the command reads them; every message and result names what the caller
// gave (a path, or "stages['blur.1'] (array)").
#include "check.h"

#include <nlohmann/json.hpp>

#include <deque>
#include <utility>
#include <vector>

#include "arrays.h"
#include "bloomref/error.h"
#include "check/check.h"
#include "check/command.h"
#include "check/output.h"
#include "check/stage_images.h"
#include "escape.h"
#include "keywords.h"

namespace py = pybind11;

namespace bloomref::python {
namespace {

// What the check is given: the scene and stages as arrays held here (the request's views point
// into them), or as paths.
class CheckInputs {
 public:
  explicit CheckInputs(cli::CheckRequest& request) : request_(request) {}

  void scene(const py::object& obj) {
    if (obj.is_none()) return;
    const std::string path = path_string(obj);
    if (!path.empty()) {
      request_.scene = path;
      return;
    }
    arrays_.push_back(scene_array(obj, "bloomref.check: scene"));
    request_.scene_image = &arrays_.back().view;
    request_.scene = "scene (array)";
  }

  void stages(const py::object& obj) {
    if (obj.is_none()) return;
    const std::string path = path_string(obj);
    if (!path.empty()) {
      request_.stages_dir = path;
      return;
    }
    if (!py::isinstance<py::dict>(obj))
      throw py::value_error("bloomref.check: stages must be a folder, or a dict from stage name "
                            "to an array or an image path");
    request_.stages.emplace();
    for (const auto& [key, value] : obj.cast<py::dict>()) {
      const std::string stage = py::str(key);
      if (!cli::looks_like_stage(stage))
        throw py::value_error("bloomref.check: stages['" + stage + "']: not a stage name (input, "
                              "bright, blur.N, down.N, up.N, bloom, composite, tonemap, output)");
      cli::StageFile f;
      f.stage = stage;
      const std::string file = path_string(value);
      if (!file.empty()) {  // the file itself, read as the command reads it
        f.path = file;
      } else {
        arrays_.push_back(scene_array(value, "bloomref.check: stages['" + stage + "']"));
        f.path = "stages['" + stage + "'] (array)";
        f.image = &arrays_.back().view;
      }
      request_.stages->push_back(std::move(f));
    }
  }

 private:
  cli::CheckRequest& request_;
  std::deque<SceneArray> arrays_;  // a deque: the views handed out stay where they are
};

}  // namespace

py::dict check(const py::object& scene, const py::object& stages, const py::kwargs& kwargs) {
  nlohmann::ordered_json result;
  try {
    // The options as the command takes them, then the scene and stages as the caller gave them.
    cli::CheckRequest request = cli::parse_check_request(option_arguments(kwargs));
    request.print_results = request.print_notes = false;  // results come back as the dict
    CheckInputs in(request);
    in.scene(scene);
    in.stages(stages);
    py::gil_scoped_release unlocked;
    result = cli::check_json(cli::check(std::move(request)));
  } catch (const InputError& e) {
    throw py::value_error("bloomref.check: " + std::string(e.what()));
  } catch (const ParamError& e) {
    throw py::value_error("bloomref.check: " + std::string(e.what()));
  }
  if (result["verdict"] == "NOTHING")
    throw py::value_error("bloomref.check: nothing compared: no stage image matched (stage "
                          "files are named as --dump-stages names them: bright.exr, blur.1.exr "
                          "... output.exr)");
  return py::module_::import("json").attr("loads")(escape::json_text(result, -1));
}

}  // namespace bloomref::python
