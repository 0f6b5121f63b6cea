// libFuzzer target: one image file read as `bloomref run FILE` reads it (load_image).
// FUZZ_EXTENSION names the format, as the file's extension does for the command: ".exr"
// (OpenEXR), ".hdr", ".png", ".tif" (the OpenImageIO module). A bad file must come out as an
// InputError (exit 2); any other exception (the command's exit 4), a crash, a leak or undefined
// behaviour is a finding.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "bloomref/error.h"
#include "bloomref/io.h"

#ifndef FUZZ_EXTENSION
#error "FUZZ_EXTENSION must name the format, e.g. \".exr\""
#endif

namespace {

// The input goes to a file of this process (the readers take paths), on tmpfs where there is
// one.
const std::string& input_path() {
  static const std::string path = [] {
    const char* dir = std::getenv("TMPDIR");
    std::string d = dir && *dir ? dir : (::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp");
    return d + "/bloomref-fuzz-" + std::to_string(::getpid()) + FUZZ_EXTENSION;
  }();
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bloomref::set_io_threads(1);  // one thread: findings reproduce, and no pool to tear down
  std::atexit([] { std::remove(input_path().c_str()); });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(input_path().c_str(), "wb");
  if (!f) std::abort();
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  // Limits well below the command's: a header may ask for any size, and the pixels of a
  // legitimate 65536 x 2048 image would only slow the search down.
  bloomref::SizeLimits limits;
  limits.max_side = 4096;
  limits.max_pixels = std::size_t(1) << 20;
  try {
    const bloomref::LoadedImage li = bloomref::load_image(input_path(), limits);
    if (li.image.width() != li.info.data_window.width() ||
        li.image.height() != li.info.data_window.height())
      std::abort();  // the image and its data window disagree
  } catch (const bloomref::Error&) {
    // refused with a message naming the file (exit 2): what a bad file must give
  }
  return 0;
}
