// bloomref.run: the pipeline of `bloomref run`, called directly (runtime/, gpu/), on an array,
// an image file or a built-in scene.
#include "run.h"

#include <CLI/CLI.hpp>

#include "arrays.h"
#include "bloomref/error.h"
#include "bloomref/executor.h"
#include "bloomref/gpu/context.h"
#include "bloomref/gpu/gl_executor.h"
#include "keywords.h"
#include "options.h"  // cli/options.h: PipelineOptions

namespace py = pybind11;

namespace bloomref::python {
namespace {

struct RunOptions {
  cli::PipelineOptions pipeline;
  std::string backend = "cpu";
  std::string gl_shaders = "fragment";
};

// The options `bloomref run` shares with this function, parsed by the command line's own
// parser: the same names, defaults and refusals.
RunOptions parse_run_options(const py::kwargs& kwargs) {
  RunOptions o;
  CLI::App app{"bloomref.run"};
  app.set_help_flag();
  o.pipeline.add_to(app);
  app.add_option("--backend", o.backend);
  app.add_option("--gl-shaders", o.gl_shaders);
  const std::vector<std::string> args = option_arguments(kwargs);
  for (const std::string& a : args) {
    const std::string name = a.substr(0, a.find('='));
    if (!app.get_option_no_throw(name)) {
      std::string key = name.substr(2);
      for (char& c : key)
        if (c == '-') c = '_';
      throw py::value_error("bloomref.run: unknown option '" + key + "'");
    }
  }
  try {
    app.parse(std::vector<std::string>(args.rbegin(), args.rend()));
  } catch (const CLI::ParseError& e) {
    throw py::value_error(std::string("bloomref.run: ") + e.what());
  }
  o.pipeline.finish();  // ParamError: ValueError
  if (o.backend != "cpu" && o.backend != "gl")
    throw ParamError("--backend '" + o.backend + "' is not one of: cpu, gl");
  return o;
}

// The CPU executor reads an array in place (or copies it where a stage would write it) and
// writes the output into the buffer of an array Python has released (kept_buffer), or takes
// over the image this call made itself (a file, a built-in scene, a converted array).
StageTrace execute_on(const RunOptions& o, const Plan& plan, ConstImageView scene,
                      Image* owned, bool keep_stages) {
  if (o.backend == "gl") {
    auto ctx = gpu::GlContext::create();  // GlUnavailable
    gpu::GlOptions go;
    go.shaders = gpu::parse_shader_kind(o.gl_shaders);
    go.keep_all = keep_stages;
    return gpu::execute_gl(*ctx, plan, scene, go);
  }
  ExecuteOptions eo;
  eo.keep_all = keep_stages;
  if (owned) return execute(plan, std::move(*owned), eo);
  return execute(plan, scene, kept_buffer(scene.width, scene.height), eo);
}

}  // namespace

py::object run(const py::object& image, bool keep_stages, const py::kwargs& kwargs) {
  const RunOptions o = parse_run_options(kwargs);
  SceneArray scene;
  LoadedImage loaded;  // a file or a built-in scene, handed over to the executor
  std::string source = "array";
  const std::string path = path_string(image);
  const bool from_array = !image.is_none() && path.empty();
  if (from_array) scene = scene_array(image, "bloomref.run: image");
  StageTrace trace;
  {
    py::gil_scoped_release unlocked;
    if (!from_array) loaded = o.pipeline.load_input(path, source);
    const ConstImageView view = from_array ? scene.view : loaded.image.cview();
    const Plan plan = make_plan(o.pipeline.params, view, source);
    Image* owned = !from_array ? &loaded.image : scene.copied ? &scene.copy : nullptr;
    trace = execute_on(o, plan, view, owned, keep_stages);
  }
  if (!keep_stages) return to_array(std::move(trace.stages.back().image));
  py::dict stages;
  for (StageResult& s : trace.stages) stages[py::str(s.name)] = to_array(std::move(s.image));
  return std::move(stages);
}

}  // namespace bloomref::python
