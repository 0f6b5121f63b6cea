// Image windows (io.h): the data window is what is bloomed; both windows are held to OpenEXR's
// limits when read (an input beyond them is refused, exit 2, the input named), and an EXR output
// keeps them. Test files are written with OpenImageIO and read back with OpenEXR, not through
// the code under test.
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <OpenImageIO/imageio.h>

#include <catch2/catch.hpp>
#include <string>
#include <vector>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "io_test_util.h"

using bloomref::test::TempDir;

namespace {

// A w x h float RGB TIFF of 0.25 with one pixel of 40 at (w/3, h/2), its data window at (x, y)
// and its display window fw x fh at (fx, fy) (OIIO writes XPosition/YPosition and its own
// full-size tags).
void write_tiff(const std::string& path, int w, int h, int x, int y, int fx, int fy, int fw,
                int fh) {
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
  spec.x = x;
  spec.y = y;
  spec.full_x = fx;
  spec.full_y = fy;
  spec.full_width = fw;
  spec.full_height = fh;
  std::vector<float> px(std::size_t(w) * h * 3, 0.25f);
  for (int c = 0; c < 3; ++c) px[(std::size_t(h / 2) * w + w / 3) * 3 + c] = 40.0f;
  auto out = OIIO::ImageOutput::create(path);
  REQUIRE(out);
  REQUIRE(out->open(path, spec));
  REQUIRE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
  REQUIRE(out->close());
}

// The same pixels in an EXR at the origin, no display window of its own.
void write_plain_exr(const std::string& path, int w, int h) {
  std::vector<float> r(std::size_t(w) * h, 0.25f);
  r[std::size_t(h / 2) * w + w / 3] = 40.0f;
  bloomref::test::write_test_exr(path, w, h, {"R", "G", "B"}, r);
}

struct Windows {
  Imath::Box2i data, display;
};
Windows exr_windows(const std::string& path) {
  Imf::InputFile f(path.c_str());
  return {f.header().dataWindow(), f.header().displayWindow()};
}

}  // namespace

TEST_CASE("an input whose windows reach beyond OpenEXR's limits is refused, the input named",
          "[io][windows]") {
  TempDir dir;
  // XPosition 2147483520: x + width - 1 overflowed an int; 1500000000 fits an int but not an
  // EXR header (corners strictly inside +-1073741823), which failed at writing, blaming the
  // output.
  for (const int x : {2147483520, 1500000000, 1073741800}) {
    INFO("x " << x);
    write_tiff(dir / "far.tif", 64, 32, x, 0, x, 0, 64, 32);
    try {
      bloomref::load_image(dir / "far.tif");
      FAIL("load_image took a window at x = " << x);
    } catch (const bloomref::InputError& e) {
      CHECK(e.file() == dir / "far.tif");
      CHECK(e.problem().find("data window") != std::string::npos);
    }
    const auto r = bloomref::test::run_cli("run far.tif -o out.exr", "", dir.path());
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.rfind("bloomref: far.tif: the data window", 0) == 0);
    CHECK(dir.listing() == std::vector<std::string>{"far.tif"});
  }
  // A data window near the limit is taken: 2^30 - 128, which TIFF's float XPosition holds
  // exactly, to 2^30 - 65.
  write_tiff(dir / "edge.tif", 64, 32, 1073741696, 0, 1073741696, 0, 64, 32);
  const auto r = bloomref::test::run_cli("run edge.tif -o out.exr -q", "", dir.path());
  INFO(r.err);
  REQUIRE(r.code == 0);
  const Windows w = exr_windows(dir / "out.exr");
  CHECK(w.data.min.x == 1073741696);
  CHECK(w.data.max.x == 1073741759);
}

TEST_CASE("the data window is bloomed, and an EXR output keeps both windows", "[io][windows]") {
  // 400x300 pixels at (30, 40) in a 501x401 display window.
  TempDir dir;
  write_tiff(dir / "t08.tif", 400, 300, 30, 40, 0, 0, 501, 401);
  write_plain_exr(dir / "plain.exr", 400, 300);
  const auto r = bloomref::test::run_cli("run t08.tif -o t08.exr -o t08.png -q", "", dir.path());
  INFO(r.err);
  REQUIRE(r.code == 0);
  const Windows w = exr_windows(dir / "t08.exr");
  CHECK(w.data.min.x == 30);
  CHECK(w.data.min.y == 40);
  CHECK(w.data.max.x == 429);
  CHECK(w.data.max.y == 339);
  CHECK(w.display.min.x == 0);
  CHECK(w.display.min.y == 0);
  CHECK(w.display.max.x == 500);
  CHECK(w.display.max.y == 400);
  // The placement changes nothing in the pixels: the same as the same pixels at the origin,
  // whose output sits at the origin.
  REQUIRE(bloomref::test::run_cli("run plain.exr -o plain.out.exr -q", "", dir.path()).code == 0);
  const Windows p = exr_windows(dir / "plain.out.exr");
  CHECK(p.data.min.x == 0);
  CHECK(p.display.max.x == 399);
  const bloomref::LoadedImage a = bloomref::load_image(dir / "t08.exr");
  const bloomref::LoadedImage b = bloomref::load_image(dir / "plain.out.exr");
  CHECK(bloomref::test::bit_identical(a.image.cview(), b.image.cview()));
  // The PNG holds the data window's pixels alone.
  auto png = OIIO::ImageInput::open(dir / "t08.png");
  REQUIRE(png);
  CHECK(png->spec().width == 400);
  CHECK(png->spec().height == 300);
}

TEST_CASE("corpus: a run on multipart.0001 keeps its data window inside its display window",
          "[io][windows][corpus]") {
  const std::string corpus = bloomref::test::corpus_dir();
  if (corpus.empty()) {
    WARN("BLOOMREF_CORPUS is not set: skipping the corpus");
    return;
  }
  // README of the corpus: part 0 is 877x876 at (654, 245) in a 2048x1556 display window.
  TempDir dir;
  const auto r = bloomref::test::run_cli(
      "run '" + corpus + "/multipart.0001.exr' -o out.exr -q", "", dir.path());
  INFO(r.err);
  REQUIRE(r.code == 0);
  const Windows w = exr_windows(dir / "out.exr");
  CHECK(w.data.min.x == 654);
  CHECK(w.data.min.y == 245);
  CHECK(w.data.max.x == 654 + 877 - 1);
  CHECK(w.data.max.y == 245 + 876 - 1);
  CHECK(w.display.min.x == 0);
  CHECK(w.display.min.y == 0);
  CHECK(w.display.max.x == 2047);
  CHECK(w.display.max.y == 1555);
}
