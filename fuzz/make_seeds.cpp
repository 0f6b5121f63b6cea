// Seeds for the fuzz targets: bloomref_fuzz_seeds TARGET CORPUS OUT writes into OUT small files
// of TARGET's format made from the images in CORPUS (the HDR corpus: BLOOMREF_CORPUS), plus a
// few of its own that the corpus lacks. Small, so that libFuzzer's mutations stay fast:
//   exr       the corpus's EXR files up to 128 KiB, and 8x8 crops of the others written in
//             each layout the reader handles (scanline and tiled, half and float, none, piz,
//             rle, b44, dwaa, zip, pxr24, mip-mapped, multipart, luminance/chroma, windows off
//             the origin, one Y channel)
//   hdr       the corpus's .hdr files up to 128 KiB, and 16x16 crops as Radiance RGBE
//   png, tiff 16x16 crops as 8- and 16-bit PNG, and as float, half, 16- and 8-bit TIFF (one
//             tiled, one with an origin off (0, 0), one grey, one with alpha)
//   manifest  fuzz/seeds/manifest/*.json (copied by scripts/fuzz)
#include <ImfChannelList.h>
#include <ImfOutputFile.h>
#include <ImfPartType.h>
#include <ImfHeader.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfRgbaFile.h>
#include <ImfTiledRgbaFile.h>
#include <ImfTiledOutputFile.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "bloomref/io.h"

namespace fs = std::filesystem;
using bloomref::Image;

namespace {

constexpr std::uintmax_t kSmallFile = 128 * 1024;

// An n x n crop of `img` around its brightest pixel (the part a bloom cares about).
Image crop(const Image& img, int n) {
  int bx = 0, by = 0;
  float best = -1;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const float* p = img.pixel(x, y);
      const float l = p[0] + p[1] + p[2];
      if (l > best) {  // NaN never is
        best = l;
        bx = x;
        by = y;
      }
    }
  const int w = std::min(n, img.width()), h = std::min(n, img.height());
  const int x0 = std::clamp(bx - w / 2, 0, img.width() - w), y0 = std::clamp(by - h / 2, 0, img.height() - h);
  Image out(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) out.pixel(x, y)[c] = img.pixel(x0 + x, y0 + y)[c];
  return out;
}

void write_oiio(const fs::path& path, const Image& img, OIIO::TypeDesc type, int channels,
                int x = 0, int y = 0, bool tiled = false) {
  OIIO::ImageSpec spec(img.width(), img.height(), channels, type);
  spec.x = x;
  spec.y = y;
  spec.full_x = 0;
  spec.full_y = 0;
  if (tiled) spec.tile_width = spec.tile_height = 16;
  std::vector<float> px;
  for (int yy = 0; yy < img.height(); ++yy)
    for (int xx = 0; xx < img.width(); ++xx)
      for (int c = 0; c < channels; ++c)
        px.push_back(img.pixel(xx, yy)[channels == 1 ? 1 : channels == 2 && c == 1 ? 3 : c]);
  auto out = OIIO::ImageOutput::create(path.string());
  if (!out || !out->open(path.string(), spec) ||
      !out->write_image(OIIO::TypeDesc::FLOAT, px.data()) || !out->close())
    std::cerr << "bloomref_fuzz_seeds: cannot write " << path << ": " << OIIO::geterror() << "\n";
}

void insert_rgba(Imf::Header& h, Imf::PixelType t) {
  for (const char* c : {"R", "G", "B", "A"}) h.channels().insert(c, Imf::Channel(t));
}

Imf::FrameBuffer frame(const Image& img, const Imath::Box2i& dw, const char* const* names, int n) {
  Imf::FrameBuffer fb;
  char* base = reinterpret_cast<char*>(const_cast<float*>(img.data()));
  const std::size_t xs = 16, ys = 16 * std::size_t(img.width());
  for (int c = 0; c < n; ++c)
    fb.insert(names[c], Imf::Slice::Make(Imf::FLOAT, base + 4 * c, dw, xs, ys));
  return fb;
}

std::vector<Imf::Rgba> half_pixels(const Image& img) {
  std::vector<Imf::Rgba> px;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const float* p = img.pixel(x, y);
      px.emplace_back(p[0], p[1], p[2], p[3]);
    }
  return px;
}

// OpenEXR writes a channel only from a frame buffer of its own pixel type: half layouts go
// through the Rgba interfaces, float ones through OutputFile.
void write_exr_layouts(const fs::path& out, const std::string& stem, const Image& img) {
  const char* rgba[] = {"R", "G", "B", "A"};
  const int w = img.width(), h = img.height();
  const std::vector<Imf::Rgba> half = half_pixels(img);
  for (const auto& [name, comp] : {std::pair{"none", Imf::NO_COMPRESSION},
                                   std::pair{"piz", Imf::PIZ_COMPRESSION},
                                   std::pair{"rle", Imf::RLE_COMPRESSION},
                                   std::pair{"b44", Imf::B44_COMPRESSION},
                                   std::pair{"dwaa", Imf::DWAA_COMPRESSION}}) {
    Imf::Header hd(w, h);
    hd.compression() = comp;
    Imf::RgbaOutputFile f((out / (stem + "-" + name + ".exr")).c_str(), hd, Imf::WRITE_RGBA);
    f.setFrameBuffer(half.data(), 1, w);
    f.writePixels(h);
  }
  for (const auto& [name, comp] : {std::pair{"zip-float", Imf::ZIP_COMPRESSION},
                                   std::pair{"pxr24-float", Imf::PXR24_COMPRESSION}}) {
    Imf::Header hd(w, h);
    hd.compression() = comp;
    // Windows off the origin.
    hd.dataWindow() = Imath::Box2i({3, -2}, {3 + w - 1, -2 + h - 1});
    hd.displayWindow() = Imath::Box2i({0, 0}, {w + 5, h + 5});
    insert_rgba(hd, Imf::FLOAT);
    Imf::OutputFile f((out / (stem + "-" + name + ".exr")).c_str(), hd);
    f.setFrameBuffer(frame(img, hd.dataWindow(), rgba, 4));
    f.writePixels(h);
  }
  {  // tiled, mip-mapped
    Imf::TiledRgbaOutputFile f((out / (stem + "-tiled.exr")).c_str(), Imf::Header(w, h), Imf::WRITE_RGBA,
                               4, 4, Imf::MIPMAP_LEVELS, Imf::ROUND_DOWN);
    for (int l = 0; l < f.numLevels(); ++l) {
      const std::vector<Imf::Rgba> level =
          l == 0 ? half : std::vector<Imf::Rgba>(std::size_t(f.levelWidth(l)) * f.levelHeight(l),
                                                 Imf::Rgba(0.5f, 0.5f, 0.5f, 1.0f));
      f.setFrameBuffer(level.data(), 1, f.levelWidth(l));
      f.writeTiles(0, f.numXTiles(l) - 1, 0, f.numYTiles(l) - 1, l);
    }
  }
  {  // multipart: a Z part first, then RGBA
    std::vector<Imf::Header> parts(2, Imf::Header(w, h));
    parts[0].channels().insert("Z", Imf::Channel(Imf::FLOAT));
    parts[0].setName("depth");
    parts[0].setType(Imf::SCANLINEIMAGE);
    insert_rgba(parts[1], Imf::FLOAT);
    parts[1].setName("rgba");
    parts[1].setType(Imf::SCANLINEIMAGE);
    Imf::MultiPartOutputFile f((out / (stem + "-multipart.exr")).c_str(), parts.data(), 2);
    const char* z[] = {"Z"};
    Imf::OutputPart p0(f, 0), p1(f, 1);
    p0.setFrameBuffer(frame(img, parts[0].dataWindow(), z, 1));
    p0.writePixels(h);
    p1.setFrameBuffer(frame(img, parts[1].dataWindow(), rgba, 4));
    p1.writePixels(h);
  }
  {  // luminance/chroma, subsampled
    Imf::RgbaOutputFile f((out / (stem + "-yc.exr")).c_str(), Imf::Header(w, h), Imf::WRITE_YCA);
    f.setFrameBuffer(half.data(), 1, w);
    f.writePixels(h);
  }
  {  // one Y channel
    Imf::Header hd(w, h);
    hd.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    const char* y[] = {"Y"};
    Imf::OutputFile f((out / (stem + "-y.exr")).c_str(), hd);
    f.setFrameBuffer(frame(img, hd.dataWindow(), y, 1));
    f.writePixels(h);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: bloomref_fuzz_seeds exr|hdr|png|tiff CORPUS OUT\n";
    return 2;
  }
  const std::string target = argv[1];
  const fs::path corpus = argv[2], out = argv[3];
  fs::create_directories(out);
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(corpus))
    if (e.path().extension() == ".exr" || e.path().extension() == ".hdr") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  int written = 0;
  for (const fs::path& f : files) {
    const std::string stem = f.stem().string();
    const std::string ext = f.extension().string();
    if (((target == "exr" && ext == ".exr") || (target == "hdr" && ext == ".hdr")) &&
        fs::file_size(f) <= kSmallFile) {
      fs::copy_file(f, out / f.filename(), fs::copy_options::overwrite_existing);
      ++written;
      continue;
    }
    Image img;
    try {
      img = bloomref::load_image(f.string()).image;
    } catch (const std::exception& e) {
      std::cerr << "bloomref_fuzz_seeds: skipping " << f << ": " << e.what() << "\n";
      continue;
    }
    if (target == "exr") {
      if (written < 40) {
        write_exr_layouts(out, stem, crop(img, 8));
        written += 10;
      }
    } else if (target == "hdr") {
      write_oiio(out / (stem + ".hdr"), crop(img, 16), OIIO::TypeDesc::FLOAT, 3);
      ++written;
    } else if (target == "png") {
      const Image c = crop(img, 16);
      write_oiio(out / (stem + "-8.png"), c, OIIO::TypeDesc::UINT8, 3);
      write_oiio(out / (stem + "-16a.png"), c, OIIO::TypeDesc::UINT16, 4);
      write_oiio(out / (stem + "-grey.png"), c, OIIO::TypeDesc::UINT8, 1);
      written += 3;
    } else if (target == "tiff") {
      const Image c = crop(img, 16);
      write_oiio(out / (stem + "-float.tif"), c, OIIO::TypeDesc::FLOAT, 3);
      write_oiio(out / (stem + "-half.tif"), c, OIIO::TypeDesc::HALF, 4, 0, 0, true);
      write_oiio(out / (stem + "-16.tif"), c, OIIO::TypeDesc::UINT16, 3, 30, 40);
      write_oiio(out / (stem + "-8grey.tif"), c, OIIO::TypeDesc::UINT8, 2);
      written += 4;
    } else {
      std::cerr << "bloomref_fuzz_seeds: unknown target " << target << "\n";
      return 2;
    }
  }
  std::cout << written << " seeds in " << out.string() << "\n";
  return 0;
}
