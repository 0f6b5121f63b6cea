// libFuzzer target: check --layout's file (cli/check/layout.h), the description of the names a
// user's shaders use. A bad file must come out as an InputError naming it (exit 2); any other
// exception (exit 4), a crash, a leak or undefined behaviour is a finding.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "bloomref/error.h"
#include "check/layout.h"

namespace fs = std::filesystem;

namespace {
fs::path g_path;
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tmp = std::getenv("TMPDIR");
  g_path = fs::path(tmp && *tmp ? tmp : "/tmp") /
           ("bloomref-fuzz-layout-" + std::to_string(::getpid()) + ".json");
  std::atexit([] {
    std::error_code ec;
    fs::remove(g_path, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(g_path.c_str(), "wb");
  if (!f) std::abort();
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  try {
    (void)bloomref::cli::read_layout(g_path.string());
  } catch (const bloomref::InputError&) {
  }
  return 0;
}
