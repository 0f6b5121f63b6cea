// The bloomref command on bad input: exit code 2, a message on stderr naming the file and the
// problem, no crash, the input's bytes untouched, no output written. And on good input (every
// corpus image): exit 0, outputs written, no NaN in the output under the default policy.
//
// The command runs as a separate process (BLOOMREF_EXE) in a temporary folder.
#include <ImfInputFile.h>
#include <OpenImageIO/imageio.h>

#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

#include "bloomref/io.h"
#include "io_test_util.h"

using bloomref::test::CliResult;
using bloomref::test::run_cli;
using bloomref::test::TempDir;
namespace fs = std::filesystem;

namespace {

/// Runs a command that must be refused as bad input: exit 2, stderr names every item of
/// `mentions`, `inputs` keep their bytes, no output file appears.
void expect_bad_input(const TempDir& dir, const std::string& args,
                      const std::vector<std::string>& mentions,
                      const std::vector<std::string>& inputs = {}) {
  std::vector<std::string> before;
  for (const auto& in : inputs) before.push_back(bloomref::test::read_bytes(dir / in));
  const auto listing = dir.listing();
  const CliResult r = run_cli(args, "", dir.path());
  INFO("bloomref " << args << "\nstderr: " << r.err);
  CHECK(r.code < 128);  // no crash
  CHECK(r.code == 2);
  for (const auto& m : mentions) CHECK(r.err.find(m) != std::string::npos);
  CHECK(r.err.find("internal error") == std::string::npos);
  for (std::size_t i = 0; i < inputs.size(); ++i)
    CHECK(bloomref::test::read_bytes(dir / inputs[i]) == before[i]);
  CHECK(dir.listing() == listing);  // no output, no temporary file
}

std::string shell_quoted(const std::string& s) { return "'" + s + "'"; }

/// Reads an EXR's RGBA as float with OpenEXR (independent of the code under test).
std::vector<float> read_exr_rgba(const std::string& path, Imath::Box2i& dw) {
  Imf::InputFile file(path.c_str());
  dw = file.header().dataWindow();
  const long w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  std::vector<float> px(std::size_t(w) * h * 4);
  Imf::FrameBuffer fb;
  const char* names[] = {"R", "G", "B", "A"};
  for (int c = 0; c < 4; ++c)
    fb.insert(names[c], Imf::Slice::Make(Imf::FLOAT, px.data() + c, dw, 16, 16 * w));
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return px;
}

}  // namespace

TEST_CASE("bloomref run refuses bad input with exit code 2", "[cli]") {
  TempDir dir;
  const std::string run = "run ";
  bloomref::test::write_test_exr(dir / "in.exr", 16, 16, {"R", "G", "B"},
                                 std::vector<float>(256, 2.0f), Imf::ZIP_COMPRESSION);

  SECTION("missing file") {
    expect_bad_input(dir, run + "missing.exr -o out.exr", {"missing.exr", "no such file"});
  }
  SECTION("empty file") {
    bloomref::test::write_bytes(dir / "empty.exr", "");
    expect_bad_input(dir, run + "empty.exr -o out.exr", {"empty.exr", "empty"}, {"empty.exr"});
  }
  SECTION("truncated EXR") {
    const std::string bytes = bloomref::test::read_bytes(dir / "in.exr");
    bloomref::test::write_bytes(dir / "cut.exr", bytes.substr(0, bytes.size() / 2));
    expect_bad_input(dir, run + "cut.exr -o out.exr", {"cut.exr"}, {"cut.exr"});
  }
  SECTION("truncated PNG") {
    // Read through OpenImageIO's PNG reader, whose error path leaks libpng's buffers (under
    // LeakSanitizer the process then fails unless scripts/lsan-suppressions.txt names it).
    bloomref::save_png(dir / "whole.png", bloomref::test::constant_image(64, 64, 0.5f).cview());
    const std::string bytes = bloomref::test::read_bytes(dir / "whole.png");
    bloomref::test::write_bytes(dir / "cut.png", bytes.substr(0, bytes.size() / 2));
    std::filesystem::remove(dir / "whole.png");
    expect_bad_input(dir, run + "cut.png -o out.exr", {"cut.png"}, {"cut.png"});
  }
  SECTION("an output without an extension (/dev/null) says so") {
    expect_bad_input(dir, run + "in.exr -o /dev/null", {"/dev/null", "has no extension", ".exr or .png"});
  }
  SECTION("a text file named .exr") {
    bloomref::test::write_bytes(dir / "notes.exr", "not an image, just text\n");
    expect_bad_input(dir, run + "notes.exr -o out.exr", {"notes.exr", "not an OpenEXR file"},
                     {"notes.exr"});
  }
  SECTION("a text file named .hdr") {
    bloomref::test::write_bytes(dir / "notes.hdr", "not an image, just text\n");
    expect_bad_input(dir, run + "notes.hdr -o out.exr", {"notes.hdr"}, {"notes.hdr"});
  }
  SECTION("a header claiming 100000x100000") {
    bloomref::test::write_forged_window_exr(dir / "huge.exr", 99999, 99999);
    expect_bad_input(dir, run + "huge.exr -o out.exr", {"huge.exr", "100000x100000", "limit"},
                     {"huge.exr"});
  }
  SECTION("a header within the limits that the file cannot hold (60000x2000 in 400 bytes)") {
    bloomref::test::write_forged_window_exr(dir / "forged.exr", 59999, 1999);
    expect_bad_input(dir, run + "forged.exr -o out.exr", {"forged.exr", "truncated"},
                     {"forged.exr"});
  }
  SECTION("an unsupported channel layout (only Z)") {
    bloomref::test::write_test_exr(dir / "depth.exr", 4, 4, {"Z"}, std::vector<float>(16, 3.0f));
    expect_bad_input(dir, run + "depth.exr -o out.exr", {"depth.exr", "channel", "Z"},
                     {"depth.exr"});
  }
  SECTION("output path equal to the input path") {
    fs::create_directory(dir / "sub");
    expect_bad_input(dir, run + "in.exr -o in.exr", {"in.exr", "input"}, {"in.exr"});
    expect_bad_input(dir, run + "in.exr -o ./sub/../in.exr", {"in.exr", "input"}, {"in.exr"});
    expect_bad_input(dir, run + "./sub/../in.exr -o in.exr", {"in.exr", "input"}, {"in.exr"});
    expect_bad_input(dir, run + "in.exr -o " + shell_quoted(dir / "in.exr"), {"in.exr", "input"},
                     {"in.exr"});
    expect_bad_input(dir, run + "in.exr -o out.exr --json in.exr", {"in.exr", "input"},
                     {"in.exr"});
  }
  SECTION("unknown option values") {
    expect_bad_input(dir, run + "in.exr -o out.exr --kernel foo", {"kernel", "foo"}, {"in.exr"});
    expect_bad_input(dir, run + "in.exr -o out.exr --nonfinite maybe", {"maybe"}, {"in.exr"});
    expect_bad_input(dir, run + "in.exr -o out.tif", {"out.tif"}, {"in.exr"});
  }
  SECTION("--nonfinite error on a file holding NaN") {
    std::vector<float> v(16, 0.5f);
    v[5] = std::numeric_limits<float>::quiet_NaN();
    bloomref::test::write_test_exr(dir / "nan.exr", 4, 4, {"R", "G", "B"}, v);
    expect_bad_input(dir, run + "nan.exr -o out.exr --nonfinite error", {"nan.exr", "NaN"},
                     {"nan.exr"});
  }
  SECTION("an output folder that does not exist") {
    const auto before = bloomref::test::read_bytes(dir / "in.exr");
    const CliResult r = run_cli(run + "in.exr -o nowhere/out.exr", "", dir.path());
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find("nowhere/out.exr") != std::string::npos);
    CHECK(bloomref::test::read_bytes(dir / "in.exr") == before);
    CHECK(dir.listing() == std::vector<std::string>{"in.exr"});
  }
}

TEST_CASE("an EXR attribute larger than its file is refused before it is allocated", "[cli]") {
  // A valid 1x1 header plus an attribute of unknown type declaring 1.9 GB: OpenEXR's C++ reader
  // allocated it whole before reading (found by scripts/fuzz exr). The command runs with its
  // address space capped at 1.5 GB (not under AddressSanitizer, whose shadow needs more), so an
  // allocation of that size would fail.
  TempDir dir;
  std::string b = "\x76\x2f\x31\x01";  // magic
  const auto i32 = [](std::int32_t v) {
    std::string s(4, '\0');
    for (int k = 0; k < 4; ++k) s[k] = char((std::uint32_t(v) >> (8 * k)) & 0xff);
    return s;
  };
  const auto f32 = [&](float v) {
    std::int32_t i;
    std::memcpy(&i, &v, 4);
    return i32(i);
  };
  const auto attr = [&](const std::string& name, const std::string& type, const std::string& v) {
    return name + '\0' + type + '\0' + i32(std::int32_t(v.size())) + v;
  };
  b += i32(2);  // version 2, single part, scanline
  // channels: "R", FLOAT (2), pLinear and reserved, x and y sampling 1; then the list's end.
  b += attr("channels", "chlist", std::string("R\0", 2) + i32(2) + std::string(4, '\0') + i32(1) +
                                      i32(1) + std::string(1, '\0'));
  b += attr("compression", "compression", std::string(1, '\0'));
  b += attr("dataWindow", "box2i", i32(0) + i32(0) + i32(0) + i32(0));
  b += attr("displayWindow", "box2i", i32(0) + i32(0) + i32(0) + i32(0));
  b += attr("lineOrder", "lineOrder", std::string(1, '\0'));
  b += attr("pixelAspectRatio", "float", f32(1.0f));
  b += attr("screenWindowCenter", "v2f", f32(0.0f) + f32(0.0f));
  b += attr("screenWindowWidth", "float", f32(1.0f));
  b += std::string("mystery\0unknownType\0", 20) + i32(1900000000) + std::string(16, '\0');
  bloomref::test::write_bytes(dir / "huge.exr", b);
#if defined(__SANITIZE_ADDRESS__)
  const std::string cap;
#else
  const std::string cap = "ulimit -v 1500000;";
#endif
  const CliResult r = run_cli("run huge.exr -o out.exr", cap, dir.path());
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find("huge.exr") != std::string::npos);
  CHECK(r.err.find("'mystery' (unknownType) declares 1900000000 bytes") != std::string::npos);
  CHECK(dir.listing() == std::vector<std::string>{"huge.exr"});
}

TEST_CASE("bloomref run refuses truncated corpus files with exit code 2", "[cli][corpus]") {
  const std::string corpus = bloomref::test::corpus_dir();
  if (corpus.empty()) {
    WARN("BLOOMREF_CORPUS is not set: skipping truncated corpus files");
    return;
  }
  TempDir dir;
  // Tiled, mip-mapped, luminance/chroma, multipart, DWAB, Radiance RLE: each reader's path.
  for (const char* name : {"GoldenGate.exr", "StageEnvLatLong.exr", "StarField.exr",
                           "multipart.0001.exr", "comp_dwab_v2.exr", "hdr-rgb-riverwalk.hdr"}) {
    const std::string bytes = bloomref::test::read_bytes((fs::path(corpus) / name).string());
    const std::string cut = std::string("cut-") + name;
    bloomref::test::write_bytes(dir / cut, bytes.substr(0, bytes.size() / 2));
    expect_bad_input(dir, "run " + cut + " -o out.exr", {cut}, {cut});
    fs::remove(dir / cut);
  }
}

TEST_CASE("bloomref run writes EXR, PNG and JSON", "[cli]") {
  TempDir dir;
  const std::string corpus = bloomref::test::corpus_dir();
  std::string in;
  if (!corpus.empty()) {
    in = (fs::path(corpus) / "reference-crop.exr").string();
  } else {
    WARN("BLOOMREF_CORPUS is not set: using a written EXR instead of a corpus file");
    in = dir / "in.exr";
    bloomref::test::write_test_exr(in, 16, 16, {"R", "G", "B"}, std::vector<float>(256, 2.0f));
  }
  const std::string before = bloomref::test::read_bytes(in);
  const CliResult r =
      run_cli("run " + shell_quoted(in) + " -o out.exr -o out.png --json out.json", "", dir.path());
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(bloomref::test::read_bytes(in) == before);
  Imath::Box2i dw;
  const auto px = read_exr_rgba(dir / "out.exr", dw);
  CHECK(dw.max.x - dw.min.x + 1 == (corpus.empty() ? 16 : 160));
  CHECK(dw.max.y - dw.min.y + 1 == (corpus.empty() ? 16 : 160));
  CHECK(bloomref::test::read_bytes(dir / "out.png").substr(0, 8) == "\x89PNG\r\n\x1a\n");
  const auto j = nlohmann::json::parse(bloomref::test::read_bytes(dir / "out.json"));
  CHECK(j.contains("params"));
  CHECK(j.contains("renderer"));
  CHECK(j["timings_ms"].contains("total"));
  CHECK(j.contains("skipped"));
}

TEST_CASE("bloomref run --json says whether the adaptive plan took the scene as dense or small",
          "[cli]") {
  TempDir dir;
  // 480x270: beyond a small scene (256x256), dense at threshold 0.05; 200x120: small.
  struct Case {
    const char* size;
    const char* threshold;
    bool dense, small;
  };
  for (const Case& c : {Case{"480x270", "1", false, false}, Case{"480x270", "0.05", true, false},
                        Case{"200x120", "1", false, true}}) {
    const std::string json = std::string("t") + c.size + "_" + c.threshold + ".json";
    const CliResult r = run_cli(std::string("run --size ") + c.size + " -q -o out.exr --threshold " +
                                    c.threshold + " --json " + json,
                                "", dir.path());
    REQUIRE(r.code == 0);
    const auto j = nlohmann::json::parse(bloomref::test::read_bytes(dir / json));
    INFO(c.size << " threshold " << c.threshold);
    CHECK(j["dense_scene"].get<bool>() == c.dense);
    CHECK(j["small_scene"].get<bool>() == c.small);
    // Blurred whole (dense or small): no texel of blur.1 left out; tracked: most of them.
    const double left_out = j["skipped_texel_fraction"]["blur.1"].get<double>();
    if (c.dense || c.small) CHECK(left_out == 0.0);
    else CHECK(left_out > 0.5);
  }
}

TEST_CASE("bloomref run --repeat times later runs in the same process, same bits", "[cli]") {
  TempDir dir;
  // 64x48 with a bright block: the blur runs (the adaptive plan's masked passes).
  std::vector<float> px(64 * 48 * 3, 0.25f);
  for (int y = 20; y < 24; ++y)
    for (int x = 30; x < 34; ++x)
      for (int c = 0; c < 3; ++c) px[(std::size_t(y) * 64 + x) * 3 + c] = 6.0f;
  bloomref::test::write_test_exr(dir / "in.exr", 64, 48, {"R", "G", "B"}, px);
  const CliResult once = run_cli("run in.exr -o once.exr", "", dir.path());
  REQUIRE(once.code == 0);
  const CliResult r = run_cli("run in.exr -o rep.exr --repeat 4 --json rep.json", "", dir.path());
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("first of 4 runs") != std::string::npos);
  // The output written is the first run's, the bytes a single run writes.
  CHECK(bloomref::test::read_bytes(dir / "rep.exr") == bloomref::test::read_bytes(dir / "once.exr"));
  const auto j = nlohmann::json::parse(bloomref::test::read_bytes(dir / "rep.json"));
  const auto& rep = j["repeat"];
  REQUIRE(rep["total_ms"].size() == 4);
  CHECK(rep["runs"] == 4);
  CHECK(rep["same_bits"] == true);
  // The first run is the one timings_ms reports; the warm median is that of runs 2-4.
  std::vector<double> t;
  for (const auto& v : rep["total_ms"]) t.push_back(v.get<double>());
  CHECK(t[0] == j["timings_ms"]["total"].get<double>());
  CHECK(rep["first_ms"].get<double>() == t[0]);
  std::vector<double> warm(t.begin() + 1, t.end());
  std::sort(warm.begin(), warm.end());
  CHECK(rep["warm_median_ms"]["total"].get<double>() == warm[1]);
  for (const auto& [name, ms] : j["timings_ms"].items()) CHECK(rep["warm_median_ms"].contains(name));
  // Bad counts and combinations are refused before any work.
  expect_bad_input(dir, "run in.exr -o x.exr --repeat 0", {"--repeat"}, {"in.exr"});
  expect_bad_input(dir, "run in.exr -o x.exr --repeat 2 --backend gl", {"--repeat", "CPU"}, {"in.exr"});
  expect_bad_input(dir, "run in.exr -o x.exr --repeat 100001", {"--repeat", "100000"}, {"in.exr"});
  expect_bad_input(dir, "run in.exr -o x.exr --repeat 2 --dump-stages d", {"--repeat", "--dump-stages"},
                   {"in.exr"});
  // A deliberate GL bug needs the GL backend and a known name, said before any work (no GL).
  expect_bad_input(dir, "run in.exr -o x.exr --inject-fault mip-level-offset",
                   {"--inject-fault", "--backend gl"}, {"in.exr"});
  expect_bad_input(dir, "run in.exr -o x.exr --backend gl --inject-fault nope",
                   {"--inject-fault", "nope", "mip-level-offset"}, {"in.exr"});
}

/// A 4x2 Radiance .hdr written through OIIO (this test links it; bloomref does not).
void write_small_hdr(const std::string& path) {
  OIIO::ImageSpec spec(4, 2, 3, OIIO::TypeDesc::FLOAT);
  std::vector<float> px(4 * 2 * 3, 0.5f);
  px[0] = 8.0f;  // one bright texel
  auto out = OIIO::ImageOutput::create(path);
  REQUIRE(out);
  REQUIRE(out->open(path, spec));
  REQUIRE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
  REQUIRE(out->close());
}

TEST_CASE("OpenImageIO is loaded only for the formats that need it", "[cli]") {
  // LD_DEBUG=libs makes the dynamic loader say on stderr which libraries it loads.
  TempDir dir;
  bloomref::test::write_test_exr(dir / "in.exr", 8, 8, {"R", "G", "B"},
                                 std::vector<float>(64, 2.0f));
  write_small_hdr(dir / "in.hdr");
  const CliResult exr = run_cli("run in.exr -o out.png -o out.exr", "LD_DEBUG=libs", dir.path());
  INFO(exr.err.substr(0, 2000));
  REQUIRE(exr.code == 0);
  CHECK(exr.err.find("libOpenImageIO") == std::string::npos);
  CHECK(exr.err.find("libbloomref_oiio") == std::string::npos);
  // The control: reading a .hdr loads the module, and through it OIIO.
  const CliResult hdr = run_cli("run in.hdr -o hdr.exr", "LD_DEBUG=libs", dir.path());
  INFO(hdr.err.substr(0, 2000));
  REQUIRE(hdr.code == 0);
  CHECK(hdr.err.find("libbloomref_oiio") != std::string::npos);
  CHECK(hdr.err.find("libOpenImageIO") != std::string::npos);
  Imath::Box2i dw;
  const auto px = read_exr_rgba(dir / "hdr.exr", dw);
  CHECK(dw.max.x - dw.min.x + 1 == 4);
  CHECK(dw.max.y - dw.min.y + 1 == 2);
}

TEST_CASE("a missing OpenImageIO module is a clear input error", "[cli]") {
  TempDir dir;
  write_small_hdr(dir / "in.hdr");
  // BLOOMREF_OIIO_MODULE, when set, is the only place the module is looked for.
  const CliResult r =
      run_cli("run in.hdr -o out.exr", "BLOOMREF_OIIO_MODULE=./nowhere.so", dir.path());
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find("in.hdr") != std::string::npos);
  CHECK(r.err.find("libbloomref_oiio.so") != std::string::npos);
  CHECK(r.err.find("nowhere.so") != std::string::npos);
  CHECK(!fs::exists(dir / "out.exr"));
  // EXR input needs no module.
  bloomref::test::write_test_exr(dir / "in.exr", 8, 8, {"R", "G", "B"},
                                 std::vector<float>(64, 2.0f));
  CHECK(run_cli("run in.exr -o out.exr", "BLOOMREF_OIIO_MODULE=./nowhere.so", dir.path()).code == 0);
}

TEST_CASE("bloomref run succeeds on every corpus image, with no NaN out", "[cli][corpus]") {
  const std::string corpus = bloomref::test::corpus_dir();
  if (corpus.empty()) {
    WARN("BLOOMREF_CORPUS is not set: skipping the corpus run");
    return;
  }
  TempDir dir;
  int files = 0;
  for (const auto& e : fs::directory_iterator(corpus)) {
    const std::string name = e.path().filename().string();
    if (name == "README.md") continue;
    ++files;
    const std::string before = bloomref::test::read_bytes(e.path().string());
    const CliResult r =
        run_cli("run " + shell_quoted(e.path().string()) + " -o out.exr -q", "", dir.path());
    INFO(name << "\nstderr: " << r.err);
    REQUIRE(r.code == 0);
    CHECK(bloomref::test::read_bytes(e.path().string()) == before);
    Imath::Box2i dw;
    const auto px = read_exr_rgba(dir / "out.exr", dw);
    std::size_t nan = 0, inf = 0;
    for (float v : px) {
      nan += std::isnan(v);
      inf += std::isinf(v);
    }
    CHECK(nan == 0);  // default policy: zero
    CHECK(inf == 0);
    if (name == "multipart.0001.exr") {  // README: part 0's data window, origin (654, 245)
      CHECK(dw.min.x == 654);
      CHECK(dw.min.y == 245);
      CHECK(dw.max.x - dw.min.x + 1 == 877);
      CHECK(dw.max.y - dw.min.y + 1 == 876);
    }
    CHECK(dir.listing() == std::vector<std::string>{"out.exr"});
    fs::remove(dir / "out.exr");
  }
  CHECK(files == 15);
}
