// bloomref — reading and writing images.
//
// Reading: EXR through OpenEXR (scanline, tiled, mip-mapped -> level 0, multipart -> the first
// part with R, G, B or Y, luminance/chroma (Y, RY, BY) reconstructed to RGB by RgbaInputFile,
// data window != display window -> the data window's pixels, both windows kept in ImageInfo);
// everything else (Radiance .hdr, PNG, TIFF, ...) through OpenImageIO, converted to float.
// Channel layouts: R, G, B present -> RGB (a missing one is 0); a single channel (Y, G, ...)
// -> grey R = G = B; A optional (1 when absent). Anything else is an InputError.
//
// Sizes are checked against SizeLimits from the header, before any pixel memory is allocated.
//
// Writing: EXR holds 32-bit float RGBA; PNG holds opaque 8-bit RGB, round(clamp(x, 0, 1) * 255)
// (alpha after a bloom is not a coverage a viewer can use; it stays in the EXR).
// Every write goes to an unnamed file in the destination folder and is given its name when
// complete (output_files.h), so a failure or a kill leaves no partial file and never touches
// what was there.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

#include "bloomref/image.h"

namespace bloomref {

struct SizeLimits {
  int max_side = 65536;                     ///< per axis
  std::size_t max_pixels = std::size_t(1) << 27;  ///< 134M pixels = 2 GiB per float RGBA image
  /// Optional: called with the size once it is within the limits above, before any pixel
  /// memory is allocated; throws InputError naming the path to refuse it (a command's memory
  /// budget).
  std::function<void(const std::string& path, int width, int height)> accept;
};

struct Window {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  ///< inclusive corners, as OpenEXR's Box2i
  int width() const { return x1 - x0 + 1; }
  int height() const { return y1 - y0 + 1; }
};

/// Image windows (placement): the data window holds the pixels, and is what bloomref blooms (its
/// edges are the clamp-to-edge edges; pixels of the display window outside it do not exist);
/// the display window is where they sit in the picture. Every window read is held to OpenEXR's
/// limits, so that every EXR output can keep it: at least one pixel, corners strictly inside
/// +-kWindowLimit (INT_MAX / 2, which keeps max - min + 1 and max + min from overflowing;
/// Imf::Header::sanityCheck). A window beyond them is an InputError naming the input (exit 2).
constexpr long long kWindowLimit = 1073741823;

/// The window of `width` x `height` pixels whose first is (x, y), computed without overflow;
/// InputError naming `path` and `which` ("data window", "display window") when it breaks the
/// limits above.
Window make_window(const std::string& path, const std::string& which, long long x, long long y,
                   long long width, long long height);

struct ImageInfo {
  std::string path;
  std::string format;       ///< "exr", or OIIO's format name ("hdr", "png", "tiff", ...)
  std::string layout;       ///< how the pixels were obtained, e.g. "part 0 of 10, RGBA"
  std::string channels;     ///< the source channels used, comma-separated
  bool has_alpha = false;
  Window data_window;       ///< the pixels we have (the image's size), where they sit
  Window display_window;    ///< the picture's frame (the data window's, when a file has none)
};

struct LoadedImage {
  Image image;
  ImageInfo info;
};

LoadedImage load_image(const std::string& path, const SizeLimits& limits = {});

/// load_image for a caller that reads R, G and B alone (check's stage images): alpha is 1 in
/// the image, and not converted where the reader can skip it. info.has_alpha still says whether
/// the file has one.
LoadedImage load_image_rgb(const std::string& path, const SizeLimits& limits = {});

/// Throws InputError naming `path` if width x height breaks a limit (says which).
void check_size(const std::string& path, long long width, long long height,
                const SizeLimits& limits);

/// Writes by extension (.exr or .png, case-insensitive); InputError for anything else.
/// `windows` (optional) gives the EXR data/display windows to keep the input's placement: they
/// are written when the data window has the image's size (the run's output, a stage of the
/// input's size); otherwise, and without `windows`, both windows are the image at (0, 0). A
/// PNG holds the data window's pixels alone.
void save_image(const std::string& path, ConstImageView img, const ImageInfo* windows = nullptr);

/// How a float EXR is compressed, all lossless (docs/design.md, "EXR compression"): PIZ for
/// outputs (smallest, fastest to write); for stage images read back by check, none (fastest to
/// write and to read), RLE, ZIPS or ZIP (smaller, slower to read).
enum class ExrCompression { piz, zip, zips, rle, none };
/// "piz", "zip", "zips", "rle" or "none"; ParamError naming `option` otherwise.
ExrCompression parse_exr_compression(const std::string& name, const std::string& option);

void save_exr(const std::string& path, ConstImageView img, const ImageInfo* windows = nullptr,
              ExrCompression compression = ExrCompression::piz);
void save_png(const std::string& path, ConstImageView img);
/// The bytes of the PNG save_png would write (for pages that embed images).
std::string encode_png(ConstImageView img);

/// Threads OpenEXR may use to decompress and compress (its chunks are independent, the bytes do
/// not depend on the count): 0 = all hardware threads (the default), 1 = none besides the
/// caller's. Process-wide, like OpenEXR's own pool.
void set_io_threads(int threads);

/// Throws InputError if writing `output` would replace `input` (same file, via any path).
void refuse_overwrite(const std::string& output, const std::string& input);

}  // namespace bloomref

namespace bloomref {
/// Writes text (JSON, Markdown) atomically, like the image writers.
void save_text(const std::string& path, const std::string& text);
}  // namespace bloomref
