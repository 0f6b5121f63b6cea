// bloomref.check: the check command itself (cli/check/command.h), run in this process on the
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
#include "check/command.h"
#include "check/stage_images.h"
#include "escape.h"
#include "keywords.h"

namespace py = pybind11;

namespace bloomref::python {
namespace {

// What the check is given: the scene and stages as arrays held here (the views point into
// them), or as paths.
class CheckInputs {
 public:
  std::vector<std::string> args;
  cli::InMemoryItem memory;
  bool in_memory = false;

  void scene(const py::object& obj) {
    if (obj.is_none()) return;
    const std::string path = path_string(obj);
    if (!path.empty()) {
      scene_path_ = path[0] == '-' ? "./" + path : path;
      return;
    }
    arrays_.push_back(scene_array(obj, "bloomref.check: scene"));
    memory.scene = &arrays_.back().view;
    memory.scene_name = "scene (array)";
    in_memory = true;
  }

  void stages(const py::object& obj) {
    if (obj.is_none()) return;
    const std::string path = path_string(obj);
    if (!path.empty()) {
      stages_dir_ = path;
      return;
    }
    if (!py::isinstance<py::dict>(obj))
      throw py::value_error("bloomref.check: stages must be a folder, or a dict from stage name "
                            "to an array or an image path");
    in_memory = true;
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
      memory.stages.push_back(std::move(f));
    }
  }

  /// The command line: the scene and the stage folder as arguments unless the item is in
  /// memory, which then holds them.
  void finish() {
    if (in_memory) {
      if (!memory.scene && !scene_path_.empty()) memory.scene_name = scene_path_;
      memory.stages_dir = stages_dir_;
      if (!memory.scene && !scene_path_.empty()) args.insert(args.begin(), scene_path_);
      return;
    }
    if (!scene_path_.empty()) args.insert(args.begin(), scene_path_);
    if (!stages_dir_.empty()) args.push_back("--stages=" + stages_dir_);
  }

 private:
  std::deque<SceneArray> arrays_;  // a deque: the views handed out stay where they are
  std::string scene_path_, stages_dir_;
};

}  // namespace

py::dict check(const py::object& scene, const py::object& stages, const py::kwargs& kwargs) {
  CheckInputs in;
  in.scene(scene);
  in.stages(stages);
  for (std::string& a : option_arguments(kwargs)) in.args.push_back(std::move(a));
  in.args.push_back("-q");  // results come back as the dict; nothing is printed
  in.finish();
  std::string text;
  try {
    py::gil_scoped_release unlocked;
    text = escape::json_text(cli::check_results(in.args, in.in_memory ? &in.memory : nullptr), -1);
  } catch (const InputError& e) {
    throw py::value_error("bloomref.check: " + std::string(e.what()));
  } catch (const ParamError& e) {
    throw py::value_error("bloomref.check: " + std::string(e.what()));
  }
  py::dict result = py::module_::import("json").attr("loads")(text);
  if (result["verdict"].cast<std::string>() == "NOTHING")
    throw py::value_error("bloomref.check: nothing compared: no stage image matched (stage "
                          "files are named as --dump-stages names them: bright.exr, blur.1.exr "
                          "... output.exr)");
  return result;
}

}  // namespace bloomref::python
