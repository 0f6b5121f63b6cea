// bloomref.check: the check command itself (cli/check/command.h), run in this process. Arrays
// are written to a scratch folder as float EXR (lossless) and judged as files, because check
// reads its captures one by one as it reaches them; its judging takes far longer than the
// writing (docs/check.md, "Speed and memory").
#include "check.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <utility>
#include <vector>

#include "arrays.h"
#include "bloomref/error.h"
#include "bloomref/io.h"
#include "check/command.h"
#include "check/shaders.h"
#include "check/stage_images.h"
#include "escape.h"
#include "keywords.h"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace bloomref::python {
namespace {

// What the check is given, with the scratch files' paths and what to call them in messages and
// results (the caller's names, not the scratch folder's).
class CheckInputs {
 public:
  std::vector<std::string> args;

  void scene(const py::object& obj) {
    if (obj.is_none()) return;
    const std::string path = path_string(obj);
    if (!path.empty()) {
      args.push_back(path[0] == '-' ? "./" + path : path);
      return;
    }
    arrays_.push_back({scene_array(obj, "bloomref.check: scene"), scratch() / "scene.exr"});
    labels_.push_back({arrays_.back().second.string(), "scene (array)"});
    args.push_back(arrays_.back().second.string());
  }

  void stages(const py::object& obj) {
    if (obj.is_none()) return;
    const std::string path = path_string(obj);
    if (!path.empty()) {
      args.push_back("--stages=" + path);
      return;
    }
    if (!py::isinstance<py::dict>(obj))
      throw py::value_error("bloomref.check: stages must be a folder, or a dict from stage name "
                            "to an array or an image path");
    const fs::path dir = scratch() / "stages";
    fs::create_directories(dir);
    for (const auto& [key, value] : obj.cast<py::dict>()) {
      const std::string stage = py::str(key);
      if (!cli::looks_like_stage(stage))
        throw py::value_error("bloomref.check: stages['" + stage + "']: not a stage name (input, "
                              "bright, blur.N, down.N, up.N, bloom, composite, tonemap, output)");
      const std::string label = "stages['" + stage + "']";
      const std::string file = path_string(value);
      if (!file.empty()) {  // the file itself, under the stage's name
        const fs::path link = dir / (stage + fs::path(file).extension().string());
        fs::create_symlink(fs::absolute(file), link);
        labels_.push_back({link.string(), file});
        continue;
      }
      arrays_.push_back({scene_array(value, "bloomref.check: " + label), dir / (stage + ".exr")});
      labels_.push_back({arrays_.back().second.string(), label + " (array)"});
    }
    labels_.push_back({dir.string(), "stages"});
    args.push_back("--stages=" + dir.string());
  }

  /// Writes the arrays (without the GIL: the arrays are held by this object).
  void write_arrays() const {
    // Read back at once and removed: uncompressed, the fastest to write and to read.
    for (const auto& [array, file] : arrays_)
      save_exr(file.string(), array.view, nullptr, ExrCompression::none);
  }

  /// `text` with every scratch path replaced by the caller's name for it; `json` escapes the
  /// names as JSON string contents.
  std::string relabel(std::string text, bool json) const {
    auto labels = labels_;  // the longest paths first: a file before its folder
    std::sort(labels.begin(), labels.end(),
              [](const auto& a, const auto& b) { return a.first.size() > b.first.size(); });
    for (const auto& [from, to] : labels) {
      std::string name = to;
      if (json) {
        name = nlohmann::json(to).dump();
        name = name.substr(1, name.size() - 2);
      }
      for (std::size_t at = text.find(from); at != std::string::npos;
           at = text.find(from, at + name.size()))
        text.replace(at, from.size(), name);
    }
    return text;
  }

 private:
  const fs::path& scratch() {
    if (!scratch_) scratch_ = std::make_unique<cli::ScratchDir>();
    return scratch_->path();
  }

  std::unique_ptr<cli::ScratchDir> scratch_;
  std::vector<std::pair<SceneArray, fs::path>> arrays_;
  std::vector<std::pair<std::string, std::string>> labels_;
};

}  // namespace

py::dict check(const py::object& scene, const py::object& stages, const py::kwargs& kwargs) {
  CheckInputs in;
  in.scene(scene);
  in.stages(stages);
  for (std::string& a : option_arguments(kwargs)) in.args.push_back(std::move(a));
  in.args.push_back("-q");  // results come back as the dict; nothing is printed
  std::string text;
  try {
    py::gil_scoped_release unlocked;
    in.write_arrays();
    text = escape::json_text(cli::check_results(in.args), -1);
  } catch (const InputError& e) {
    throw py::value_error("bloomref.check: " + in.relabel(e.what(), false));
  } catch (const ParamError& e) {
    throw py::value_error("bloomref.check: " + in.relabel(e.what(), false));
  }
  py::dict result = py::module_::import("json").attr("loads")(in.relabel(text, true));
  if (result["verdict"].cast<std::string>() == "NOTHING")
    throw py::value_error("bloomref.check: nothing compared: no stage image matched (stage "
                          "files are named as --dump-stages names them: bright.exr, blur.1.exr "
                          "... output.exr)");
  return result;
}

}  // namespace bloomref::python
