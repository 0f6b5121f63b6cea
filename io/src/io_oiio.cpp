// Formats other than EXR (Radiance .hdr, PNG, TIFF, ...) through OpenImageIO, which lives in a
// module loaded on first use (oiio_module.h says why; oiio_module.cpp is the OIIO side).
#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

#include "bloomref/error.h"
#include "bloomref/stages.h"
#include "io_internal.h"
#include "oiio_module.h"

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

ChannelMap map_channels(const OiioHeader& spec) {
  ChannelMap m;
  const int nch = spec.nchannels;
  m.alpha = spec.alpha_channel >= 0 && spec.alpha_channel < nch ? spec.alpha_channel : -1;
  bool named = false;
  for (int c = 0; c < nch; ++c) {
    const std::string& n = spec.channel_names[c];
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

/// The folder of `file` ("" when it has no slash), with its trailing slash.
std::string folder_of(const std::string& file) {
  const auto slash = file.rfind('/');
  return slash == std::string::npos ? std::string() : file.substr(0, slash + 1);
}

/// Where the module may be: $BLOOMREF_OIIO_MODULE alone when it is set; otherwise, from the
/// folder of the running program and from that of the binary this code is linked into (the
/// Python module, a program linking the installed libraries): the module beside it, then where
/// an installed layout puts it (BLOOMREF_OIIO_MODULE_RELATIVE_DIRS, ':'-separated folders
/// relative to the installed binaries' own, set by CMake: the installation may move); then
/// where the installation at the configured prefix has it (BLOOMREF_OIIO_MODULE_INSTALLED_PATH:
/// for programs linking the installed libraries, wherever they are); last, where this build put
/// it (BLOOMREF_OIIO_MODULE_PATH).
std::vector<std::string> module_candidates() {
  if (const char* env = std::getenv("BLOOMREF_OIIO_MODULE"); env && *env) return {env};
  std::vector<std::string> folders;
  std::string exe(4096, '\0');
  const ssize_t n = ::readlink("/proc/self/exe", exe.data(), exe.size() - 1);
  if (n > 0) folders.push_back(folder_of(exe.substr(0, static_cast<std::size_t>(n))));
  Dl_info self{};
  if (::dladdr(reinterpret_cast<void*>(&folder_of), &self) && self.dli_fname) {
    const std::string f = folder_of(self.dli_fname);
    if (!f.empty() && (folders.empty() || f != folders.front())) folders.push_back(f);
  }
  std::vector<std::string> relative{""};
#ifdef BLOOMREF_OIIO_MODULE_RELATIVE_DIRS
  const std::string dirs = BLOOMREF_OIIO_MODULE_RELATIVE_DIRS;
  for (std::size_t a = 0; a <= dirs.size();) {
    const std::size_t b = std::min(dirs.find(':', a), dirs.size());
    if (b > a) relative.push_back(dirs.substr(a, b - a) + "/");
    a = b + 1;
  }
#endif
  std::vector<std::string> paths;
  for (const std::string& folder : folders)
    for (const std::string& rel : relative) paths.push_back(folder + rel + "libbloomref_oiio.so");
#ifdef BLOOMREF_OIIO_MODULE_INSTALLED_PATH
  paths.push_back(BLOOMREF_OIIO_MODULE_INSTALLED_PATH);
#endif
#ifdef BLOOMREF_OIIO_MODULE_PATH
  paths.push_back(BLOOMREF_OIIO_MODULE_PATH);
#endif
  return paths;
}

/// The module's reader, loaded once per process; throws InputError naming `path` when no
/// candidate loads (the message lists what was tried).
OiioReadFn oiio_reader(const std::string& path) {
  struct Loaded {
    OiioReadFn read = nullptr;
    std::string why;
  };
  static const Loaded loaded = [] {
    Loaded l;
    for (const std::string& candidate : module_candidates()) {
      ::dlerror();
      void* handle = ::dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!handle) {
        const char* e = ::dlerror();
        l.why += (l.why.empty() ? "" : "; ") + std::string(e ? e : candidate);
        continue;
      }
      l.read = reinterpret_cast<OiioReadFn>(::dlsym(handle, kOiioReadSymbol));
      if (l.read) return l;
      l.why += (l.why.empty() ? "" : "; ") + candidate + ": no " + kOiioReadSymbol;
    }
    return l;
  }();
  if (!loaded.read)
    throw InputError(path, "reading this format needs bloomref's OpenImageIO module "
                           "(libbloomref_oiio.so), which did not load (BLOOMREF_OIIO_MODULE may name "
                           "it): " + loaded.why);
  return loaded.read;
}

// The windows, held to io.h's limits: TIFF's XPosition/YPosition reach OIIO's origin as any
// int (2147483520 made x + width - 1 overflow). OIIO gives a format without a display window
// the data window's size at the data window's origin; a display window of no pixels is taken
// as none.
Window data_window(const std::string& path, const OiioHeader& h) {
  return make_window(path, "data window", h.x, h.y, h.width, h.height);
}
Window display_window(const std::string& path, const OiioHeader& h) {
  if (h.full_width == 0 || h.full_height == 0) return data_window(path, h);
  return make_window(path, "display window", h.full_x, h.full_y, h.full_width, h.full_height);
}

struct AcceptContext {
  const std::string* path;
  const SizeLimits* limits;
};

/// Refuses, before any pixel memory is allocated, what load_image would not take.
void accept_header(const OiioHeader& h, void* ctx) {
  const auto& a = *static_cast<const AcceptContext*>(ctx);
  check_size(*a.path, h.width, h.height, *a.limits);
  if (h.depth > 1) throw InputError(*a.path, "volume images are not supported");
  if (h.nchannels < 1)
    throw InputError(*a.path, "unsupported channel layout: the image has no channels");
  if (map_channels(h).colours == 0)
    throw InputError(*a.path, "unsupported channel layout: alpha only");
  data_window(*a.path, h);
  display_window(*a.path, h);
}

}  // namespace

LoadedImage load_oiio(const std::string& path, const SizeLimits& limits) {
  const OiioReadFn read = oiio_reader(path);
  OiioHeader spec;
  std::vector<float> buf;
  std::string why;
  AcceptContext ctx{&path, &limits};
  switch (read(path.c_str(), spec, accept_header, &ctx, buf, why)) {
    case OiioStatus::ok:
      break;
    case OiioStatus::cannot_open:
      throw InputError(path, "cannot read this image: " + (why.empty() ? "unknown format" : why));
    case OiioStatus::cannot_read:
      throw InputError(path, "cannot read the pixels: " + why);
  }
  const int nch = spec.nchannels;

  LoadedImage out;
  ImageInfo& info = out.info;
  info.path = path;
  info.format = spec.format;
  info.data_window = data_window(path, spec);
  info.display_window = display_window(path, spec);
  for (int c = 0; c < nch; ++c)
    info.channels += (c ? ", " : "") + spec.channel_names[c];
  const ChannelMap map = map_channels(spec);
  info.has_alpha = map.alpha >= 0;
  info.layout = map.grey ? "one channel read as grey" : "RGB";

  out.image = Image(spec.width, spec.height);
  float* d = out.image.data();
  for (std::size_t i = 0; i < out.image.pixel_count(); ++i) {
    const float* s = &buf[i * nch];
    for (int c = 0; c < 3; ++c) d[i * kChannels + c] = map.rgb[c] >= 0 ? s[map.rgb[c]] : 0.0f;
    d[i * kChannels + 3] = map.alpha >= 0 ? s[map.alpha] : 1.0f;
  }
  return out;
}

}  // namespace bloomref::detail
