#include "test_util.h"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "bloomref/scenes.h"

namespace bloomref::test {

std::string corpus_dir() {
  const char* env = std::getenv("BLOOMREF_CORPUS");
  if (!env || !*env) return "";
  fs::path p(env);
  if (p.is_relative() && !fs::is_directory(p)) p = fs::path(BLOOMREF_SOURCE_DIR) / p;
  if (!fs::is_directory(p))
    throw std::runtime_error(std::string("BLOOMREF_CORPUS=") + env + " is not a folder");
  return fs::absolute(p).string();  // commands run from other folders read it too
}

std::string data_path(const std::string& name) {
  return (fs::path(BLOOMREF_SOURCE_DIR) / "data" / name).string();
}

std::vector<std::string> corpus_files() {
  std::vector<std::string> files;
  const std::string dir = corpus_dir();
  if (dir.empty()) return files;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (ext == ".exr" || ext == ".hdr") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<std::pair<std::string, Image>> scenes_and_corpus(
    std::vector<std::pair<std::string, Image>> extra) {
  std::vector<std::pair<std::string, Image>> inputs;
  for (const SceneInfo& s : scene_list()) inputs.emplace_back(s.name, make_scene(s.name));
  for (const std::string& f : corpus_files())
    inputs.emplace_back(std::filesystem::path(f).filename().string(), load_image(f).image);
  for (auto& e : extra) inputs.push_back(std::move(e));
  return inputs;
}

Image run_output(const Image& scene, const BloomParams& p) {
  return execute(make_plan(p, scene.cview()), scene.cview()).final_image();
}

std::map<std::string, Image> run_stages(BloomParams p, const Image& scene, int subtexel_bits) {
  p.subtexel_bits = subtexel_bits;
  ExecuteOptions eo;
  eo.keep_all = true;
  const StageTrace t = execute(make_plan(p, scene.cview()), scene.cview(), eo);
  std::map<std::string, Image> out;
  for (const StageResult& s : t.stages) out[s.name] = s.image;
  return out;
}

Image constant_image(int w, int h, float v) {
  Image img(w, h);
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    float* p = img.data() + i * kChannels;
    p[0] = p[1] = p[2] = v;
    p[3] = 1.0f;
  }
  return img;
}

double max_abs_diff(ConstImageView a, ConstImageView b) {
  double m = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double u = a.pixel(x, y)[c], v = b.pixel(x, y)[c];
        if (std::isfinite(u) && std::isfinite(v)) m = std::max(m, std::fabs(u - v));
      }
  return m;
}

bool bit_identical(ConstImageView a, ConstImageView b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y)
    if (std::memcmp(a.row(y), b.row(y), sizeof(float) * kChannels * a.width) != 0) return false;
  return true;
}

bool same_bits_nan_agnostic(ConstImageView a, ConstImageView b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y) {
    const float* p = a.row(y);
    const float* q = b.row(y);
    for (int i = 0; i < a.width * kChannels; ++i) {
      if (std::isnan(p[i]) && std::isnan(q[i])) continue;
      if (std::memcmp(p + i, q + i, sizeof(float)) != 0) return false;
    }
  }
  return true;
}

bool same_bits_nan_agnostic(float a, float b) {
  if (std::isnan(a) && std::isnan(b)) return true;
  return std::memcmp(&a, &b, sizeof(float)) == 0;
}

std::size_t count_nan(ConstImageView img) {
  std::size_t n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int i = 0; i < img.width * kChannels; ++i) n += std::isnan(img.row(y)[i]);
  return n;
}

std::vector<BlurIsa> isas() {
  std::vector<BlurIsa> v = {BlurIsa::generic};
  if (blur_isa_available(BlurIsa::avx2)) v.push_back(BlurIsa::avx2);
  if (blur_isa_available(BlurIsa::avx512)) v.push_back(BlurIsa::avx512);
  return v;
}

TempDir::TempDir() {
  std::string tmpl = (fs::temp_directory_path() / "bloomref-test-XXXXXX").string();
  if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::vector<std::string> TempDir::listing() const {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open " + path);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!f) throw std::runtime_error("cannot write " + path);
}

CliResult run_cli(const std::string& args, const std::string& env, const fs::path& cwd) {
  const TempDir logs;
  std::string cmd = cwd.empty() ? "" : "cd '" + cwd.string() + "' && ";
  cmd += env + " '" BLOOMREF_EXE "' " + args + " >'" + (logs / "out") + "' 2>'" +
         (logs / "err") + "'";
  const int status = std::system(cmd.c_str());
  if (status == -1) throw std::runtime_error("std::system could not start a shell");
  CliResult r;
  if (WIFEXITED(status)) r.code = WEXITSTATUS(status);
  else if (WIFSIGNALED(status)) r.code = 128 + WTERMSIG(status);
  r.out = read_bytes(logs / "out");
  r.err = read_bytes(logs / "err");
  return r;
}

int spawn_cli(const std::vector<std::string>& args, const fs::path& cwd,
              const std::vector<std::string>& env) {
  std::vector<std::string> argv_s{BLOOMREF_EXE};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  // The environment is made before fork: the child calls only async-signal-safe functions.
  // `env` first: getenv takes the first entry of a name.
  std::vector<std::string> env_s(env);
  for (char** e = environ; *e; ++e) env_s.emplace_back(*e);
  std::vector<char*> envp;
  for (std::string& e : env_s) envp.push_back(e.data());
  envp.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(127);
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  return pid;
}

int wait_cli(int pid) {
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid) throw std::runtime_error("waitpid failed");
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

bool has_open_file_in(int pid, const fs::path& dir) {
  std::error_code ec;
  const std::string prefix = fs::canonical(dir).string() + "/";
  for (const auto& e : fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
    std::error_code lec;
    const std::string target = fs::read_symlink(e.path(), lec).string();
    if (!lec && target.compare(0, prefix.size(), prefix) == 0) return true;
  }
  return false;
}

}  // namespace bloomref::test
