// The interface between the reader of non-EXR files (io_oiio.cpp, in the library) and the
// OpenImageIO module (oiio_module.cpp, built as libbloomref_oiio.so and loaded with dlopen the
// first time such a file is read).
//
// Why a module: linking OpenImageIO 2.4 (Debian 12) loads ~260 shared libraries (OpenCV,
// FFmpeg, GDAL, DCMTK, ...) into the process, and relocating them slows every start of
// `bloomref`, whatever the command (docs/design.md, "OpenImageIO is a module loaded on first
// use, and PNG goes through libpng"). EXR input and PNG output do not need OIIO; only Radiance
// .hdr, TIFF, PNG input and the other formats do, and they pay that cost when they are read,
// once per process.
//
// Both sides are built by this project with the same compiler and standard library, so the
// structures below may hold std::string and std::vector.
#pragma once

#include <string>
#include <vector>

namespace bloomref::detail {

struct OiioHeader {
  std::string format;  ///< OIIO's format name ("hdr", "png", "tiff", ...)
  int width = 0, height = 0, depth = 1, nchannels = 0;
  int x = 0, y = 0;                                 ///< data window origin
  int full_x = 0, full_y = 0, full_width = 0, full_height = 0;  ///< display window
  int alpha_channel = -1;
  std::vector<std::string> channel_names;
};

enum class OiioStatus { ok = 0, cannot_open = 1, cannot_read = 2 };

/// Opens `path`, fills `header`, calls `accept(header, ctx)` (which throws to refuse the file,
/// e.g. when it is too large: nothing has been allocated for the pixels yet), then reads every
/// channel of subimage 0 as float into `pixels` (width * height * nchannels). On failure
/// returns the status and OIIO's message in `message`.
using OiioReadFn = OiioStatus (*)(const char* path, OiioHeader& header,
                                  void (*accept)(const OiioHeader&, void*), void* ctx,
                                  std::vector<float>& pixels, std::string& message);

/// The symbol the module exports (extern "C", so dlsym finds it by this name).
inline constexpr const char* kOiioReadSymbol = "bloomref_oiio_read";

}  // namespace bloomref::detail
