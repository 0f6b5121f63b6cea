// PNG output through libpng's simplified API (png.h: png_image_write_to_file, libpng 1.6).
//
// Written directly rather than through OpenImageIO: OIIO pulls ~260 shared libraries into every
// process that links it (their dynamic relocation runs before main), and its PNG writer is
// slow on large pictures (docs/design.md, "OpenImageIO is a module loaded on first use, and
// PNG goes through libpng").
#include <png.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "io_internal.h"

namespace bloomref::detail {

namespace {

// The picture's 8-bit codes and libpng's description of it, for either destination.
struct PngPicture {
  std::vector<unsigned char> px;
  png_image image;

  explicit PngPicture(ConstImageView img) {
    // Opaque RGB: the PNG is the display-referred picture. Alpha after a bloom is not a
    // coverage any viewer can use (CandleGlass.exr's flame has A = 0 and bright RGB; a viewer
    // would show it transparent), so it stays in the EXR output only.
    constexpr int kOut = 3;
    px.resize(static_cast<std::size_t>(img.width) * img.height * kOut);
    for (int y = 0; y < img.height; ++y) {
      const float* row = img.row(y);
      unsigned char* out = &px[std::size_t(y) * img.width * kOut];
      for (int x = 0; x < img.width; ++x)
        for (int c = 0; c < kOut; ++c) out[x * kOut + c] = quantize_8bit(row[x * kChannels + c]);
    }
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(img.width);
    image.height = static_cast<png_uint_32>(img.height);
    image.format = PNG_FORMAT_RGB;
    // NOT_sRGB: the codes are pow(x, 1 / gamma), not the sRGB curve, so no sRGB chunk is
    // claimed; libpng then writes gAMA 1/2.2 (the default gamma; it does not follow --gamma).
    // FAST: libpng's quicker row filter and zlib settings, which write a large picture several
    // times faster than libpng's defaults (and than OIIO), at about the same file size.
    image.flags = PNG_IMAGE_FLAG_COLORSPACE_NOT_sRGB | PNG_IMAGE_FLAG_FAST;
  }
  ~PngPicture() { png_image_free(&image); }

  void check(int ok) {
    if (!ok) throw InputError("", std::string("cannot write the PNG: ") + image.message);
  }
};

}  // namespace

void write_png_stream(std::FILE* f, ConstImageView img) {
  PngPicture p(img);
  p.check(png_image_write_to_stdio(&p.image, f, /*convert_to_8bit=*/0, p.px.data(),
                                   /*row_stride=*/0, /*colormap=*/nullptr));
}

}  // namespace bloomref::detail

namespace bloomref {

std::string encode_png(ConstImageView img) {
  if (img.empty() || img.data == nullptr) throw InputError("", "nothing to encode: the image is empty");
  detail::PngPicture p(img);
  png_alloc_size_t size = 0;
  p.check(png_image_write_to_memory(&p.image, nullptr, &size, 0, p.px.data(), 0, nullptr));
  std::string bytes(size, '\0');
  p.check(png_image_write_to_memory(&p.image, bytes.data(), &size, 0, p.px.data(), 0, nullptr));
  bytes.resize(size);
  return bytes;
}

}  // namespace bloomref
