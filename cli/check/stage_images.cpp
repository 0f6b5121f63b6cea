#include "check/stage_images.h"

#include <Imath/half.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

#include "bloomref/error.h"
#include "bloomref/io.h"

namespace fs = std::filesystem;

namespace bloomref::cli {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// sRGB EOTF (IEC 61966-2-1).
float srgb_decode(float v) {
  return v <= 0.04045f ? v / 12.92f : static_cast<float>(std::pow((v + 0.055) / 1.055, 2.4));
}

Image read_raw(const StageFile& f, int width, int height) {
  const int w = f.width > 0 ? f.width : width, h = f.height > 0 ? f.height : height;
  const int ch = f.channels == ChannelOrder::rgb ? 3 : 4;
  const std::size_t bytes_per = f.format == RawFormat::f16 ? 2 : 4;
  // The declared size is compared first: nothing is read for a size the stage does not have.
  if (w != width || h != height)
    throw InputError(f.path, "is declared " + std::to_string(w) + "x" + std::to_string(h) +
                                 ", but stage '" + f.stage + "' of this scene is " +
                                 std::to_string(width) + "x" + std::to_string(height));
  const std::size_t expected = std::size_t(w) * h * ch * bytes_per;
  std::error_code ec;
  const auto size = fs::file_size(f.path, ec);
  if (ec) throw InputError(f.path, "cannot read: " + ec.message());
  if (size != expected)
    throw InputError(f.path, "holds " + std::to_string(size) + " bytes; a raw " +
                                 std::to_string(w) + "x" + std::to_string(h) + " image of " +
                                 std::to_string(ch) + " " +
                                 (f.format == RawFormat::f16 ? "f16" : "f32") + " channels has " +
                                 std::to_string(expected) +
                                 " (check width, height, format and channels)");
  std::ifstream in(f.path, std::ios::binary);
  std::vector<char> data(expected);
  if (!in.read(data.data(), static_cast<std::streamsize>(expected)))
    throw InputError(f.path, "cannot read its " + std::to_string(expected) + " bytes");
  Image img(w, h);
  for (std::size_t i = 0; i < std::size_t(w) * h; ++i)
    for (int c = 0; c < 4; ++c) {
      float v = 1.0f;  // alpha of an RGB file
      if (c < ch) {
        const char* p = data.data() + (i * ch + c) * bytes_per;
        if (f.format == RawFormat::f16) {
          std::uint16_t bits;
          std::memcpy(&bits, p, 2);
          Imath::half hv;
          hv.setBits(bits);
          v = hv;
        } else {
          std::memcpy(&v, p, 4);
        }
      }
      img.data()[i * 4 + c] = v;
    }
  return img;
}

Encoding resolve(const StageFile& f) {
  if (f.encoding != Encoding::automatic) return f.encoding;
  const std::string e = lower(fs::path(f.path).extension().string());
  if (e == ".exr") return Encoding::exr;
  if (e == ".png") return Encoding::png_linear;
  if (e == ".raw" || e == ".bin") return Encoding::raw;
  return Encoding::automatic;  // OpenImageIO, as float
}

const char* kStageExtensions[] = {".exr", ".png", ".raw", ".bin", ".hdr", ".tif", ".tiff"};

}  // namespace

Encoding parse_encoding(const std::string& s) {
  if (s == "auto") return Encoding::automatic;
  if (s == "exr") return Encoding::exr;
  if (s == "png-linear" || s == "png") return Encoding::png_linear;
  if (s == "png-srgb") return Encoding::png_srgb;
  if (s == "raw") return Encoding::raw;
  throw ParamError("encoding '" + s + "' is not one of: auto, exr, png-linear, png-srgb, raw");
}
Origin parse_origin(const std::string& s) {
  if (s == "top") return Origin::top;
  if (s == "bottom") return Origin::bottom;
  throw ParamError("origin '" + s + "' is not one of: top, bottom");
}
ChannelOrder parse_channel_order(const std::string& s) {
  const std::string u = lower(s);
  if (u == "rgba") return ChannelOrder::rgba;
  if (u == "bgra") return ChannelOrder::bgra;
  if (u == "rgb") return ChannelOrder::rgb;
  throw ParamError("channel order '" + s + "' is not one of: RGBA, BGRA, RGB");
}
RawFormat parse_raw_format(const std::string& s) {
  if (s == "f32") return RawFormat::f32;
  if (s == "f16") return RawFormat::f16;
  throw ParamError("raw format '" + s + "' is not one of: f32, f16");
}
std::string to_string(Encoding e) {
  switch (e) {
    case Encoding::automatic: return "auto";
    case Encoding::exr: return "exr";
    case Encoding::png_linear: return "png-linear";
    case Encoding::png_srgb: return "png-srgb";
    case Encoding::raw: return "raw";
  }
  return "?";
}
std::string to_string(Origin o) { return o == Origin::top ? "top" : "bottom"; }
std::string to_string(ChannelOrder c) {
  return c == ChannelOrder::rgba ? "RGBA" : c == ChannelOrder::bgra ? "BGRA" : "RGB";
}

LoadedStage load_stage(const StageFile& f, int width, int height) {
  LoadedStage out;
  if (f.image) {  // in memory: copied, alpha 1 (R, G and B are judged)
    const ConstImageView& v = *f.image;
    if (v.width != width || v.height != height)
      throw InputError(f.path, "is " + std::to_string(v.width) + "x" + std::to_string(v.height) +
                                   ", but stage '" + f.stage + "' of this scene is " +
                                   std::to_string(width) + "x" + std::to_string(height));
    out.image = Image::uninitialised(width, height);
    for (int y = 0; y < height; ++y) {
      const float* r = v.row(y);
      float* d = out.image.view().row(y);
      for (int i = 0; i < width * kChannels; ++i) d[i] = i % kChannels == 3 ? 1.0f : r[i];
    }
    return out;
  }
  const Encoding enc = resolve(f);
  if (enc == Encoding::raw) {
    out.image = read_raw(f, width, height);
  } else {
    std::error_code ec;
    if (!fs::exists(f.path, ec)) throw InputError(f.path, "no such file");
    // R, G and B are judged: alpha is 1 (a PIZ file's is not decoded). InputError naming the
    // file when it is corrupt.
    // The header's size is compared before any pixel memory is allocated.
    SizeLimits limits;
    limits.accept = [&f, width, height](const std::string& path, int w, int h) {
      if (w != width || h != height)
        throw InputError(path, "is " + std::to_string(w) + "x" + std::to_string(h) +
                                   ", but stage '" + f.stage + "' of this scene is " +
                                   std::to_string(width) + "x" + std::to_string(height));
    };
    out.image = load_image_rgb(f.path, limits).image;
    if (enc == Encoding::png_linear || enc == Encoding::png_srgb) out.code_bits = 8;
    if (enc == Encoding::png_srgb) {
      out.srgb = true;
      for (std::size_t i = 0; i < out.image.values().size(); ++i)
        if (i % 4 != 3) out.image.values()[i] = srgb_decode(out.image.values()[i]);
    }
  }
  if (out.image.width() != width || out.image.height() != height)
    throw InputError(f.path, "is " + std::to_string(out.image.width()) + "x" +
                                 std::to_string(out.image.height()) + ", but stage '" + f.stage +
                                 "' of this scene is " + std::to_string(width) + "x" +
                                 std::to_string(height));
  if (f.origin == Origin::bottom) {
    const std::size_t row = std::size_t(width) * kChannels;
    for (int y = 0; y < height / 2; ++y)
      std::swap_ranges(out.image.view().row(y), out.image.view().row(y) + row,
                       out.image.view().row(height - 1 - y));
  }
  if (f.channels == ChannelOrder::bgra)
    for (std::size_t i = 0; i < out.image.pixel_count(); ++i)
      std::swap(out.image.data()[i * 4], out.image.data()[i * 4 + 2]);
  return out;
}

bool looks_like_stage(const std::string& name) {
  static const char* plain[] = {"input", "bright", "bloom", "composite", "tonemap", "output"};
  for (const char* p : plain)
    if (name == p) return true;
  for (const char* prefix : {"blur.", "down.", "up."}) {
    const std::size_t n = std::strlen(prefix);
    if (name.size() > n && name.compare(0, n, prefix) == 0 &&
        std::all_of(name.begin() + n, name.end(), [](unsigned char c) { return std::isdigit(c); }))
      return true;
  }
  return false;
}

void stage_size(const Plan& plan, const std::string& name, int& width, int& height) {
  width = plan.facts.width;
  height = plan.facts.height;
  for (const StageSpec& s : plan.stages)
    if (s.name == name && (s.kind == StageKind::down || s.kind == StageKind::up)) {
      width = plan.levels[s.pass - 1].width;
      height = plan.levels[s.pass - 1].height;
    }
}

void require_stage_in_plan(const StageFile& f, const Plan& plan) {
  for (const StageSpec& s : plan.stages)
    if (s.name == f.stage) return;
  std::string names;
  for (const StageSpec& s : plan.stages) names += (names.empty() ? "" : ", ") + s.name;
  throw InputError(f.path, "is taken as stage '" + f.stage + "', but this pipeline (" +
                               to_string(plan.params.method) + ", " +
                               std::to_string(plan.params.passes) + " passes) has no such stage; "
                               "its stages: " + names);
}

std::vector<StageFile> find_stage_files(const std::string& dir, const Plan& plan,
                                        const StageFile& proto,
                                        const std::map<std::string, std::string>& aliases,
                                        std::vector<std::string>& ignored) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir, "is not a folder (--stages needs a folder)");
  std::vector<fs::path> entries;
  for (const auto& e : fs::directory_iterator(dir, ec)) entries.push_back(e.path());
  if (ec) throw InputError(dir, "cannot list the folder: " + ec.message());
  std::sort(entries.begin(), entries.end());
  std::map<std::string, std::string> seen;  // stage -> file
  std::vector<StageFile> out;
  for (const fs::path& p : entries) {
    const std::string file = p.filename().string();
    if (file.empty() || file[0] == '.') continue;
    const std::string ext = lower(p.extension().string());
    const auto alias = aliases.find(p.stem().string());
    const std::string stem = alias != aliases.end() ? alias->second : p.stem().string();
    const bool known_ext = std::find(std::begin(kStageExtensions), std::end(kStageExtensions),
                                     ext) != std::end(kStageExtensions);
    if (!looks_like_stage(stem)) {
      ignored.push_back(file);
      continue;
    }
    if (!known_ext)
      throw InputError(p.string(), "is named like stage '" + stem + "' but '" + ext +
                                       "' is not an image type check reads (exr, png, raw, bin, "
                                       "hdr, tif)");
    StageFile f = proto;
    f.stage = stem;
    f.path = p.string();
    require_stage_in_plan(f, plan);
    const auto [it, fresh] = seen.emplace(stem, p.string());
    if (!fresh)
      throw InputError(p.string(), "is a second file for stage '" + stem + "' (the first: " +
                                       it->second + ")");
    if (!fs::is_regular_file(p, ec)) throw InputError(p.string(), "is not a regular file");
    out.push_back(f);
  }
  return out;
}

}  // namespace bloomref::cli
