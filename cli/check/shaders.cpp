#include "check/shaders.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <new>
#include <string>
#include <system_error>

#include "bloomref/error.h"
#include "bloomref/gpu/context.h"
#include "bloomref/gpu/described_pipeline.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/io.h"
#include "bloomref/memory_budget.h"
#include "bloomref/plan.h"
#include "bloomref/vulkan/described.h"
#include "check/layout.h"
#include "check/pipeline.h"

namespace bloomref::cli {

namespace fs = std::filesystem;

namespace {

std::optional<gpu::ShaderSource> optional_shader(const std::string& path) {
  if (path.empty()) return std::nullopt;
  return gpu::load_shader(path);
}

gpu::LearnOpenGLShaders load_shaders(const ShaderArgs& s) {
  if (s.preset != "learnopengl")
    throw ParamError("--shaders '" + s.preset +
                     "' is not a known preset (known: learnopengl, learnopengl-pbb, pipeline)");
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

gpu::MipChainShaders load_mip_chain_shaders(const ShaderArgs& s) {
  if (s.downsample_fs.empty() || s.upsample_fs.empty() || s.final_fs.empty())
    throw ParamError(
        "--shaders learnopengl-pbb needs --downsample-fs FILE, --upsample-fs FILE and --final-fs "
        "FILE");
  if (!s.blur_fs.empty() || !s.blur_vs.empty() || !s.bright_fs.empty())
    throw ParamError("--shaders learnopengl-pbb has no blur or bright pass: --blur-fs, --blur-vs "
                     "and --bright-fs are for --shaders learnopengl");
  gpu::MipChainShaders sh;
  sh.downsample_fs = gpu::load_shader(s.downsample_fs);
  sh.upsample_fs = gpu::load_shader(s.upsample_fs);
  sh.final_fs = gpu::load_shader(s.final_fs);
  sh.downsample_vs = optional_shader(s.downsample_vs);
  sh.upsample_vs = optional_shader(s.upsample_vs);
  sh.final_vs = optional_shader(s.final_vs);
  return sh;
}

// The article's host code around the user's shaders; every pass they drew is written to `dir`.
std::string run_mip_chain_shaders(const ShaderArgs& s, const std::string& scene_path,
                                  const PipelineOptions& pipeline, const fs::path& dir,
                                  bool& software, const std::function<void(int, int)>& on_scene) {
  if (!s.layout.empty())
    throw ParamError("--layout names what --shaders learnopengl binds; learnopengl-pbb takes the "
                     "article's names");
  const gpu::MipChainShaders shaders = load_mip_chain_shaders(s);
  gpu::MipChainOptions opt = gpu::mip_chain_options_for(pipeline.params);
  if (!s.target_format.empty()) opt.format = gpu::parse_target_format(s.target_format);
  if (s.filter != "linear" || s.wrap != "clamp-to-edge")
    throw ParamError("--shaders learnopengl-pbb samples as the article does (linear, clamp to "
                     "edge): --filter and --wrap are for --shaders learnopengl");
  opt.final_target = gpu::parse_final_target(s.final_target);
  std::string source;
  const LoadedImage scene = pipeline.load_input(scene_path, source);
  if (on_scene) on_scene(scene.image.width(), scene.image.height());
  auto ctx = gpu::GlContext::create();  // GlUnavailable -> exit 3
  gpu::check_mip_chain(*ctx, shaders, opt);
  const gpu::MipChainRun run = gpu::run_mip_chain(*ctx, scene.image.cview(), shaders, opt);
  for (const auto& st : run.run.trace.stages) {
    if (st.name == "input" || st.name == "bright") continue;  // the oracle's
    if (st.name == "output" && run.run.output_code_bits == 8)
      save_png((dir / "output.png").string(), st.image.cview());
    else
      save_exr((dir / (st.name + ".exr")).string(), st.image.cview(), nullptr, ExrCompression::none);
  }
  const gpu::ContextInfo& d = ctx->info();
  software = d.software;
  return d.renderer + " (" + d.version + ")";
}

// A pipeline description's passes around the user's shaders; every pass that names a stage is
// written to `dir`.
std::string run_pipeline_shaders(const ShaderArgs& s, const std::string& scene_path,
                                 const PipelineOptions& pipeline, const fs::path& dir,
                                 bool& software, const std::function<void(int, int)>& on_scene) {
  if (s.pipeline.empty())
    throw ParamError("--shaders pipeline needs --pipeline FILE (docs/check.md, \"Any host code\")");
  if (!s.given().empty() || !s.layout.empty() || !s.target_format.empty() ||
      s.filter != "linear" || s.wrap != "clamp-to-edge" || s.final_target != "same")
    throw ParamError("--shaders pipeline takes its shaders, formats and sampling from the "
                     "--pipeline file: no --*-fs, --*-vs, --layout, --target-format, --filter, "
                     "--wrap or --final-target");
  const gpu::PipelineDescription d = read_pipeline(s.pipeline);
  std::string source;
  const LoadedImage scene = pipeline.load_input(scene_path, source);
  if (on_scene) on_scene(scene.image.width(), scene.image.height());
  const std::vector<std::string> names =
      stage_names(pipeline.params, scene.image.width(), scene.image.height());
  for (const gpu::DescribedPass& p : d.passes)
    if (!p.stage.empty() && std::find(names.begin(), names.end(), p.stage) == names.end())
      throw InputError(s.pipeline, "a pass reads back stage '" + p.stage +
                                       "', which the pipeline judged against (--preset and the "
                                       "options) does not have on this scene");
  auto save = [&](const StageTrace& trace) {
    for (const auto& st : trace.stages)
      save_exr((dir / (st.name + ".exr")).string(), st.image.cview(), nullptr, ExrCompression::none);
  };
  if (s.backend == "vulkan") {
    auto vk = vulkan::Context::create();  // VulkanUnavailable -> exit 3
    save(vulkan::run_described(*vk, scene.image.cview(), d, pipeline.params));
    software = vk->info().type == "cpu";
    return vk->info().name + " (Vulkan compute, " + vk->info().driver_info + ")";
  }
  auto ctx = gpu::GlContext::create();  // GlUnavailable -> exit 3
  save(gpu::run_described(*ctx, scene.image.cview(), d, pipeline.params).trace);
  const gpu::ContextInfo& info = ctx->info();
  software = info.software;
  return info.renderer + " (" + info.version + ")";
}

}  // namespace

std::vector<std::string> ShaderArgs::given() const {
  std::vector<std::string> out;
  for (const std::string* f : {&bright_fs, &blur_vs, &blur_fs, &downsample_vs, &downsample_fs,
                               &upsample_vs, &upsample_fs, &final_vs, &final_fs})
    if (!f->empty()) out.push_back(*f);
  return out;
}

std::string ShaderArgs::files() const {
  if (preset == "pipeline") return "the shaders of " + pipeline;
  const std::vector<std::string> g = given();
  std::string out;
  for (std::size_t i = 0; i < g.size(); ++i)
    out += (i == 0 ? "" : i + 1 == g.size() ? " and " : ", ") + g[i];
  return out;
}

std::string run_user_shaders(const ShaderArgs& s, const std::string& scene_path,
                             const PipelineOptions& pipeline, const fs::path& dir, bool& software,
                             const std::function<void(int, int)>& on_scene) {
  if (s.preset == "learnopengl-pbb")
    return run_mip_chain_shaders(s, scene_path, pipeline, dir, software, on_scene);
  if (s.preset == "pipeline")
    return run_pipeline_shaders(s, scene_path, pipeline, dir, software, on_scene);
  const gpu::LearnOpenGLShaders shaders = load_shaders(s);
  gpu::UserPipelineOptions opt = gpu::options_for(pipeline.params);
  if (!s.target_format.empty()) opt.format = gpu::parse_target_format(s.target_format);
  opt.filter = gpu::parse_texture_filter(s.filter);
  opt.wrap = gpu::parse_texture_wrap(s.wrap);
  opt.final_target = gpu::parse_final_target(s.final_target);
  if (!s.layout.empty()) opt.layout = read_layout(s.layout);
  std::string source;
  const LoadedImage scene = pipeline.load_input(scene_path, source);
  if (on_scene) on_scene(scene.image.width(), scene.image.height());
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
      save_exr((dir / (st.name + ".exr")).string(), st.image.cview(), nullptr,
               ExrCompression::none);  // read back at once, never kept
  }
  const gpu::ContextInfo& d = ctx->info();
  software = d.software;
  return d.renderer + " (" + d.version + ")";
}

double shader_timeout(int width, int height) {
  return 120.0 + 20.0 * double(width) * double(height) / 1e6;
}

std::uint64_t shader_memory(int width, int height, std::uint64_t max_memory) {
  const std::uint64_t image = std::uint64_t(std::max(width, 1)) * std::uint64_t(std::max(height, 1)) * 16;
  return std::min<std::uint64_t>(max_memory, (std::uint64_t(1) << 30) + 24 * image);
}

namespace {

// The child's report through the pipe: fields separated by NUL bytes.
//   ok      software  renderer
//   input   file      problem
//   gl | error | memory | internal   message
void send(int fd, const std::vector<std::string>& fields) {
  std::string msg;
  for (const std::string& f : fields) msg += f + '\0';
  for (std::size_t off = 0; off < msg.size();) {
    const ssize_t n = ::write(fd, msg.data() + off, msg.size() - off);
    if (n <= 0) return;
    off += static_cast<std::size_t>(n);
  }
}

[[noreturn]] void child_main(int fd, const ShaderArgs& s, const std::string& scene_path,
                             const PipelineOptions& pipeline, const fs::path& dir) {
  int code = 0;
  try {
    bool software = false;
    const std::string renderer = run_user_shaders(
        s, scene_path, pipeline, dir, software,
        [fd](int w, int h) { send(fd, {"size", std::to_string(w), std::to_string(h)}); });
    send(fd, {"ok", software ? "1" : "0", renderer});
  } catch (const gpu::GlUnavailable& e) {
    send(fd, {"gl", e.what()});
  } catch (const vulkan::VulkanUnavailable& e) {
    send(fd, {"vulkan", e.what()});
  } catch (const InputError& e) {
    send(fd, {"input", e.file(), e.problem()});
  } catch (const Error& e) {
    send(fd, {"error", e.what()});
  } catch (const std::bad_alloc&) {
    send(fd, {"memory", "out of memory"});
  } catch (const std::exception& e) {
    send(fd, {"internal", e.what()});
    code = 4;
  }
  ::close(fd);
  ::_exit(code);  // no destructors, no atexit: the parent owns the folder and the terminal
}

// Resident bytes of process `pid` (/proc/PID/statm), 0 when unreadable.
std::uint64_t resident_bytes(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/statm");
  std::uint64_t size = 0, resident = 0;
  if (!(f >> size >> resident)) return 0;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

// The shader files, comma-separated: the `file` of an InputError about them.
std::string shader_names(const ShaderArgs& s) {
  std::string out;
  for (const std::string& f : s.given()) out += (out.empty() ? "" : ", ") + f;
  return out;
}

}  // namespace

std::string run_user_shaders_bounded(const ShaderArgs& s, const std::string& scene_path,
                                     const PipelineOptions& pipeline, const fs::path& dir,
                                     bool& software) {
  const std::uint64_t budget = pipeline.memory_budget();
  // Until the child says the scene's size: the run's memory limit, and the time a scene of the
  // largest size bloomref reads would be given.
  std::uint64_t memory = s.max_memory.empty() ? budget : parse_byte_size(s.max_memory, "--shader-memory");
  double timeout = s.timeout_s > 0 ? s.timeout_s : shader_timeout(65536, 2048);
  auto limit_by_scene = [&](int w, int h) {
    if (s.max_memory.empty()) memory = shader_memory(w, h, budget);
    if (s.timeout_s <= 0) timeout = shader_timeout(w, h);
  };
  const std::uint64_t baseline = resident_bytes(::getpid());  // a forked child starts with it
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw Error("cannot make a pipe for the shaders' process");
  std::fflush(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw Error("cannot start a process for the shaders");
  }
  if (pid == 0) {
    ::close(fds[0]);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // ends with the parent, however it ends
    if (::getppid() != parent) ::_exit(4);
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) ::signal(sig, SIG_DFL);  // the parent cleans up
    child_main(fds[1], s, scene_path, pipeline, dir);
  }
  ::close(fds[1]);
  std::string msg;
  std::string over;  // why the child was ended
  const auto t0 = std::chrono::steady_clock::now();
  std::uint64_t peak = 0;
  bool sized = false;
  for (bool open = true; open;) {
    pollfd p{fds[0], POLLIN, 0};
    const int r = ::poll(&p, 1, 20);
    if (r > 0) {
      char buf[4096];
      const ssize_t n = ::read(fds[0], buf, sizeof buf);
      if (n > 0) msg.append(buf, static_cast<std::size_t>(n));
      else if (n == 0 || errno != EINTR) open = false;
    }
    if (!sized && msg.rfind("size", 0) == 0 && std::count(msg.begin(), msg.end(), '\0') >= 3) {
      const std::size_t a = msg.find('\0') + 1, b = msg.find('\0', a), c = msg.find('\0', b + 1);
      limit_by_scene(std::atoi(msg.substr(a, b - a).c_str()),
                     std::atoi(msg.substr(b + 1, c - b - 1).c_str()));
      msg.erase(0, c + 1);
      sized = true;
    }
    peak = std::max(peak, resident_bytes(pid));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (open && peak > baseline + memory) over = "used more than " + byte_size_text(memory) + " of memory";
    else if (open && seconds > timeout)
      over = "ran longer than " + std::to_string(static_cast<long>(timeout)) + " s";
    if (!over.empty()) {
      ::kill(pid, SIGKILL);
      break;
    }
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!over.empty())
    throw InputError(shader_names(s),
                     "compiling and running these shaders " + over +
                         " (limits: --shader-timeout, --shader-memory); nothing was judged");
  std::vector<std::string> f;
  for (std::size_t a = 0, b; a < msg.size(); a = b + 1) {
    b = msg.find('\0', a);
    if (b == std::string::npos) break;
    f.push_back(msg.substr(a, b - a));
  }
  if (f.empty()) {
    const std::string how = WIFSIGNALED(status) ? "was ended by signal " + std::to_string(WTERMSIG(status))
                                                : "exited with status " + std::to_string(WEXITSTATUS(status));
    throw InputError(shader_names(s), "the GL driver's process " + how +
                                          " while compiling or running these shaders; nothing was judged");
  }
  if (f[0] == "ok" && f.size() == 3) {
    software = f[1] == "1";
    return f[2];
  }
  if (f[0] == "gl" && f.size() == 2) throw gpu::GlUnavailable(f[1]);
  if (f[0] == "vulkan" && f.size() == 2) throw vulkan::VulkanUnavailable(f[1]);
  if (f[0] == "input" && f.size() == 3) throw InputError(f[1], f[2]);
  if (f[0] == "error" && f.size() == 2) throw Error(f[1]);
  if (f[0] == "memory")
    throw InputError(shader_names(s), "compiling and running these shaders ran out of memory");
  throw std::runtime_error(f.size() > 1 ? f[1] : "the shaders' process failed");
}

}  // namespace bloomref::cli
