// Internal to the I/O module: the readers and writers behind io.h and output_files.h.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

#include "bloomref/io.h"
#include "bloomref/output_files.h"

namespace bloomref::detail {

bool has_exr_magic(const std::string& path);
/// `rgb_only`: the caller reads R, G and B alone, so a PIZ file's alpha is not decoded (alpha
/// is then 1 in the image).
LoadedImage load_exr(const std::string& path, const SizeLimits& limits, bool rgb_only = false);
LoadedImage load_oiio(const std::string& path, const SizeLimits& limits);
/// Alpha 1 throughout (a file without alpha, or a caller that reads R, G and B alone).
void fill_alpha(Image& img);

/// The writers, into an open stream (`name` for OpenEXR's messages).
void write_exr_stream(std::FILE* f, const std::string& name, ConstImageView img,
                      const ImageInfo* windows, ExrCompression compression = ExrCompression::piz);
void write_png_stream(std::FILE* f, ConstImageView img);

/// Runs `write` on a stdio stream over the pending file, then flushes it; every failure is an
/// InputError naming the destination.
void write_pending(PendingFile& file, const std::function<void(std::FILE*)>& write);

/// Writes `img` by the extension of `path` (.exr or .png) into the pending file; InputError for
/// another extension or an empty image.
void write_image_pending(PendingFile& file, ConstImageView img, const ImageInfo* windows,
                         ExrCompression compression = ExrCompression::piz);

}  // namespace bloomref::detail
