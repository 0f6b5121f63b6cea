// Formats other than EXR (Radiance .hdr, PNG, TIFF, ...) through OpenImageIO.
#include <OpenImageIO/imageio.h>

#include <vector>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "io_internal.h"

namespace bloomref::detail {

LoadedImage load_oiio(const std::string& path, const SizeLimits& limits) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    std::string why = OIIO::geterror();
    throw InputError(path, "cannot read this image: " + (why.empty() ? "unknown format" : why));
  }
  const OIIO::ImageSpec spec = in->spec();
  check_size(path, spec.width, spec.height, limits);
  if (spec.depth > 1) throw InputError(path, "volume images are not supported");
  const int nch = spec.nchannels;
  if (nch < 1) throw InputError(path, "unsupported channel layout: the image has no channels");

  LoadedImage out;
  ImageInfo& info = out.info;
  info.path = path;
  info.format = in->format_name();
  info.data_window = {spec.x, spec.y, spec.x + spec.width - 1, spec.y + spec.height - 1};
  info.display_window = {spec.full_x, spec.full_y, spec.full_x + spec.full_width - 1,
                         spec.full_y + spec.full_height - 1};
  for (int c = 0; c < nch; ++c)
    info.channels += (c ? ", " : "") + std::string(spec.channel_name(c));
  const int alpha = spec.alpha_channel >= 0 ? spec.alpha_channel : (nch == 2 || nch >= 4 ? nch - 1 : -1);
  const int colours = alpha >= 0 ? std::min(nch - 1, 3) : std::min(nch, 3);
  if (colours < 1) throw InputError(path, "unsupported channel layout: alpha only");
  info.has_alpha = alpha >= 0;
  info.layout = colours == 1 ? "one channel read as grey" : "RGB";

  std::vector<float> buf(static_cast<std::size_t>(spec.width) * spec.height * nch);
  if (!in->read_image(0, 0, 0, nch, OIIO::TypeDesc::FLOAT, buf.data()))
    throw InputError(path, "cannot read the pixels: " + in->geterror());

  out.image = Image(spec.width, spec.height);
  float* d = out.image.data();
  for (std::size_t i = 0; i < out.image.pixel_count(); ++i) {
    const float* s = &buf[i * nch];
    for (int c = 0; c < 3; ++c) d[i * kChannels + c] = s[colours == 1 ? 0 : std::min(c, colours - 1)];
    if (colours == 2) d[i * kChannels + 2] = 0.0f;
    d[i * kChannels + 3] = alpha >= 0 ? s[alpha] : 1.0f;
  }
  return out;
}

void write_png_file(const std::string& path, ConstImageView img) {
  std::vector<unsigned char> px(static_cast<std::size_t>(img.width) * img.height * kChannels);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width * kChannels; ++x)
      px[(std::size_t(y) * img.width * kChannels) + x] = quantize_8bit(img.row(y)[x]);
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw InputError(path, "cannot create a PNG writer: " + OIIO::geterror());
  OIIO::ImageSpec spec(img.width, img.height, kChannels, OIIO::TypeDesc::UINT8);
  if (!out->open(path, spec) || !out->write_image(OIIO::TypeDesc::UINT8, px.data()) ||
      !out->close())
    throw InputError(path, "cannot write: " + out->geterror());
}

}  // namespace bloomref::detail
