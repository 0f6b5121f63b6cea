// Internal to the I/O module: the two readers and writers behind io.h.
#pragma once

#include <string>

#include "bloomref/io.h"

namespace bloomref::detail {

bool has_exr_magic(const std::string& path);
LoadedImage load_exr(const std::string& path, const SizeLimits& limits);
LoadedImage load_oiio(const std::string& path, const SizeLimits& limits);
void write_exr_file(const std::string& path, ConstImageView img, const ImageInfo* windows);
void write_png_file(const std::string& path, ConstImageView img);

}  // namespace bloomref::detail
