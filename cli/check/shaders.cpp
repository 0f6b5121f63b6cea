#include "check/shaders.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <string>
#include <system_error>

#include "bloomref/error.h"
#include "bloomref/gpu/context.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/io.h"
#include "check/layout.h"

namespace bloomref::cli {

namespace fs = std::filesystem;

ScratchDir::ScratchDir() {
  static std::atomic<int> counter{0};
  const char* tmp = std::getenv("TMPDIR");
  const fs::path base = tmp && *tmp ? fs::path(tmp) : fs::temp_directory_path();
  path_ = base / ("bloomref-check-" + std::to_string(::getpid()) + "-" +
                  std::to_string(counter++));
  std::error_code ec;
  fs::remove_all(path_, ec);
  if (!fs::create_directories(path_, ec) || ec)
    throw InputError(path_.string(), "cannot make a temporary folder: " + ec.message());
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

namespace {

std::optional<gpu::ShaderSource> optional_shader(const std::string& path) {
  if (path.empty()) return std::nullopt;
  return gpu::load_shader(path);
}

gpu::LearnOpenGLShaders load_shaders(const ShaderArgs& s) {
  if (s.preset != "learnopengl")
    throw ParamError("--shaders '" + s.preset + "' is not a known preset (known: learnopengl)");
  if (s.blur_fs.empty() || s.final_fs.empty())
    throw ParamError("--shaders learnopengl needs --blur-fs FILE and --final-fs FILE");
  gpu::LearnOpenGLShaders sh;
  sh.blur_fs = gpu::load_shader(s.blur_fs);
  sh.final_fs = gpu::load_shader(s.final_fs);
  sh.blur_vs = optional_shader(s.blur_vs);
  sh.final_vs = optional_shader(s.final_vs);
  sh.bright_fs = optional_shader(s.bright_fs);
  return sh;
}

}  // namespace

std::string run_user_shaders(const ShaderArgs& s, const std::string& scene_path,
                             const PipelineOptions& pipeline, const fs::path& dir, bool& software) {
  const gpu::LearnOpenGLShaders shaders = load_shaders(s);
  gpu::UserPipelineOptions opt = gpu::options_for(pipeline.params);
  if (!s.target_format.empty()) opt.format = gpu::parse_target_format(s.target_format);
  opt.filter = gpu::parse_texture_filter(s.filter);
  opt.wrap = gpu::parse_texture_wrap(s.wrap);
  opt.final_target = gpu::parse_final_target(s.final_target);
  if (!s.layout.empty()) opt.layout = read_layout(s.layout);
  std::string source;
  const LoadedImage scene = pipeline.load_input(scene_path, source);
  auto ctx = gpu::GlContext::create();  // GlUnavailable -> exit 3
  // Refused shaders (a missing or unknown uniform, a compile error) stop here, before drawing.
  gpu::check_learnopengl(*ctx, shaders, opt);
  const gpu::UserPipelineRun run = gpu::run_learnopengl(*ctx, scene.image.cview(), shaders, opt);
  for (const auto& st : run.trace.stages) {
    // Only what the user's shaders drew is theirs to be judged: the input and (unless their own
    // bright shader made it) the bright image are the oracle's.
    const bool theirs = st.name.rfind("blur.", 0) == 0 || st.name == "output" ||
                        (st.name == "bright" && run.bright_source != "oracle");
    if (!theirs) continue;
    if (st.name == "output" && run.output_code_bits == 8)
      save_png((dir / "output.png").string(), st.image.cview());  // codes / 255: exact
    else
      save_exr((dir / (st.name + ".exr")).string(), st.image.cview());
  }
  const gpu::ContextInfo& d = ctx->info();
  software = d.software;
  return d.renderer + " (" + d.version + ")";
}

}  // namespace bloomref::cli
