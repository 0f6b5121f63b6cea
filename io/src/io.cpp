#include "bloomref/io.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
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

// Writes through `write` into a pending file of `path` (output_files.h) and publishes it: a
// reader never sees a partial file, and a failed or interrupted write leaves the old file as it
// was and nothing beside it.
void write_atomically(const std::string& path, const std::function<void(std::FILE*)>& write) {
  PendingFile file(path);
  detail::write_pending(file, write);
  file.publish();
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
  if (limits.accept) limits.accept(path, static_cast<int>(width), static_cast<int>(height));
}

Window make_window(const std::string& path, const std::string& which, long long x, long long y,
                   long long width, long long height) {
  const long long x1 = x + width - 1, y1 = y + height - 1;  // |x|, |w| < 2^31: no overflow
  if (width < 1 || height < 1)
    throw InputError(path, "the " + which + " is empty (" + std::to_string(width) + "x" +
                               std::to_string(height) + ")");
  const auto inside = [](long long v) { return v > -kWindowLimit && v < kWindowLimit; };
  if (!inside(x) || !inside(y) || !inside(x1) || !inside(y1))
    throw InputError(path, "the " + which + " (" + std::to_string(width) + "x" +
                               std::to_string(height) + " at " + std::to_string(x) + ", " +
                               std::to_string(y) + ") reaches beyond +-" +
                               std::to_string(kWindowLimit) +
                               ", where an image window may lie (OpenEXR's limit)");
  return {int(x), int(y), int(x1), int(y1)};
}

namespace {

LoadedImage load(const std::string& path, const SizeLimits& limits, bool rgb_only) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "no such file");
  if (fs::is_directory(path, ec)) throw InputError(path, "is a folder, not an image file");
  const auto bytes = fs::file_size(path, ec);
  if (ec) throw InputError(path, "cannot read: " + ec.message());
  if (bytes == 0) throw InputError(path, "the file is empty (0 bytes)");
  if (detail::has_exr_magic(path)) return detail::load_exr(path, limits, rgb_only);
  if (lower_extension(path) == ".exr")
    throw InputError(path, "not an OpenEXR file: it does not start with the OpenEXR magic number");
  LoadedImage out = detail::load_oiio(path, limits);
  if (rgb_only) detail::fill_alpha(out.image);
  return out;
}

}  // namespace

LoadedImage load_image(const std::string& path, const SizeLimits& limits) {
  return load(path, limits, false);
}

LoadedImage load_image_rgb(const std::string& path, const SizeLimits& limits) {
  return load(path, limits, true);
}

void save_exr(const std::string& path, ConstImageView img, const ImageInfo* windows,
              ExrCompression compression) {
  require_pixels(path, img);
  write_atomically(path, [&](std::FILE* f) {
    detail::write_exr_stream(f, path, img, windows, compression);
  });
}

ExrCompression parse_exr_compression(const std::string& name, const std::string& option) {
  if (name == "piz") return ExrCompression::piz;
  if (name == "zip") return ExrCompression::zip;
  if (name == "zips") return ExrCompression::zips;
  if (name == "rle") return ExrCompression::rle;
  if (name == "none") return ExrCompression::none;
  throw ParamError(option + " '" + name + "' is not one of: none, rle, zips, zip, piz");
}

void save_png(const std::string& path, ConstImageView img) {
  require_pixels(path, img);
  write_atomically(path, [&](std::FILE* f) { detail::write_png_stream(f, img); });
}

void save_image(const std::string& path, ConstImageView img, const ImageInfo* windows) {
  const std::string e = lower_extension(path);
  if (e == ".exr") return save_exr(path, img, windows);
  if (e == ".png") return save_png(path, img);
  throw InputError(path, (e.empty() ? std::string("has no extension") : "cannot write '" + e + "' files") +
                             ": the output must end in .exr or .png");
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

namespace bloomref {

void save_text(const std::string& path, const std::string& text) {
  write_atomically(path, [&](std::FILE* f) {
    if (std::fwrite(text.data(), 1, text.size(), f) != text.size())
      throw InputError(path, std::string("cannot write: ") + std::strerror(errno));
  });
}

namespace detail {

void write_pending(PendingFile& file, const std::function<void(std::FILE*)>& write) {
  const std::string& path = file.destination();
  const int fd = ::dup(file.fd());
  std::FILE* f = fd >= 0 ? ::fdopen(fd, "wb") : nullptr;
  if (!f) {
    const int e = errno;
    if (fd >= 0) ::close(fd);
    throw InputError(path, std::string("cannot write: ") + std::strerror(e));
  }
  try {
    write(f);
  } catch (const InputError& e) {
    std::fclose(f);
    throw InputError(path, e.problem());  // named after the destination
  } catch (const std::exception& e) {
    std::fclose(f);
    throw InputError(path, std::string("cannot write: ") + e.what());
  }
  const bool failed = std::fflush(f) != 0 || std::ferror(f);
  const int e = errno;
  if (std::fclose(f) != 0 || failed)
    throw InputError(path, std::string("cannot write: ") + std::strerror(failed ? e : errno));
}

void write_image_pending(PendingFile& file, ConstImageView img, const ImageInfo* windows,
                         ExrCompression compression) {
  const std::string& path = file.destination();
  const std::string e = lower_extension(path);
  if (e != ".exr" && e != ".png")
    throw InputError(path, (e.empty() ? std::string("has no extension") : "cannot write '" + e + "' files") +
                             ": the output must end in .exr or .png");
  require_pixels(path, img);
  write_pending(file, [&](std::FILE* f) {
    if (e == ".exr") write_exr_stream(f, path, img, windows, compression);
    else write_png_stream(f, img);
  });
}

}  // namespace detail
}  // namespace bloomref
