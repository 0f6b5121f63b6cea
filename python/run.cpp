// bloomref.run: the pipeline of `bloomref run`, called directly (runtime/, gpu/), on an array,
// an image file or a built-in scene.
#include "run.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <utility>

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

// Whether [a, a + an) and [b, b + bn) share a byte.
bool overlap(const float* a, std::size_t an, const float* b, std::size_t bn) {
  const auto x = reinterpret_cast<std::uintptr_t>(a), y = reinterpret_cast<std::uintptr_t>(b);
  return x < y + bn * sizeof(float) && y < x + an * sizeof(float);
}

}  // namespace

py::object run(const py::object& image, bool keep_stages, const py::object& out,
               const py::kwargs& kwargs) {
  const RunOptions o = parse_run_options(kwargs);
  if (!out.is_none() && keep_stages)
    throw py::value_error("bloomref.run: out and keep_stages do not go together (out receives "
                          "the output only)");
  SceneArray scene;
  LoadedImage loaded;  // a file or a built-in scene, handed over to the executor
  std::string source = "array";
  const std::string path = path_string(image);
  const bool from_array = !image.is_none() && path.empty();
  if (from_array) {
    scene = scene_array(image, "bloomref.run: image");
  } else {
    py::gil_scoped_release unlocked;
    loaded = o.pipeline.load_input(path, source);
  }
  const ConstImageView view = from_array ? scene.view : loaded.image.cview();
  OutArray target;
  if (!out.is_none()) target = out_array(out, view.width, view.height, "bloomref.run: out");
  const std::size_t values = std::size_t(view.width) * view.height * kChannels;

  // out= an array whose buffer is a bloomref image (one this module returned): the buffer is
  // handed to the executor, which leaves the output in it (output_in_given_buffer), and taken
  // back, with the GIL, even on an exception (the executor gives it back then). In place when
  // it is the scene's own buffer, as the command runs on the image it loaded; a scene that
  // shares some other part of it is read first, and the output copied in.
  ExecuteOptions eo;
  eo.keep_all = keep_stages;
  Image handed;
  bool in_place = false;
  if (target.image && o.backend == "cpu" && output_in_given_buffer(o.pipeline.params, eo)) {
    const std::size_t scene_values = std::size_t(view.stride) * (view.height - 1) * kChannels +
                                     std::size_t(view.width) * kChannels;
    in_place = view.data == target.data && view.stride == view.width;
    if (in_place || !overlap(view.data, scene_values, target.data, values))
      handed = std::exchange(*target.image, Image());
  }
  struct GiveBack {  // the handed buffer back into its array's image, after the GIL is taken
    Image* to;
    Image* from;
    ~GiveBack() {
      if (to && from->data() && to->empty()) *to = std::move(*from);
    }
  };
  const bool handing = !handed.empty();
  StageTrace trace;
  GiveBack give_back{target.image, &handed};
  {
    py::gil_scoped_release unlocked;
    const Plan plan = make_plan(o.pipeline.params, view, source);
    if (handed.empty()) {
      Image* owned = !from_array ? &loaded.image : scene.copied ? &scene.copy : nullptr;
      trace = execute_on(o, plan, view, owned, keep_stages);
    } else if (in_place) {
      trace = execute(plan, std::move(handed), eo);
    } else {
      trace = execute(plan, view, std::move(handed), eo);
    }
  }
  Image& result = trace.stages.back().image;
  if (handing) {
    if (result.data() != target.data)  // output_in_given_buffer promised otherwise
      throw std::logic_error("bloomref.run: the output left the buffer of out");
    handed = std::move(result);  // given back to the array by give_back
    return out;
  }
  if (target.data) {
    std::copy(result.data(), result.data() + values, target.data);
    return out;
  }
  if (!keep_stages) return to_array(std::move(result));
  py::dict stages;
  for (StageResult& s : trace.stages) stages[py::str(s.name)] = to_array(std::move(s.image));
  return std::move(stages);
}

}  // namespace bloomref::python
