// I/O: every corpus image loads with the size and values its README states; EXR round trips
// are exact; PNG codes are round(clamp(x, 0, 1) * 255); writes are atomic.
//
// Expected numbers come from ../shared/data/hdr/README.md (measured there with exrheader, iinfo
// and an Imf::InputFile reader), never from the code under test. Where the README rounds a
// number, the tolerance is half its last printed digit plus the pixel type's own spacing.
#include <ImfThreading.h>
#include <OpenImageIO/imageio.h>

#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <set>

#include "bloomref/error.h"
#include "bloomref/image.h"
#include "bloomref/io.h"
#include "io_test_util.h"

using namespace bloomref;
using test::TempDir;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

struct ChannelStats {
  double min = std::numeric_limits<double>::infinity();  // over finite values
  double max = -std::numeric_limits<double>::infinity();
  std::uint64_t nan = 0, pos_inf = 0, neg_inf = 0, negative = 0, denormal = 0;
};

std::array<ChannelStats, kChannels> channel_stats(const Image& img) {
  std::array<ChannelStats, kChannels> s;
  for (std::size_t i = 0; i < img.pixel_count(); ++i)
    for (int c = 0; c < kChannels; ++c) {
      const float v = img.data()[i * kChannels + c];
      ChannelStats& cs = s[c];
      if (std::isnan(v)) { ++cs.nan; continue; }
      if (std::isinf(v)) { ++(v > 0 ? cs.pos_inf : cs.neg_inf); continue; }
      cs.min = std::min<double>(cs.min, v);
      cs.max = std::max<double>(cs.max, v);
      if (v < 0) ++cs.negative;
      if (std::fpclassify(v) == FP_SUBNORMAL) ++cs.denormal;
    }
  return s;
}

double rgb_max(const std::array<ChannelStats, kChannels>& s) {
  return std::max({s[0].max, s[1].max, s[2].max});
}
double rgb_min(const std::array<ChannelStats, kChannels>& s) {
  return std::min({s[0].min, s[1].min, s[2].min});
}

/// Pixels whose max(R, G, B) is above `level` (the README's "hot px").
std::size_t hot_pixels(const Image& img, float level) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    const float* p = img.data() + i * kChannels;
    if (std::max({p[0], p[1], p[2]}) > level) ++n;
  }
  return n;
}

bool alpha_all_one(const Image& img) {
  for (std::size_t i = 0; i < img.pixel_count(); ++i)
    if (img.data()[i * kChannels + 3] != 1.0f) return false;
  return true;
}

/// Loads a corpus file, or returns nothing (with a warning) when BLOOMREF_CORPUS is unset.
std::optional<LoadedImage> load_corpus(const std::string& name) {
  const std::string dir = test::corpus_dir();
  if (dir.empty()) {
    WARN("BLOOMREF_CORPUS is not set: skipping the corpus check of " << name);
    return std::nullopt;
  }
  return load_image((test::fs::path(dir) / name).string());
}

}  // namespace

TEST_CASE("every corpus file loads, with alpha exactly where the README says", "[io][corpus]") {
  const std::string dir = test::corpus_dir();
  if (dir.empty()) {
    WARN("BLOOMREF_CORPUS is not set: skipping the corpus");
    return;
  }
  // README, "Coverage summary": alpha in CandleGlass, comp_dwab_v2 and multipart.0001 only.
  const std::set<std::string> with_alpha = {"CandleGlass.exr", "comp_dwab_v2.exr",
                                            "multipart.0001.exr"};
  int files = 0;
  for (const auto& e : test::fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name == "README.md") continue;
    ++files;
    INFO(name);
    LoadedImage li = load_image(e.path().string());
    CHECK(li.image.width() == li.info.data_window.width());
    CHECK(li.image.height() == li.info.data_window.height());
    CHECK(li.info.has_alpha == (with_alpha.count(name) == 1));
    if (!li.info.has_alpha) CHECK(alpha_all_one(li.image));
    CHECK(li.info.format == (e.path().extension() == ".hdr" ? "hdr" : "exr"));
  }
  CHECK(files == 15);  // "There are 15 files here"
}

TEST_CASE("corpus: GoldenGate is tiled, 1262x860, R max 685.5, 31 px above 100", "[io][corpus]") {
  auto li = load_corpus("GoldenGate.exr");
  if (!li) return;
  CHECK(li->image.width() == 1262);
  CHECK(li->image.height() == 860);
  CHECK(li->info.layout.find("tiled") != std::string::npos);
  const auto s = channel_stats(li->image);
  CHECK(s[0].max == 685.5);  // exact in half
  CHECK(hot_pixels(li->image, 100) == 31);
}

TEST_CASE("corpus: multipart.0001 reads part 0 with its windows", "[io][corpus]") {
  auto li = load_corpus("multipart.0001.exr");
  if (!li) return;
  CHECK(li->image.width() == 877);
  CHECK(li->image.height() == 876);
  const Window& d = li->info.data_window;
  CHECK(d.x0 == 654);
  CHECK(d.y0 == 245);
  CHECK(d.width() == 877);
  CHECK(d.height() == 876);
  const Window& v = li->info.display_window;
  CHECK(v.x0 == 0);
  CHECK(v.y0 == 0);
  CHECK(v.width() == 2048);
  CHECK(v.height() == 1556);
  CHECK(li->info.has_alpha);
  CHECK(li->info.layout.find("part 0") != std::string::npos);
  // "Part 0 is RGBA in [0, 0.5]": true of RGB; its alpha reaches 1 (oiiotool --stats: A max
  // 1.0), so alpha is only checked to lie in [0, 1].
  const auto s = channel_stats(li->image);
  for (int c = 0; c < 4; ++c) {
    INFO("channel " << c);
    CHECK(s[c].nan + s[c].pos_inf + s[c].neg_inf == 0);
    CHECK(s[c].min >= 0.0);
    CHECK(s[c].max <= (c < 3 ? 0.5 : 1.0));
  }
  CHECK(rgb_max(s) > 0.0);  // not an all-black fill
}

TEST_CASE("corpus: StarField luminance/chroma reconstructs to RGB", "[io][corpus]") {
  auto li = load_corpus("StarField.exr");
  if (!li) return;
  CHECK(li->image.width() == 1000);
  CHECK(li->image.height() == 1000);
  const auto s = channel_stats(li->image);
  // "R/G/B max are 805/1349/1888": 1 % covers the rounding and half spacing (1 at 1024-2048).
  CHECK(s[0].max == Approx(805).epsilon(0.01));
  CHECK(s[1].max == Approx(1349).epsilon(0.01));
  CHECK(s[2].max == Approx(1888).epsilon(0.01));
  CHECK(s[0].nan + s[1].nan + s[2].nan == 0);
}

TEST_CASE("corpus: WideFloatRange's single G channel is read as float grey", "[io][corpus]") {
  auto li = load_corpus("WideFloatRange.exr");
  if (!li) return;
  const Image& img = li->image;
  CHECK(img.width() == 500);
  CHECK(img.height() == 500);
  bool grey = true;
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    const float* p = img.data() + i * kChannels;
    grey = grey && std::memcmp(&p[0], &p[1], 4) == 0 && std::memcmp(&p[0], &p[2], 4) == 0;
  }
  CHECK(grey);
  const auto s = channel_stats(img);
  // "values from -1.70e38 to +1.70e38": float32 kept as float (half would be +-Inf).
  CHECK(s[1].max == Approx(1.70e38).epsilon(0.005));
  CHECK(s[1].min == Approx(-1.70e38).epsilon(0.005));
  CHECK(s[1].pos_inf + s[1].neg_inf + s[1].nan == 0);
  // "half of the pixels are negative"
  CHECK(s[1].negative > img.pixel_count() * 45 / 100);
  CHECK(s[1].negative < img.pixel_count() * 55 / 100);
}

TEST_CASE("corpus: BrightRingsNanInf keeps 2 NaN, 2 +Inf, 2 -Inf per channel", "[io][corpus]") {
  auto li = load_corpus("BrightRingsNanInf.exr");
  if (!li) return;
  CHECK(li->image.width() == 800);
  CHECK(li->image.height() == 800);
  const auto s = channel_stats(li->image);
  for (int c = 0; c < 3; ++c) {
    INFO("channel " << c);
    CHECK(s[c].nan == 2);
    CHECK(s[c].pos_inf == 2);
    CHECK(s[c].neg_inf == 2);
  }
  CHECK(rgb_max(s) == Approx(1025).epsilon(0.001));  // "values up to 1025"
  CHECK(hot_pixels(li->image, 100) == 60648);
}

TEST_CASE("corpus: AllHalfValues holds every half bit pattern", "[io][corpus]") {
  auto li = load_corpus("AllHalfValues.exr");
  if (!li) return;
  CHECK(li->image.width() == 256);
  CHECK(li->image.height() == 256);
  const auto s = channel_stats(li->image);
  for (int c = 0; c < 3; ++c) {
    INFO("channel " << c);
    CHECK(s[c].max == 65504.0);
    CHECK(s[c].min == -65504.0);
    CHECK(s[c].nan == 2046);
    CHECK(s[c].pos_inf == 1);
    CHECK(s[c].neg_inf == 1);
    CHECK(s[c].negative == 31743);
    // Half denormals are normal floats; the README's 2,046 counts half denormals: values
    // with 0 < |v| < 2^-14.
  }
  std::size_t half_denormals = 0;
  for (std::size_t i = 0; i < li->image.pixel_count(); ++i) {
    const float v = li->image.data()[i * kChannels];
    if (v != 0 && std::fabs(v) < 6.103515625e-05f) ++half_denormals;
  }
  CHECK(half_denormals == 2046);
}

TEST_CASE("corpus: WideColorGamut has negative RGB", "[io][corpus]") {
  auto li = load_corpus("WideColorGamut.exr");
  if (!li) return;
  CHECK(li->image.width() == 800);
  CHECK(li->image.height() == 800);
  const auto s = channel_stats(li->image);
  CHECK(s[0].min == Approx(-1.30).margin(0.006));
  CHECK(s[1].min == Approx(-0.81).margin(0.006));
  CHECK(s[2].min == Approx(-0.08).margin(0.006));
  CHECK(rgb_max(s) == Approx(21.4).margin(0.06));
  CHECK(s[0].negative == Approx(79000).margin(500));  // "79k px have R < 0"
}

TEST_CASE("corpus: CandleGlass keeps RGB where alpha is 0", "[io][corpus]") {
  auto li = load_corpus("CandleGlass.exr");
  if (!li) return;
  const Image& img = li->image;
  CHECK(img.width() == 1000);
  CHECK(img.height() == 810);
  CHECK(li->info.has_alpha);
  std::size_t zero_alpha_bright = 0;
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    const float* p = img.data() + i * kChannels;
    if (p[3] == 0.0f && std::max({p[0], p[1], p[2]}) > 1.0f) ++zero_alpha_bright;
  }
  CHECK(zero_alpha_bright == 1315);  // "1,315 px have A = 0 and RGB > 1"
  const auto s = channel_stats(img);
  CHECK(s[0].max == Approx(413).margin(0.5));  // "R max 413"; half spacing 0.25 there
  CHECK(hot_pixels(img, 100) == 347);
  CHECK(rgb_min(s) == Approx(-3.4e-4).margin(0.06e-4));
}

TEST_CASE("corpus: StageEnvLatLong reads mip level 0", "[io][corpus]") {
  auto li = load_corpus("StageEnvLatLong.exr");
  if (!li) return;
  CHECK(li->image.width() == 1000);
  CHECK(li->image.height() == 500);
  CHECK(li->info.layout.find("level 0") != std::string::npos);
  const auto s = channel_stats(li->image);
  CHECK(rgb_max(s) == 4096.0);
  CHECK(hot_pixels(li->image, 1000) == 166);
}

TEST_CASE("corpus: comp_dwab_v2 (DWAB, RGBA)", "[io][corpus]") {
  auto li = load_corpus("comp_dwab_v2.exr");
  if (!li) return;
  CHECK(li->image.width() == 587);
  CHECK(li->image.height() == 675);
  const auto s = channel_stats(li->image);
  CHECK(s[2].max == Approx(501.5).margin(0.25));
  CHECK(s[1].min == Approx(-0.0024).margin(0.00006));
  CHECK(hot_pixels(li->image, 100) == 20706);
}

TEST_CASE("corpus: reference-crop fireflies", "[io][corpus]") {
  auto li = load_corpus("reference-crop.exr");
  if (!li) return;
  CHECK(li->image.width() == 160);
  CHECK(li->image.height() == 160);
  CHECK(rgb_max(channel_stats(li->image)) == Approx(12632).margin(4));
}

TEST_CASE("corpus: uffizi_probe-128 has negatives down to -1", "[io][corpus]") {
  auto li = load_corpus("uffizi_probe-128.exr");
  if (!li) return;
  CHECK(li->image.width() == 128);
  CHECK(li->image.height() == 128);
  const auto s = channel_stats(li->image);
  CHECK(rgb_max(s) == Approx(16.7).margin(0.06));
  CHECK(rgb_min(s) == Approx(-1.0).margin(0.06));
  const auto negative = s[0].negative + s[1].negative + s[2].negative;
  // "2.7k samples" (2,7xx).
  CHECK(negative >= 2700);
  CHECK(negative < 2800);
}

TEST_CASE("corpus: hdr-rgb-riverwalk (Radiance RLE)", "[io][corpus]") {
  auto li = load_corpus("hdr-rgb-riverwalk.hdr");
  if (!li) return;
  CHECK(li->info.format == "hdr");
  CHECK(li->image.width() == 768);
  CHECK(li->image.height() == 768);
  CHECK(rgb_max(channel_stats(li->image)) == Approx(84.5).margin(0.3));
  CHECK(hot_pixels(li->image, 10) == 31444);
}

TEST_CASE("corpus: scale.hdr (flat RGBE, 256x8, up to 1.69e38)", "[io][corpus]") {
  auto li = load_corpus("scale.hdr");
  if (!li) return;
  CHECK(li->image.width() == 256);
  CHECK(li->image.height() == 8);
  const auto s = channel_stats(li->image);
  CHECK(rgb_max(s) == Approx(1.69e38).epsilon(0.005));
  CHECK(rgb_min(s) == 0.0);
  CHECK(s[0].pos_inf + s[1].pos_inf + s[2].pos_inf == 0);
  CHECK(hot_pixels(li->image, 1000) == 940);
}

TEST_CASE("corpus: HDR-A-1x1", "[io][corpus]") {
  auto li = load_corpus("HDR-A-1x1.exr");
  if (!li) return;
  REQUIRE(li->image.width() == 1);
  REQUIRE(li->image.height() == 1);
  const float* p = li->image.pixel(0, 0);
  // "RGB 1.63/1.84/2.13": two decimals, half spacing 2^-9 or 2^-10 there.
  CHECK(p[0] == Approx(1.63).margin(0.007));
  CHECK(p[1] == Approx(1.84).margin(0.007));
  CHECK(p[2] == Approx(2.13).margin(0.007));
  CHECK(p[3] == 1.0f);
}

TEST_CASE("size limits are checked from the header, naming the limit", "[io]") {
  SizeLimits lim;
  CHECK_THROWS_WITH(check_size("a.exr", 65537, 1, lim),
                    Catch::Contains("a.exr") && Catch::Contains("limit"));
  CHECK_THROWS_WITH(check_size("a.exr", 65536, 65536, lim), Catch::Contains("limit"));
  CHECK_THROWS_WITH(check_size("a.exr", 0, 5, lim), Catch::Contains("empty"));
  CHECK_NOTHROW(check_size("a.exr", 65536, 2048, lim));

  TempDir dir;
  const std::string exr = dir / "small.exr";
  test::write_test_exr(exr, 40, 30, {"R", "G", "B"}, std::vector<float>(40 * 30, 0.5f));
  SizeLimits tight;
  tight.max_side = 32;
  CHECK_THROWS_AS(load_image(exr, tight), InputError);
  CHECK_THROWS_WITH(load_image(exr, tight), Catch::Contains("small.exr") && Catch::Contains("40x30"));
  tight.max_side = 64;
  tight.max_pixels = 1000;
  CHECK_THROWS_WITH(load_image(exr, tight), Catch::Contains("limit"));

  // Headers are checked before OpenEXR reads offset tables or anything is allocated.
  const std::string huge = dir / "huge.exr";
  test::write_forged_window_exr(huge, 99999, 99999);
  CHECK_THROWS_WITH(load_image(huge), Catch::Contains("huge.exr") &&
                                          Catch::Contains("100000x100000") &&
                                          Catch::Contains("limit"));
  const std::string forged = dir / "forged.exr";
  test::write_forged_window_exr(forged, 59999, 1999);  // within the limits, not within the file
  CHECK_THROWS_WITH(load_image(forged), Catch::Contains("forged.exr") &&
                                            Catch::Contains("truncated"));
  // The same for Radiance: the header alone says 100000x100000.
  const std::string hdr = dir / "huge.hdr";
  test::write_bytes(hdr, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\nxxxx");
  CHECK_THROWS_WITH(load_image(hdr), Catch::Contains("huge.hdr") && Catch::Contains("limit"));
}

TEST_CASE("EXR reading and writing give the same bits on any number of threads", "[io][corpus]") {
  // OpenEXR decompresses and compresses chunks on its own pool (set_io_threads); chunks are
  // independent, so the pixels read and the bytes written must not depend on the count. The
  // written file (PIZ) must also read back bit for bit, NaN payloads included.
  const std::string dir = test::corpus_dir();
  if (dir.empty()) {
    WARN("BLOOMREF_CORPUS is not set: skipping the corpus");
    return;
  }
  TempDir tmp;
  int files = 0;
  for (const auto& e : test::fs::directory_iterator(dir)) {
    if (e.path().extension() != ".exr") continue;
    ++files;
    INFO(e.path().filename().string());
    set_io_threads(1);
    const LoadedImage one = load_image(e.path().string());
    save_exr(tmp / "one.exr", one.image.cview(), &one.info);
    set_io_threads(3);
    const LoadedImage three = load_image(e.path().string());
    CHECK(Imf::globalThreadCount() == 3);  // the reader did run on OpenEXR's pool of 3
    save_exr(tmp / "three.exr", three.image.cview(), &three.info);
    const std::size_t bytes = one.image.pixel_count() * kChannels * sizeof(float);
    REQUIRE(three.image.pixel_count() == one.image.pixel_count());
    CHECK(std::memcmp(one.image.data(), three.image.data(), bytes) == 0);
    CHECK(test::read_bytes(tmp / "one.exr") == test::read_bytes(tmp / "three.exr"));
    const LoadedImage back = load_image(tmp / "three.exr");
    REQUIRE(back.image.pixel_count() == one.image.pixel_count());
    CHECK(std::memcmp(back.image.data(), one.image.data(), bytes) == 0);
  }
  set_io_threads(0);
  CHECK(files == 13);  // the corpus README's 13 EXR files
}

TEST_CASE("save_exr / load_image round trip is exact and keeps the windows", "[io]") {
  const float denorm = std::numeric_limits<float>::denorm_min();
  const float values[] = {-1.5f,   0.0f,     -0.0f,        denorm,   -denorm,  1e-40f,
                          3.4e38f, -3.4e38f, 1.70141e38f,  65504.0f, 65520.0f, 1.0f / 3.0f,
                          kInf,    -kInf,    1e-30f,       -7.25f,   0.1f,     2.0e-38f,
                          123456.789f, -1e-45f, 0.5f,      1.0f,     4096.0f,  -65536.0f};
  constexpr int w = 3, h = 2;
  Image img(w, h);
  static_assert(sizeof(values) / sizeof(float) == w * h * kChannels);
  std::memcpy(img.data(), values, sizeof(values));

  ImageInfo windows;
  windows.data_window = {5, 7, 5 + w - 1, 7 + h - 1};
  windows.display_window = {0, 0, 19, 9};
  TempDir dir;
  const std::string path = dir / "round.exr";
  save_exr(path, img.cview(), &windows);
  const LoadedImage back = load_image(path);
  REQUIRE(back.image.width() == w);
  REQUIRE(back.image.height() == h);
  CHECK(std::memcmp(back.image.data(), img.data(), sizeof(values)) == 0);
  CHECK(back.info.has_alpha);
  CHECK(back.info.data_window.x0 == 5);
  CHECK(back.info.data_window.y0 == 7);
  CHECK(back.info.data_window.x1 == 7);
  CHECK(back.info.data_window.y1 == 8);
  CHECK(back.info.display_window.x0 == 0);
  CHECK(back.info.display_window.y0 == 0);
  CHECK(back.info.display_window.x1 == 19);
  CHECK(back.info.display_window.y1 == 9);

  SECTION("every compression save_exr offers keeps the bits, and is the one the file names") {
    const std::pair<const char*, const char*> kinds[] = {
        {"none", "none"}, {"rle", "rle"}, {"zips", "zips"}, {"zip", "zip"}, {"piz", "piz"}};
    for (const auto& [option, oiio_name] : kinds) {
      INFO(option);
      save_exr(path, img.cview(), &windows, parse_exr_compression(option, "--dump-compression"));
      auto in = OIIO::ImageInput::open(path);
      REQUIRE(in);
      CHECK(in->spec().get_string_attribute("compression") == oiio_name);
      in->close();
      const LoadedImage b = load_image(path);
      CHECK(std::memcmp(b.image.data(), img.data(), sizeof(values)) == 0);
    }
    CHECK_THROWS_WITH(parse_exr_compression("b44", "--dump-compression"),
                      Catch::Contains("--dump-compression 'b44'") && Catch::Contains("none, rle, zips, zip, piz"));
  }
  SECTION("NaN survives too") {
    Image nan_img(1, 1, kNaN);
    save_exr(path, nan_img.cview());
    const LoadedImage b = load_image(path);
    for (int c = 0; c < 4; ++c) CHECK(std::isnan(b.image.data()[c]));
    CHECK(b.info.data_window.x0 == 0);
    CHECK(b.info.data_window.y0 == 0);
  }
  SECTION("a view with a row stride wider than its width") {
    Image wide(5, 2);
    for (std::size_t i = 0; i < wide.values().size(); ++i) wide.values()[i] = float(i);
    ConstImageView v{3, 2, 5, wide.data()};
    save_exr(path, v);
    const LoadedImage b = load_image(path);
    REQUIRE(b.image.width() == 3);
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 3; ++x)
        for (int c = 0; c < 4; ++c) CHECK(b.image.pixel(x, y)[c] == v.pixel(x, y)[c]);
  }
}

namespace {

/// Reads an 8-bit PNG with OIIO, its codes exactly as stored (no alpha association).
std::vector<unsigned char> read_png_codes(const std::string& path, int& w, int& h, int& nch) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path, &config);
  REQUIRE(in);
  const OIIO::ImageSpec& spec = in->spec();
  CHECK(in->format_name() == std::string("png"));
  CHECK(spec.format == OIIO::TypeDesc::UINT8);
  w = spec.width;
  h = spec.height;
  nch = spec.nchannels;
  std::vector<unsigned char> px(std::size_t(w) * h * nch);
  REQUIRE(in->read_image(0, 0, 0, nch, OIIO::TypeDesc::UINT8, px.data()));
  return px;
}

}  // namespace

TEST_CASE("save_png stores round(clamp(x, 0, 1) * 255) as opaque RGB", "[io]") {
  // Codes worked out by hand: 0.5/255 * 255 = 0.5 -> 1 (the float nearest 0.5/255 is just
  // above it); 0.5 * 255 = 127.5 -> 128; NaN -> 0 (io.h, stages.h).
  const float xs[] = {-1.0f, 0.0f, 0.5f / 255.0f, 0.5f, 1.0f, 2.0f, kNaN};
  const unsigned char codes[] = {0, 0, 1, 128, 255, 255, 0};
  constexpr int n = 7;
  // Row 0: RGB = x, A = 1. Row 1: RGB = 0.25 (code 64 = round(63.75)), A = x: the colour codes
  // must not depend on alpha, and alpha is not written (io.h: the PNG is opaque RGB).
  Image img(n, 2);
  for (int i = 0; i < n; ++i) {
    float* p = img.pixel(i, 0);
    p[0] = p[1] = p[2] = xs[i];
    p[3] = 1.0f;
    float* q = img.pixel(i, 1);
    q[0] = q[1] = q[2] = 0.25f;
    q[3] = xs[i];
  }
  TempDir dir;
  const std::string path = dir / "codes.png";
  save_png(path, img.cview());
  int w = 0, h = 0, nch = 0;
  const auto px = read_png_codes(path, w, h, nch);
  REQUIRE(w == n);
  REQUIRE(h == 2);
  REQUIRE(nch == 3);
  for (int i = 0; i < n; ++i) {
    INFO("x = " << xs[i]);
    const unsigned char* p = &px[std::size_t(i) * 3];
    CHECK(int(p[0]) == codes[i]);
    CHECK(int(p[1]) == codes[i]);
    CHECK(int(p[2]) == codes[i]);
    const unsigned char* q = &px[std::size_t(n + i) * 3];
    CHECK(int(q[0]) == 64);
    CHECK(int(q[1]) == 64);
    CHECK(int(q[2]) == 64);
  }
  CHECK(dir.listing() == std::vector<std::string>{"codes.png"});
}

TEST_CASE("save_image picks the writer by extension, case-insensitively", "[io]") {
  TempDir dir;
  Image img(2, 2, 0.5f);
  save_image(dir / "a.EXR", img.cview());
  save_image(dir / "b.Png", img.cview());
  CHECK(test::read_bytes(dir / "a.EXR").substr(0, 4) == std::string("\x76\x2f\x31\x01", 4));
  CHECK(test::read_bytes(dir / "b.Png").substr(1, 3) == "PNG");
  CHECK_THROWS_WITH(save_image(dir / "c.tif", img.cview()),
                    Catch::Contains("c.tif") && Catch::Contains(".tif"));
  CHECK(dir.listing() == std::vector<std::string>{"a.EXR", "b.Png"});
}

TEST_CASE("writes are atomic: a failure leaves nothing behind and nothing changed", "[io]") {
  TempDir dir;
  Image img(4, 3, 0.25f);

  SECTION("a folder that does not exist") {
    for (const char* name : {"missing/out.exr", "missing/out.png", "missing/out.json"}) {
      INFO(name);
      const std::string path = dir / name;
      if (std::string(name).find(".json") != std::string::npos)
        CHECK_THROWS_AS(save_text(path, "{}"), InputError);
      else
        CHECK_THROWS_AS(save_image(path, img.cview()), InputError);
      CHECK_THROWS_WITH(save_image(dir / "missing/out.exr", img.cview()),
                        Catch::Contains("missing/out.exr") && Catch::Contains("folder"));
    }
    CHECK(dir.listing().empty());
  }

  SECTION("a failed write keeps the existing file's bytes") {
    const std::string exr = dir / "keep.exr", png = dir / "keep.png", txt = dir / "keep.json";
    save_exr(exr, img.cview());
    save_png(png, img.cview());
    save_text(txt, "{\"old\": true}\n");
    const std::string exr_bytes = test::read_bytes(exr), png_bytes = test::read_bytes(png);
    const auto before = dir.listing();

    Image empty;  // 0x0: nothing valid can be written
    CHECK_THROWS_AS(save_exr(exr, empty.cview()), InputError);
    CHECK_THROWS_AS(save_png(png, empty.cview()), InputError);
    CHECK_THROWS_WITH(save_exr(exr, empty.cview()),
                      Catch::Contains("keep.exr") && Catch::Contains("empty"));
    // Fails inside the writer, after the temporary file exists: libpng refuses widths above
    // its default user limit of 1,000,000. The message names the destination, not the
    // temporary.
    Image too_wide(1000001, 1, 0.5f);
    CHECK_THROWS_WITH(save_png(png, too_wide.cview()),
                      Catch::Contains("keep.png") && !Catch::Contains(".tmp-"));
    // The target is a folder.
    test::fs::create_directory(dir / "sub.exr");
    CHECK_THROWS_AS(save_exr(dir / "sub.exr", img.cview()), InputError);
    test::fs::remove(dir / "sub.exr");

    CHECK(test::read_bytes(exr) == exr_bytes);
    CHECK(test::read_bytes(png) == png_bytes);
    CHECK(test::read_bytes(txt) == "{\"old\": true}\n");
    CHECK(dir.listing() == before);  // no temporary file left
  }

  SECTION("a successful write replaces the file and leaves no temporary") {
    const std::string exr = dir / "out.exr";
    save_exr(exr, img.cview());
    Image other(2, 2, 7.0f);
    save_exr(exr, other.cview());
    const LoadedImage back = load_image(exr);
    CHECK(back.image.width() == 2);
    CHECK(back.image.pixel(1, 1)[0] == 7.0f);
    CHECK(dir.listing() == std::vector<std::string>{"out.exr"});
  }
}

TEST_CASE("load_image refuses bad files with the file name and the problem", "[io]") {
  TempDir dir;
  CHECK_THROWS_WITH(load_image(dir / "nope.exr"),
                    Catch::Contains("nope.exr") && Catch::Contains("no such file"));
  test::write_bytes(dir / "empty.exr", "");
  CHECK_THROWS_WITH(load_image(dir / "empty.exr"),
                    Catch::Contains("empty.exr") && Catch::Contains("empty"));
  test::write_bytes(dir / "text.exr", "this is not an image\n");
  CHECK_THROWS_WITH(load_image(dir / "text.exr"),
                    Catch::Contains("text.exr") && Catch::Contains("OpenEXR"));
  test::write_bytes(dir / "text.hdr", "this is not an image\n");
  CHECK_THROWS_AS(load_image(dir / "text.hdr"), InputError);
  CHECK_THROWS_WITH(load_image(dir.path().string()), Catch::Contains("folder"));

  const std::string z = dir / "depth.exr";
  test::write_test_exr(z, 4, 4, {"Z"}, std::vector<float>(16, 1.0f));
  CHECK_THROWS_WITH(load_image(z), Catch::Contains("depth.exr") && Catch::Contains("channel") &&
                                       Catch::Contains("Z"));

  const std::string full = dir / "full.exr";
  test::write_test_exr(full, 64, 64, {"R", "G", "B"}, std::vector<float>(64 * 64, 2.0f),
                       Imf::ZIP_COMPRESSION);
  const std::string bytes = test::read_bytes(full);
  const std::string cut = dir / "cut.exr";
  test::write_bytes(cut, bytes.substr(0, bytes.size() / 2));
  CHECK_THROWS_AS(load_image(cut), InputError);
  CHECK_THROWS_WITH(load_image(cut), Catch::Contains("cut.exr"));
  // Only the magic number and a few header bytes.
  test::write_bytes(cut, bytes.substr(0, 12));
  CHECK_THROWS_AS(load_image(cut), InputError);
}

TEST_CASE("a single R or Y channel reads as grey, R and B without G give G = 0", "[io]") {
  TempDir dir;
  const std::vector<float> v = {0.5f, 2.0f, -1.0f, 8.0f};
  const std::string y = dir / "y.exr";
  test::write_test_exr(y, 2, 2, {"Y"}, v);
  LoadedImage li = load_image(y);
  for (int i = 0; i < 4; ++i) {
    const float* p = li.image.data() + i * kChannels;
    CHECK(p[0] == v[i]);
    CHECK(p[1] == v[i]);
    CHECK(p[2] == v[i]);
    CHECK(p[3] == 1.0f);
  }
  const std::string rb = dir / "rb.exr";
  test::write_test_exr(rb, 2, 2, {"R", "B"}, v);
  li = load_image(rb);
  for (int i = 0; i < 4; ++i) {
    const float* p = li.image.data() + i * kChannels;
    CHECK(p[0] == v[i]);
    CHECK(p[1] == 0.0f);
    CHECK(p[2] == v[i]);
  }
}

namespace {

/// Writes a float TIFF through OIIO with the given channel names; pixel values are
/// 0.1 * (channel + 1) everywhere, so each channel is recognisable.
void write_tiff(const std::string& path, const std::vector<std::string>& names, int alpha = -1) {
  const int nch = static_cast<int>(names.size());
  OIIO::ImageSpec spec(2, 2, nch, OIIO::TypeDesc::FLOAT);
  spec.channelnames = names;
  spec.alpha_channel = alpha;
  std::vector<float> px(4 * nch);
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < nch; ++c) px[i * nch + c] = 0.1f * (c + 1);
  auto out = OIIO::ImageOutput::create(path);
  REQUIRE(out);
  REQUIRE(out->open(path, spec));
  REQUIRE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
  REQUIRE(out->close());
}

}  // namespace

TEST_CASE("OIIO formats: channels are taken by name, as for EXR", "[io]") {
  TempDir dir;
  struct Case {
    std::vector<std::string> names;
    int alpha;
    float r, g, b, a;
  };
  // io.h: R, G, B present -> RGB, a missing one 0; one colour channel -> grey; A optional.
  const Case cases[] = {
      {{"R", "G"}, -1, 0.1f, 0.2f, 0.0f, 1.0f},
      {{"R", "G", "B", "A"}, 3, 0.1f, 0.2f, 0.3f, 0.4f},
      {{"R", "G", "B", "A", "Z"}, 3, 0.1f, 0.2f, 0.3f, 0.4f},
      {{"Y"}, -1, 0.1f, 0.1f, 0.1f, 1.0f},
      {{"Y", "A"}, 1, 0.1f, 0.1f, 0.1f, 0.2f},
      {{"G", "A"}, 1, 0.1f, 0.1f, 0.1f, 0.2f},
  };
  int k = 0;
  for (const Case& c : cases) {
    const std::string path = dir / ("c" + std::to_string(k++) + ".tif");
    write_tiff(path, c.names, c.alpha);
    INFO(path);
    const LoadedImage li = load_image(path);
    const float* p = li.image.pixel(1, 1);
    // TIFF stores associated alpha; OIIO hands it back as stored.
    CHECK(p[0] == Approx(c.r));
    CHECK(p[1] == Approx(c.g));
    CHECK(p[2] == Approx(c.b));
    CHECK(p[3] == Approx(c.a));
    CHECK(li.info.has_alpha == (c.a != 1.0f));
    // load_image_rgb: the same colour, alpha 1.
    const LoadedImage rgb = load_image_rgb(path);
    const float* q = rgb.image.pixel(1, 1);
    CHECK((q[0] == p[0] && q[1] == p[1] && q[2] == p[2]));
    CHECK(q[3] == 1.0f);
    CHECK(rgb.info.has_alpha == li.info.has_alpha);
  }
}

TEST_CASE("refuse_overwrite sees the same file through any spelling", "[io]") {
  TempDir dir;
  const std::string in = dir / "in.exr";
  test::write_bytes(in, "x");
  test::fs::create_directory(dir / "sub");
  CHECK_THROWS_AS(refuse_overwrite(in, in), InputError);
  CHECK_THROWS_AS(refuse_overwrite(dir / "sub/../in.exr", in), InputError);
  test::fs::create_hard_link(in, dir / "link.exr");
  CHECK_THROWS_AS(refuse_overwrite(dir / "link.exr", in), InputError);
  CHECK_NOTHROW(refuse_overwrite(dir / "out.exr", in));
  CHECK_NOTHROW(refuse_overwrite(dir / "sub/in.exr", in));
}

TEST_CASE("EXR files of every lossless compression, half or float, read the values written",
          "[io]") {
  // Written with OpenEXR's C++ writer: channels R, G, B; R, G, B, A (stored A, B, G, R, as
  // RenderDoc's half EXR saves are); or those and Z beside them. Distinct values per channel, a
  // data window off the origin and lines in decreasing order, so that a value read into the
  // wrong texel, channel or row shows. A sparse image (zeros but one row) and a dense one. Files go
  // to OpenEXRCore or to the C++ reader (io_exr.cpp): every one must give the values written.
  TempDir dir;
  const int w = 67, h = 45, x0 = -3, y0 = 5;
  bool piz_packed = false, piz_raw = false;
  for (const bool dense : {false, true})
    for (const Imf::PixelType type : {Imf::FLOAT, Imf::HALF})
     for (const int channels : {3, 4, 5})
      for (const Imf::Compression comp : {Imf::NO_COMPRESSION, Imf::RLE_COMPRESSION,
                                          Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
                                          Imf::PIZ_COMPRESSION}) {
        const bool alpha = channels >= 4;
        // Values exact in half (k/64 for |k| <= 1024), scrambled per texel and channel.
        const auto value = [&](int x, int y, int c) {
          if (!dense && y != 7) return 0.0f;
          const unsigned k = (unsigned(x) * 73856093u) ^ (unsigned(y) * 19349663u) ^
                             (unsigned(c + 1) * 83492791u);
          const float v = static_cast<float>(int((k >> 7) % 2049u) - 1024) / 64.0f;
          // Float files: every bit of the mantissa in play (a word of a float read into the
          // wrong half shows), and too scrambled for PIZ to shrink when dense (chunks stored
          // raw).
          return type == Imf::HALF ? v : v + std::ldexp(static_cast<float>(k & 0x7fffu), -22);
        };
        const char* names[] = {"R", "G", "B", "A", "Z"};
        std::vector<std::vector<float>> planes(5, std::vector<float>(std::size_t(w) * h));
        std::vector<std::vector<half>> halves(5, std::vector<half>(std::size_t(w) * h));
        for (int c = 0; c < 5; ++c)
          for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
              planes[c][std::size_t(y) * w + x] = value(x, y, c);
              halves[c][std::size_t(y) * w + x] = half(value(x, y, c));
            }
        Imf::Header header(Imath::Box2i({0, 0}, {w + 9, h + 9}),
                           Imath::Box2i({x0, y0}, {x0 + w - 1, y0 + h - 1}));
        header.compression() = comp;
        header.lineOrder() = Imf::DECREASING_Y;
        Imf::FrameBuffer fb;
        for (int c = 0; c < 5; ++c) {
          if ((c == 3 && !alpha) || (c == 4 && channels < 5)) continue;
          header.channels().insert(names[c], Imf::Channel(type));
          char* base = type == Imf::HALF ? reinterpret_cast<char*>(halves[c].data())
                                         : reinterpret_cast<char*>(planes[c].data());
          const std::size_t size = type == Imf::HALF ? sizeof(half) : sizeof(float);
          base -= (std::ptrdiff_t(x0) + std::ptrdiff_t(y0) * w) * std::ptrdiff_t(size);
          fb.insert(names[c], Imf::Slice(type, base, size, size * w));
        }
        const std::string path =
            dir / ("c" + std::to_string(int(comp)) + (type == Imf::HALF ? "h" : "f") +
                   std::to_string(channels) + (dense ? "d" : "s") + ".exr");
        {
          Imf::OutputFile file(path.c_str(), header);
          file.setFrameBuffer(fb);
          file.writePixels(h);
        }
        INFO(path);
        if (comp == Imf::PIZ_COMPRESSION) {
          // PIZ chunks packed, and stored raw where packing does not shrink them: both covered.
          const std::size_t raw = std::size_t(w) * h * channels * (type == Imf::HALF ? 2 : 4);
          (test::read_bytes(path).size() < raw ? piz_packed : piz_raw) = true;
        }
        const LoadedImage li = load_image(path);
        REQUIRE(li.image.width() == w);
        REQUIRE(li.image.height() == h);
        CHECK(li.info.data_window.x0 == x0);
        CHECK(li.info.data_window.y0 == y0);
        CHECK(li.info.has_alpha == alpha);
        int wrong = 0;
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x)
            for (int c = 0; c < 4; ++c) {
              const float want = c == 3 && !alpha ? 1.0f : value(x, y, c);
              wrong += li.image.pixel(x, y)[c] != want;
            }
        CHECK(wrong == 0);
        // load_image_rgb (check's stage images): the same R, G and B, alpha 1 whatever the
        // file holds (Z read past).
        const LoadedImage rgb = load_image_rgb(path);
        CHECK(rgb.info.has_alpha == alpha);
        int wrong_rgb = 0;
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x)
            for (int c = 0; c < 4; ++c)
              wrong_rgb += rgb.image.pixel(x, y)[c] != (c == 3 ? 1.0f : value(x, y, c));
        CHECK(wrong_rgb == 0);
      }
  CHECK(piz_packed);
  CHECK(piz_raw);
}
