// EXR reading and writing through OpenEXR (OIIO 2.4 refuses subsampled luminance/chroma files
// such as StarField.exr; OpenEXR's RgbaInputFile reconstructs them).
#include <ImfArray.h>
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputPart.h>
#include <ImfMultiPartInputFile.h>
#include <ImfIO.h>
#include <ImfOutputFile.h>
#include <ImfPartType.h>
#include <ImfRgbaFile.h>
#include <ImfThreading.h>
#include <ImfVersion.h>
#include <half.h>
#include <openexr.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <set>
#include <system_error>
#include <thread>
#include <vector>

#include "bloomref/error.h"
#include "io_internal.h"

namespace bloomref {
namespace {
std::atomic<int> g_io_threads{0};
}  // namespace

void set_io_threads(int threads) { g_io_threads = threads < 0 ? 0 : threads; }

}  // namespace bloomref

namespace bloomref::detail {
namespace {

/// OpenEXR's numThreads argument (chunks in flight), with its global pool, which runs them, set
/// to as many workers (0: everything in the caller).
int exr_threads() {
  const int t = g_io_threads.load();
  const int n = t > 0 ? t : static_cast<int>(std::thread::hardware_concurrency());
  const int workers = n > 1 ? n : 0;
  if (Imf::globalThreadCount() != workers) Imf::setGlobalThreadCount(workers);
  return workers;
}

// OpenEXR's reader has checked the windows against the same limits (io.h); checked again so
// that every format's windows pass one rule.
Window to_window(const std::string& path, const std::string& which, const Imath::Box2i& b) {
  return make_window(path, which, b.min.x, b.min.y, (long long)b.max.x - b.min.x + 1,
                     (long long)b.max.y - b.min.y + 1);
}

std::string join(const std::set<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// The channels of a part that bloomref can use, or "" when it has none.
struct PartChannels {
  std::set<std::string> all;
  bool rgb = false, luma = false, chroma = false, alpha = false;
  std::string single;  // the one colour channel of a grey file
};

PartChannels classify(const Imf::Header& h) {
  PartChannels pc;
  int colour = 0;
  for (auto it = h.channels().begin(); it != h.channels().end(); ++it) {
    const std::string n = it.name();
    pc.all.insert(n);
    if (n == "R" || n == "G" || n == "B") { pc.rgb = true; ++colour; pc.single = n; }
    if (n == "Y") pc.luma = true;
    if (n == "RY" || n == "BY") pc.chroma = true;
    if (n == "A") pc.alpha = true;
  }
  if (colour != 1) pc.single.clear();
  if (!pc.rgb && pc.luma && !pc.chroma) pc.single = "Y";
  return pc;
}

bool usable(const PartChannels& pc) { return pc.rgb || pc.luma; }

// An OpenEXRCore read context of `path` that reports nothing (the C++ reader reports a file
// Core cannot read), or null when Core cannot open it.
exr_context_t open_silently(const std::string& path) {
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = [](exr_const_context_t, exr_result_t, const char*) {};
  init.flags = EXR_CONTEXT_FLAG_SILENT_HEADER_PARSE;
  exr_context_t ctxt = nullptr;
  if (exr_start_read(&ctxt, path.c_str(), &init) == EXR_ERR_SUCCESS) return ctxt;
  exr_finish(&ctxt);
  return nullptr;
}

// Checks every part's data window against the limits before the C++ API opens the file: its
// constructors read each part's chunk offset table, whose length follows the data window, so a
// forged header (100000x100000) makes them read or allocate far past the file. OpenEXRCore
// parses the headers alone. When Core cannot parse them, the C++ reader reports the problem.
// Every valid file holds one 8-byte offset per chunk, so a file shorter than its offset tables
// is refused here too, before a header within the limits gets its pixels allocated.
void check_part_sizes(const std::string& path, const SizeLimits& limits,
                      unsigned long long file_bytes) {
  exr_context_t ctxt = open_silently(path);
  if (!ctxt) return;
  int parts = 0;
  exr_get_count(ctxt, &parts);
  unsigned long long chunks = 0;
  SizeLimits headers = limits;
  headers.accept = nullptr;  // the part read is judged by it once chosen (load_exr)
  try {
    for (int p = 0; p < parts; ++p) {
      int32_t n = 0;
      if (exr_get_chunk_count(ctxt, p, &n) == EXR_ERR_SUCCESS && n > 0) chunks += n;
      exr_attr_box2i_t b{};
      if (exr_get_data_window(ctxt, p, &b) != EXR_ERR_SUCCESS) continue;
      const long long w = (long long)b.max.x - b.min.x + 1, h = (long long)b.max.y - b.min.y + 1;
      try {
        check_size(path, w, h, headers);
      } catch (const InputError& e) {
        if (parts == 1) throw;
        throw InputError(path, "part " + std::to_string(p) + " of " + std::to_string(parts) +
                                   ": " + e.problem());
      }
    }
    if (chunks * 8 > file_bytes)
      throw InputError(path, "truncated or corrupt: the header describes " +
                                 std::to_string(chunks) + " pixel chunks, whose offset table "
                                 "alone needs " + std::to_string(chunks * 8) +
                                 " bytes, but the file has " + std::to_string(file_bytes));
  } catch (...) {
    exr_finish(&ctxt);
    throw;
  }
  exr_finish(&ctxt);
}

// Walks the attributes of every header (OpenEXR file layout: magic, version, then per header
// name\0 type\0 int32 size and the value, a \0 after the last attribute; multipart files
// have one header per part and a \0 after the last header) and refuses an attribute whose
// declared size is larger than what is left of the file. OpenEXR's C++ reader allocates an
// attribute of unknown type (Imf::OpaqueAttribute) at its declared size before reading it: a
// 302-byte file declaring 1.7 GB made it allocate that (found by scripts/fuzz exr). What this
// walk cannot follow (a name without its \0, the end of the file) is left to the reader.
void check_attribute_sizes(const std::string& path, unsigned long long file_bytes) {
  std::ifstream f(path, std::ios::binary);
  unsigned char head[8];
  if (!f.read(reinterpret_cast<char*>(head), 8)) return;
  const bool multipart = head[5] & 0x10;  // version flags, bit 12: multipart
  const auto read_string = [&](std::string& out) {
    out.clear();
    for (char c; f.get(c);) {
      if (c == '\0') return true;
      if (out.size() == 255) return false;  // longer than any name OpenEXR allows
      out += c;
    }
    return false;
  };
  std::string name, type;
  for (;;) {  // headers
    for (;;) {  // attributes
      if (!read_string(name)) return;
      if (name.empty()) break;  // the header's end
      unsigned char b[4];
      if (!read_string(type) || !f.read(reinterpret_cast<char*>(b), 4)) return;
      const long long size = std::int32_t(std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 |
                                          std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24);
      const long long at = f.tellg();
      if (at < 0) return;
      if (size < 0 || static_cast<unsigned long long>(at) + size > file_bytes)
        throw InputError(path, "truncated or corrupt: the header's attribute '" + name +
                                   "' (" + type + ") declares " + std::to_string(size) +
                                   " bytes, but the file has " +
                                   std::to_string(file_bytes - static_cast<unsigned long long>(at)) +
                                   " left");
      f.seekg(size, std::ios::cur);
    }
    if (!multipart || f.peek() == 0) return;  // one header, or the empty one after the last
  }
}

/// Runs decode(state, chunk) for chunks [0, chunks) on as many threads as exr_threads' pool has
/// (each chunk once), this one among them, each thread with its own state from make_state();
/// stops handing out chunks once one returns false. False when any did.
template <class MakeState, class Decode>
bool on_io_threads(int chunks, const MakeState& make_state, const Decode& decode) {
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  const auto work = [&] {
    auto state = make_state();
    for (int c; !failed && (c = next++) < chunks;)
      if (!decode(state, c)) failed = true;
  };
  const int extra = std::min(exr_threads(), chunks) - 1;
  std::vector<std::thread> workers;
  try {
    for (int t = 0; t < extra; ++t) workers.emplace_back(work);
  } catch (const std::system_error&) {
    // fewer threads: the ones started and this one share the chunks
  }
  work();
  for (auto& w : workers) w.join();
  return !failed;
}

/// The data window of part 0 of `ctxt`, its lines per chunk and chunk count, when they agree
/// with `img`.
bool chunk_layout(exr_const_context_t ctxt, const Image& img, exr_attr_box2i_t& dw,
                  int32_t& lines, int32_t& chunks) {
  return exr_get_data_window(ctxt, 0, &dw) == EXR_ERR_SUCCESS &&
         exr_get_scanlines_per_chunk(ctxt, 0, &lines) == EXR_ERR_SUCCESS &&
         exr_get_chunk_count(ctxt, 0, &chunks) == EXR_ERR_SUCCESS && lines > 0 &&
         (long long)dw.max.x - dw.min.x + 1 == img.width() &&
         (long long)dw.max.y - dw.min.y + 1 == img.height();
}

/// Where R, G, B and A go in a pixel (-1: a channel read past).
int rgba_index(const char* name) {
  static const char* const kNames[kChannels] = {"R", "G", "B", "A"};
  for (int i = 0; i < kChannels; ++i)
    if (std::strcmp(name, kNames[i]) == 0) return i;
  return -1;
}

/// Where a channel goes in a pixel when alpha is read only `alpha` (-1: read past).
int placed_index(const char* name, bool alpha) {
  const int at = rgba_index(name);
  return at == 3 && !alpha ? -1 : at;
}

/// The channels R, G, B and A of a single-part scanline file, FLOAT and not subsampled (the
/// other channels skipped), read through OpenEXRCore into `img` (the data window's size), the
/// chunks decoded on as many threads as exr_threads' pool has. OpenEXR 3.1's C++ reader copies
/// each line into the frame buffer through a generic per-value loop; Core's unpackers do it in
/// a fraction of the time (docs/design.md, "Scanline EXR files are decoded by OpenEXRCore where
/// it is faster than OpenEXR's C++ reader; no EXR codec is bloomref's own"). False, with `img`
/// in any state, when Core cannot decode the file: the C++ reader then reads it and reports the
/// problem in its words.
bool read_core(const std::string& path, bool alpha, Image& img) {
  exr_context_t ctxt = open_silently(path);
  if (!ctxt) return false;
  exr_attr_box2i_t dw{};
  int32_t lines = 0, chunks = 0;
  bool ok = chunk_layout(ctxt, img, dw, lines, chunks);
  // One decoding pipeline per thread, kept from chunk to chunk.
  struct Pipe {
    exr_const_context_t ctxt;
    exr_decode_pipeline_t pipe{};  // all zeros, as EXR_DECODE_PIPELINE_INITIALIZER ({0}) makes it
    bool started = false;
    ~Pipe() {
      if (started) exr_decoding_destroy(ctxt, &pipe);
    }
  };
  const auto decode = [&](Pipe& p, int c) {
    exr_chunk_info_t ci{};
    if (exr_read_scanline_chunk_info(ctxt, 0, dw.min.y + c * lines, &ci) != EXR_ERR_SUCCESS ||
        (p.started ? exr_decoding_update(ctxt, 0, &ci, &p.pipe)
                   : exr_decoding_initialize(ctxt, 0, &ci, &p.pipe)) != EXR_ERR_SUCCESS)
      return false;
    p.started = true;
    float* row = img.data() + static_cast<std::size_t>(ci.start_y - dw.min.y) *
                                  static_cast<std::size_t>(img.width()) * kChannels;
    for (int k = 0; k < p.pipe.channel_count; ++k) {
      exr_coding_channel_info_t& ch = p.pipe.channels[k];
      const int at = placed_index(ch.channel_name, alpha);
      ch.decode_to_ptr = at < 0 ? nullptr : reinterpret_cast<uint8_t*>(row + at);
      ch.user_pixel_stride = sizeof(float) * kChannels;
      ch.user_line_stride = ch.user_pixel_stride * img.width();
      ch.user_bytes_per_element = sizeof(float);
      ch.user_data_type = EXR_PIXEL_FLOAT;
    }
    return exr_decoding_choose_default_routines(ctxt, 0, &p.pipe) == EXR_ERR_SUCCESS &&
           exr_decoding_run(ctxt, 0, &p.pipe) == EXR_ERR_SUCCESS;
  };
  ok = ok && on_io_threads(chunks, [&] { return Pipe{ctxt}; }, decode);
  exr_finish(&ctxt);
  if (!ok) return false;
  if (!alpha) fill_alpha(img);
  return true;
}

/// Whether OpenEXRCore's reader (read_core) takes part `chosen` of `file`: the only part,
/// scanline, with R, G and B (A optional) in FLOAT, none subsampled, compressed by a lossless
/// method OpenEXR offers (none, RLE, ZIPS, ZIP, PIZ). Not HALF: OpenEXRCore 3.1 converts a file
/// of exactly the four half channels A, B, G, R (RenderDoc's EXR save of a 16-bit float target)
/// to float in reverse channel order (tests/io/test_io.cpp writes that file). PXR24, B44 and DWA,
/// and everything else, are left to the C++ reader.
bool core_reads(const Imf::MultiPartInputFile& file, int chosen) {
  if (file.parts() != 1 || chosen != 0) return false;
  const Imf::Header& h = file.header(0);
  if (h.hasTileDescription() || (h.hasType() && h.type() != Imf::SCANLINEIMAGE)) return false;
  int colour = 0;
  for (auto it = h.channels().begin(); it != h.channels().end(); ++it) {
    const Imf::Channel& c = it.channel();
    const int at = rgba_index(it.name());
    if (at < 0) continue;
    if (c.xSampling != 1 || c.ySampling != 1 || c.type != Imf::FLOAT) return false;
    colour += at < 3;
  }
  if (colour != 3) return false;
  switch (h.compression()) {
    case Imf::NO_COMPRESSION:
    case Imf::RLE_COMPRESSION:
    case Imf::ZIPS_COMPRESSION:
    case Imf::ZIP_COMPRESSION:
    case Imf::PIZ_COMPRESSION:
      return true;
    default:
      return false;
  }
}

}  // namespace

bool has_exr_magic(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char magic[4] = {};
  if (!f.read(magic, 4)) return false;
  return Imf::isImfMagic(magic);
}

void fill_alpha(Image& img) {
  float* p = img.data();
  for (std::size_t i = 0, n = img.pixel_count(); i < n; ++i) p[i * kChannels + 3] = 1.0f;
}

LoadedImage load_exr(const std::string& path, const SizeLimits& limits, bool rgb_only) {
  LoadedImage out;
  ImageInfo& info = out.info;
  info.path = path;
  info.format = "exr";
  unsigned long long bytes = ~0ull;
  {
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    if (f) bytes = static_cast<unsigned long long>(f.tellg());
    check_attribute_sizes(path, bytes);
    check_part_sizes(path, limits, bytes);
  }
  try {
    Imf::MultiPartInputFile file(path.c_str(), exr_threads());
    const int parts = file.parts();
    int chosen = -1;
    PartChannels pc;
    std::string seen;
    for (int i = 0; i < parts && chosen < 0; ++i) {
      const Imf::Header& h = file.header(i);
      if (h.hasType() && Imf::isDeepData(h.type())) continue;
      pc = classify(h);
      if (usable(pc)) chosen = i;
      else seen += (seen.empty() ? "" : "; ") + ("part " + std::to_string(i) + ": " + join(pc.all));
    }
    if (chosen < 0)
      throw InputError(path, "unsupported channel layout: no part has R, G, B or Y channels (" +
                                 (seen.empty() ? std::string("no flat image parts") : seen) +
                                 ")");
    const Imf::Header& h = file.header(chosen);
    const Imath::Box2i dw = h.dataWindow();
    const long long w = (long long)dw.max.x - dw.min.x + 1, ht = (long long)dw.max.y - dw.min.y + 1;
    check_size(path, w, ht, limits);
    info.data_window = to_window(path, "data window", dw);
    info.display_window = to_window(path, "display window", h.displayWindow());
    info.has_alpha = pc.alpha;
    info.channels = join(pc.all);
    info.layout = (parts > 1 ? "part " + std::to_string(chosen) + " of " + std::to_string(parts)
                             : std::string("single part")) +
                  (h.hasTileDescription()
                       ? (h.tileDescription().mode == Imf::ONE_LEVEL ? ", tiled"
                                                                     : ", tiled multi-level (level 0)")
                       : ", scanline");

    // The file's alpha, unless the caller reads R, G and B alone: then alpha is 1.
    const bool alpha = pc.alpha && !rgb_only;
    if (core_reads(file, chosen)) {
      Image fast = Image::uninitialised(static_cast<int>(w), static_cast<int>(ht));
      if (read_core(path, alpha, fast)) {
        out.image = std::move(fast);
        return out;
      }
    }
    out.image = Image(static_cast<int>(w), static_cast<int>(ht));
    float* base = out.image.data();
    const std::size_t xs = sizeof(float) * kChannels, ys = xs * static_cast<std::size_t>(w);

    if (pc.chroma) {
      // Luminance/chroma (Y, RY, BY, possibly subsampled): RgbaInputFile reconstructs RGB.
      if (chosen != 0)
        throw InputError(path, "luminance/chroma channels are supported in part 0 only");
      info.layout += ", luminance/chroma reconstructed to RGB";
      Imf::RgbaInputFile rgba(path.c_str(), exr_threads());
      Imf::Array2D<Imf::Rgba> px(ht, w);
      rgba.setFrameBuffer(&px[0][0] - dw.min.x - (long)dw.min.y * w, 1, w);
      rgba.readPixels(dw.min.y, dw.max.y);
      for (long long y = 0; y < ht; ++y)
        for (long long x = 0; x < w; ++x) {
          float* d = base + (y * w + x) * kChannels;
          const Imf::Rgba& s = px[y][x];
          d[0] = s.r; d[1] = s.g; d[2] = s.b; d[3] = alpha ? float(s.a) : 1.0f;
        }
      return out;
    }

    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) {
      const std::string n = it.name();
      const bool wanted = n == "R" || n == "G" || n == "B" || n == "A" || n == pc.single;
      if (wanted && (it.channel().xSampling != 1 || it.channel().ySampling != 1))
        throw InputError(path, "channel " + n + " is subsampled, which is supported only for "
                                            "luminance/chroma (Y, RY, BY) files");
    }
    Imf::FrameBuffer fb;
    const Imf::PixelType F = Imf::FLOAT;
    if (!pc.single.empty()) {
      fb.insert(pc.single, Imf::Slice::Make(F, base, dw, xs, ys, 1, 1, 0.0));
    } else {
      fb.insert("R", Imf::Slice::Make(F, base, dw, xs, ys, 1, 1, 0.0));
      fb.insert("G", Imf::Slice::Make(F, base + 1, dw, xs, ys, 1, 1, 0.0));
      fb.insert("B", Imf::Slice::Make(F, base + 2, dw, xs, ys, 1, 1, 0.0));
    }
    fb.insert("A", Imf::Slice::Make(F, base + 3, dw, xs, ys, 1, 1, 1.0));
    Imf::InputPart part(file, chosen);
    part.setFrameBuffer(fb);
    part.readPixels(dw.min.y, dw.max.y);
    if (pc.alpha && !alpha) fill_alpha(out.image);
    if (!pc.single.empty()) {
      info.layout += ", one channel (" + pc.single + ") read as grey";
      for (std::size_t i = 0; i < out.image.pixel_count(); ++i)
        base[i * kChannels + 1] = base[i * kChannels + 2] = base[i * kChannels];
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path, std::string("cannot read this OpenEXR file: ") + e.what());
  }
  return out;
}

namespace {

// OpenEXR's output stream over a stdio stream (the pending file of output_files.h).
class StdioOStream : public Imf::OStream {
 public:
  StdioOStream(std::FILE* f, const std::string& name) : Imf::OStream(name.c_str()), f_(f) {}
  void write(const char c[], int n) override {
    if (std::fwrite(c, 1, static_cast<std::size_t>(n), f_) != static_cast<std::size_t>(n))
      throw std::runtime_error(std::strerror(errno));
  }
  uint64_t tellp() override { return static_cast<uint64_t>(::ftello(f_)); }
  void seekp(uint64_t pos) override {
    if (::fseeko(f_, static_cast<off_t>(pos), SEEK_SET) != 0)
      throw std::runtime_error(std::strerror(errno));
  }

 private:
  std::FILE* f_;
};

}  // namespace

void write_exr_stream(std::FILE* f, const std::string& name, ConstImageView img,
                      const ImageInfo* windows, ExrCompression compression) {
  // The windows (io.h): the input's when the image is its data window's size, checked again
  // here for callers that make their own; otherwise both the image at the origin.
  Imf::Header header(img.width, img.height);
  if (windows && windows->data_window.width() == img.width &&
      windows->data_window.height() == img.height) {
    const auto box = [&](const Window& w, const char* which) {
      const Window c = make_window(name, std::string("input's ") + which, w.x0, w.y0,
                                   (long long)w.x1 - w.x0 + 1, (long long)w.y1 - w.y0 + 1);
      return Imath::Box2i({c.x0, c.y0}, {c.x1, c.y1});
    };
    header.dataWindow() = box(windows->data_window, "data window");
    const Window& v = windows->display_window;
    header.displayWindow() = v.width() > 0 && v.height() > 0 ? box(v, "display window")
                                                              : header.dataWindow();
  }
  // Every choice lossless; the figures behind each are in docs/design.md, "EXR compression".
  header.compression() = compression == ExrCompression::piz    ? Imf::PIZ_COMPRESSION
                         : compression == ExrCompression::zip  ? Imf::ZIP_COMPRESSION
                         : compression == ExrCompression::zips ? Imf::ZIPS_COMPRESSION
                         : compression == ExrCompression::rle  ? Imf::RLE_COMPRESSION
                                                               : Imf::NO_COMPRESSION;
  for (const char* c : {"R", "G", "B", "A"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
  const Imath::Box2i dw = header.dataWindow();
  // OpenEXR takes non-const pointers for writing too; it only reads through them.
  char* base = reinterpret_cast<char*>(const_cast<float*>(img.data));
  const std::size_t xs = sizeof(float) * kChannels, ys = xs * static_cast<std::size_t>(img.stride);
  Imf::FrameBuffer fb;
  const char* names[] = {"R", "G", "B", "A"};
  for (int c = 0; c < 4; ++c)
    fb.insert(names[c], Imf::Slice::Make(Imf::FLOAT, base + c * sizeof(float), dw, xs, ys));
  StdioOStream stream(f, name);
  Imf::OutputFile file(stream, header, exr_threads());
  file.setFrameBuffer(fb);
  file.writePixels(img.height);
}

}  // namespace bloomref::detail
