// Formats other than EXR (Radiance .hdr, PNG, TIFF, ...) through OpenImageIO.
#include <OpenImageIO/imageio.h>

#include <string>
#include <vector>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "io_internal.h"

namespace bloomref::detail {
namespace {

// Where R, G, B and A come from (channel indices, -1 = absent), by io.h's rules, as for EXR:
// channels named R, G, B -> those (a missing one is 0, other channels are ignored); one colour
// channel -> grey; without R, G, B names (Y, or formats that store none) -> positional RGB,
// with 2 channels read as grey + alpha and 4 or more as RGBA when OIIO names no alpha.
struct ChannelMap {
  int rgb[3] = {-1, -1, -1};
  int alpha = -1;
  int colours = 0;  // colour channels found
  bool grey = false;
};

ChannelMap map_channels(const OIIO::ImageSpec& spec) {
  ChannelMap m;
  const int nch = spec.nchannels;
  m.alpha = spec.alpha_channel >= 0 && spec.alpha_channel < nch ? spec.alpha_channel : -1;
  bool named = false;
  for (int c = 0; c < nch; ++c) {
    const std::string n = spec.channel_name(c);
    if (n == "R" || n == "G" || n == "B") {
      m.rgb[n == "R" ? 0 : n == "G" ? 1 : 2] = c;
      named = true;
    }
    if (m.alpha < 0 && (n == "A" || n == "Alpha")) m.alpha = c;
  }
  if (m.alpha < 0 && !named && (nch == 2 || nch >= 4)) m.alpha = nch == 2 ? 1 : 3;
  std::vector<int> colour;  // the colour channels: named R, G, B, else all but alpha
  for (int c = 0; c < nch; ++c)
    if (named ? (c == m.rgb[0] || c == m.rgb[1] || c == m.rgb[2]) : c != m.alpha)
      colour.push_back(c);
  m.colours = static_cast<int>(colour.size());
  if (m.colours == 1) {
    m.grey = true;
    m.rgb[0] = m.rgb[1] = m.rgb[2] = colour[0];
  } else if (!named) {
    for (int c = 0; c < 3 && c < m.colours; ++c) m.rgb[c] = colour[c];
  }
  return m;
}

}  // namespace

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
  const ChannelMap map = map_channels(spec);
  if (map.colours == 0) throw InputError(path, "unsupported channel layout: alpha only");
  info.has_alpha = map.alpha >= 0;
  info.layout = map.grey ? "one channel read as grey" : "RGB";

  std::vector<float> buf(static_cast<std::size_t>(spec.width) * spec.height * nch);
  if (!in->read_image(0, 0, 0, nch, OIIO::TypeDesc::FLOAT, buf.data()))
    throw InputError(path, "cannot read the pixels: " + in->geterror());

  out.image = Image(spec.width, spec.height);
  float* d = out.image.data();
  for (std::size_t i = 0; i < out.image.pixel_count(); ++i) {
    const float* s = &buf[i * nch];
    for (int c = 0; c < 3; ++c) d[i * kChannels + c] = map.rgb[c] >= 0 ? s[map.rgb[c]] : 0.0f;
    d[i * kChannels + 3] = map.alpha >= 0 ? s[map.alpha] : 1.0f;
  }
  return out;
}

void write_png_file(const std::string& path, ConstImageView img) {
  // Opaque RGB: the PNG is the display-referred picture. Alpha after a bloom is not a coverage
  // any viewer can use (CandleGlass.exr's flame has A = 0 and bright RGB; a viewer would show
  // it transparent), so it stays in the EXR output only.
  constexpr int kOut = 3;
  std::vector<unsigned char> px(static_cast<std::size_t>(img.width) * img.height * kOut);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < kOut; ++c)
        px[(std::size_t(y) * img.width + x) * kOut + c] = quantize_8bit(img.pixel(x, y)[c]);
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw InputError(path, "cannot create a PNG writer: " + OIIO::geterror());
  OIIO::ImageSpec spec(img.width, img.height, kOut, OIIO::TypeDesc::UINT8);
  if (!out->open(path, spec) || !out->write_image(OIIO::TypeDesc::UINT8, px.data()) ||
      !out->close())
    throw InputError(path, "cannot write: " + out->geterror());
}

}  // namespace bloomref::detail
