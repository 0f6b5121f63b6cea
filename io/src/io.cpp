#include "bloomref/io.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <system_error>

#include "bloomref/error.h"
#include "io_internal.h"

namespace fs = std::filesystem;

namespace bloomref {
namespace {

std::string lower_extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}

// Writes through `write` into a temporary file beside `path`, then renames it into place: a
// reader never sees a partial file, and a failed write leaves the old file untouched.
template <class Write>
void write_atomically(const std::string& path, Write write) {
  const fs::path target(path);
  fs::path dir = target.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(path, "the output folder does not exist");
  if (fs::is_directory(target, ec)) throw InputError(path, "is a folder, not a file");
  // Unique per process and per call, so concurrent writes of one path never share a temporary.
  static std::atomic<unsigned> serial{0};
  const fs::path tmp = dir / ("." + target.stem().string() + ".tmp-" + std::to_string(::getpid()) +
                              "-" + std::to_string(serial++) + target.extension().string());
  try {
    write(tmp.string());
  } catch (const InputError& e) {
    fs::remove(tmp, ec);
    throw InputError(path, e.problem());  // named after the destination, not the temporary
  } catch (const std::exception& e) {
    fs::remove(tmp, ec);
    throw InputError(path, std::string("cannot write: ") + e.what());
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(path, "cannot move the finished file into place: " + ec.message());
  }
}

// An image with no pixels cannot be written (EXR and PNG need at least 1x1); refusing it
// up front gives one clear message instead of each library's own.
void require_pixels(const std::string& path, ConstImageView img) {
  if (img.empty() || img.data == nullptr)
    throw InputError(path, "nothing to write: the image is empty (" + std::to_string(img.width) +
                               "x" + std::to_string(img.height) + ")");
}

}  // namespace

void check_size(const std::string& path, long long width, long long height,
                const SizeLimits& limits) {
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  if (width <= 0 || height <= 0) throw InputError(path, "the image is empty (" + size + ")");
  if (width > limits.max_side || height > limits.max_side)
    throw InputError(path, "the image is " + size + ", beyond the limit of " +
                               std::to_string(limits.max_side) + " pixels per side");
  if (static_cast<unsigned long long>(width) * height > limits.max_pixels)
    throw InputError(path, "the image is " + size + " = " + std::to_string(width * height) +
                               " pixels, beyond the limit of " +
                               std::to_string(limits.max_pixels) +
                               " pixels (the size of one float RGBA image is capped at " +
                               std::to_string(limits.max_pixels * 16 >> 20) + " MiB)");
}

LoadedImage load_image(const std::string& path, const SizeLimits& limits) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "no such file");
  if (fs::is_directory(path, ec)) throw InputError(path, "is a folder, not an image file");
  const auto bytes = fs::file_size(path, ec);
  if (ec) throw InputError(path, "cannot read: " + ec.message());
  if (bytes == 0) throw InputError(path, "the file is empty (0 bytes)");
  if (detail::has_exr_magic(path)) return detail::load_exr(path, limits);
  if (lower_extension(path) == ".exr")
    throw InputError(path, "not an OpenEXR file: it does not start with the OpenEXR magic number");
  return detail::load_oiio(path, limits);
}

void save_exr(const std::string& path, ConstImageView img, const ImageInfo* windows) {
  require_pixels(path, img);
  write_atomically(path, [&](const std::string& tmp) { detail::write_exr_file(tmp, img, windows); });
}

void save_png(const std::string& path, ConstImageView img) {
  require_pixels(path, img);
  write_atomically(path, [&](const std::string& tmp) { detail::write_png_file(tmp, img); });
}

void save_image(const std::string& path, ConstImageView img, const ImageInfo* windows) {
  const std::string e = lower_extension(path);
  if (e == ".exr") return save_exr(path, img, windows);
  if (e == ".png") return save_png(path, img);
  throw InputError(path, "cannot write '" + e + "' files: the output must end in .exr or .png");
}

void refuse_overwrite(const std::string& output, const std::string& input) {
  std::error_code ec, ec_out, ec_in;
  // equivalent(): the same file through links; weakly_canonical(): the same path through
  // "..", "." and symlinked folders even when the output does not exist yet. A path that cannot
  // be resolved yields an empty result, which must not count as a match.
  const bool same = fs::exists(output, ec) && fs::exists(input, ec) && fs::equivalent(output, input, ec);
  const fs::path out = fs::weakly_canonical(output, ec_out), in = fs::weakly_canonical(input, ec_in);
  if (same || (!ec_out && !ec_in && out == in))
    throw InputError(output, "is the input file; bloomref never writes over its input");
}

}  // namespace bloomref

#include <fstream>

namespace bloomref {
void save_text(const std::string& path, const std::string& text) {
  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    f.close();
    if (!f) throw InputError(tmp, "cannot write");
  });
}
}  // namespace bloomref
