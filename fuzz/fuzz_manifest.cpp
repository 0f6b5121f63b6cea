// libFuzzer target: bloomref check's JSON inputs (cli/check/manifest.h): one file read as a
// manifest, as an expectations file and as a profile file. A bad file must come out as an
// InputError naming it (exit 2); any other exception (exit 4), a crash, a leak or undefined
// behaviour is a finding. The manifest sits in a folder holding a scene (scene.exr) and a folder
// of stages (stages/bright.exr), so that items naming them get past the existence checks.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "check/manifest.h"
#include "options.h"

namespace fs = std::filesystem;

namespace {

fs::path g_dir;

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tmp = std::getenv("TMPDIR");
  g_dir = fs::path(tmp && *tmp ? tmp : "/tmp") /
          ("bloomref-fuzz-manifest-" + std::to_string(::getpid()));
  fs::create_directories(g_dir / "stages");
  const bloomref::Image pixel(1, 1, 2.0f);
  bloomref::save_exr((g_dir / "scene.exr").string(), pixel.cview());
  bloomref::save_exr((g_dir / "stages" / "bright.exr").string(), pixel.cview());
  std::atexit([] {
    std::error_code ec;
    fs::remove_all(g_dir, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = (g_dir / "manifest.json").string();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  try {
    bloomref::cli::PipelineOptions pipeline;  // none given on the command line
    bloomref::cli::read_manifest(path, {}, pipeline);
  } catch (const bloomref::Error&) {
  }
  try {
    bloomref::cli::read_expectations(path);
  } catch (const bloomref::Error&) {
  }
  try {
    bloomref::cli::read_profile_file(path);
  } catch (const bloomref::Error&) {
  }
  return 0;
}
