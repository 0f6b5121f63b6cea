// The OpenImageIO module (libbloomref_oiio.so): reads any format OIIO knows, for io_oiio.cpp.
// Loaded with dlopen only when such a file is read (oiio_module.h says why).
#include <OpenImageIO/imageio.h>

#include "oiio_module.h"

using bloomref::detail::OiioHeader;
using bloomref::detail::OiioStatus;

extern "C" __attribute__((visibility("default"))) OiioStatus bloomref_oiio_read(
    const char* path, OiioHeader& header, void (*accept)(const OiioHeader&, void*), void* ctx,
    std::vector<float>& pixels, std::string& message) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    message = OIIO::geterror();
    return OiioStatus::cannot_open;
  }
  const OIIO::ImageSpec spec = in->spec();
  header.format = in->format_name();
  header.width = spec.width;
  header.height = spec.height;
  header.depth = spec.depth;
  header.nchannels = spec.nchannels;
  header.x = spec.x;
  header.y = spec.y;
  header.full_x = spec.full_x;
  header.full_y = spec.full_y;
  header.full_width = spec.full_width;
  header.full_height = spec.full_height;
  header.alpha_channel = spec.alpha_channel;
  header.channel_names.clear();
  for (int c = 0; c < spec.nchannels; ++c) header.channel_names.push_back(spec.channel_name(c));
  accept(header, ctx);  // may throw: `in` closes the file as the exception passes
  pixels.assign(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels, 0.0f);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data())) {
    message = in->geterror();
    return OiioStatus::cannot_read;
  }
  return OiioStatus::ok;
}
