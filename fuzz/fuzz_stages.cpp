// libFuzzer target: a stage folder as `bloomref check SCENE --stages DIR` reads it
// (cli/check/stage_images.h). The first input byte chooses the file's name (a stage, an alias
// or a name that is not a stage), its declared encoding, row order, channel order and raw
// layout; the rest is the file. The plan is a 16x12 scene with 2 blur passes and the mip chain
// of depth 2, so that full-size and mip-level stages both occur. A bad file must come out as an
// InputError naming it (exit 2); any other exception (exit 4), a crash, a leak, undefined
// behaviour, or a loaded image of another size than the stage's is a finding.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "bloomref/parity/compare.h"
#include "bloomref/parity/profile.h"
#include "check/stage_images.h"

namespace fs = std::filesystem;
namespace cli = bloomref::cli;

namespace {

fs::path g_dir;

const char* const kNames[] = {"bright.exr",    "blur.2.exr",   "down.1.raw", "up.1.bin",
                              "composite.png", "output.png",   "bloom.hdr",  "tonemap.tif",
                              "blur.9.exr",    "mystage.raw",  "notes.txt",  "input.exr",
                              "down.2.exr",    "blur.1.tiff",  "bright.raw", "output.raw"};

bloomref::Plan make_plan(bool mip) {
  bloomref::BloomParams p;
  p.passes = 2;
  if (mip) {
    p.method = bloomref::Method::mip;
    p.levels = 2;
  }
  const bloomref::Image scene(16, 12, 1.5f);
  return bloomref::parity::plan_for_device(p, scene.cview(), bloomref::parity::profile_llvmpipe());
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bloomref::set_io_threads(1);
  const char* tmp = std::getenv("TMPDIR");
  g_dir = fs::path(tmp && *tmp ? tmp : "/tmp") /
          ("bloomref-fuzz-stages-" + std::to_string(::getpid()));
  std::atexit([] {
    std::error_code ec;
    fs::remove_all(g_dir, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2 || size > (1u << 20)) return 0;
  static const bloomref::Plan plans[2] = {make_plan(false), make_plan(true)};
  const std::uint8_t choice = data[0], layout = data[1];
  std::error_code ec;
  fs::remove_all(g_dir, ec);
  fs::create_directories(g_dir);
  const std::string name = kNames[choice & 15];
  std::FILE* f = std::fopen((g_dir / name).c_str(), "wb");
  if (!f) std::abort();
  if (size > 2 && std::fwrite(data + 2, 1, size - 2, f) != size - 2) std::abort();
  std::fclose(f);

  cli::StageFile proto;
  proto.encoding = static_cast<cli::Encoding>((layout & 7) % 5);
  proto.origin = (layout & 8) ? cli::Origin::bottom : cli::Origin::top;
  proto.channels = static_cast<cli::ChannelOrder>(((layout >> 4) & 3) % 3);
  proto.format = (layout & 64) ? cli::RawFormat::f16 : cli::RawFormat::f32;
  const std::map<std::string, std::string> aliases = {{"mystage", "blur.1"}};
  const bloomref::Plan& plan = plans[(choice >> 4) & 1];
  try {
    std::vector<std::string> ignored;
    for (const cli::StageFile& sf : cli::find_stage_files(g_dir.string(), plan, proto, aliases,
                                                          ignored)) {
      int w = 0, h = 0;
      cli::stage_size(plan, sf.stage, w, h);
      const cli::LoadedStage st = cli::load_stage(sf, w, h);
      if (st.image.width() != w || st.image.height() != h) std::abort();
    }
  } catch (const bloomref::Error&) {
  }
  return 0;
}
