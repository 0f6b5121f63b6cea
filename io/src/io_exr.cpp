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
#include "huffman.h"
#include "wavelet.h"
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
/// a fraction of the time (1920x1080 float, two threads: uncompressed ~15 against ~90 ms, ZIP
/// ~106 against ~166 ms). False, with `img` in any state, when Core cannot decode the file: the
/// C++ reader then reads it and reports the problem in its words.
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

// PIZ, read through bloomref's own Huffman and wavelet decoders (huffman.h: OpenEXR's looks
// codes of more than 12 bits up length by length, and those are most of a FLOAT stage's;
// wavelet.h: its finest level 8 words at a time), with each decoded chunk put into the image
// directly: OpenEXR's C++ reader would copy it value by value through its generic loop. A PIZ
// chunk (OpenEXR's PizCompressor; "OpenEXR File Layout", PIZ) holds the byte range [lo, hi] of a 65536-bit bitmap of the 16-bit words that occur, that range, the length
// of the Huffman-coded data and the data. Decoded, it is the channels one after another (in the
// file's order), each a block of its rows with every value's 16-bit words side by side (one for
// HALF, two for FLOAT and UINT, the low word first), each word position wavelet-coded on its
// own, every word an index into the words the bitmap holds. A chunk no smaller than its raw
// size is stored raw: line after line, each the channels' values in turn, little-endian.

/// A channel of a PIZ file: 16-bit words per value, where it goes in a pixel (-1: skipped).
struct WordChannel {
  int words = 2;
  int at = -1;
  bool half = false;
};

struct PizScratch {
  std::vector<std::uint8_t> packed;
  std::vector<std::uint16_t> words, lut;
  HufScratch huf;
};

/// Decodes the PIZ chunk in[0, n) of `lines` rows of `width` into s.words (channel blocks, as
/// above), each word still its index into s.lut. False where the chunk is inconsistent;
/// OpenEXR's decoders throw on corrupt data.
bool piz_words(const std::uint8_t* in, std::size_t n, const std::vector<WordChannel>& channels,
               int width, int lines, std::size_t total, PizScratch& s) {
  constexpr std::size_t kBitmapBytes = 65536 / 8;
  const auto u16 = [in](std::size_t at) { return unsigned(in[at]) | unsigned(in[at + 1]) << 8; };
  if (n < 4) return false;
  const unsigned lo = u16(0), hi = u16(2);
  std::size_t at = 4;
  std::array<std::uint8_t, kBitmapBytes> bitmap{};
  if (lo <= hi) {
    if (hi >= kBitmapBytes || n - at < hi - lo + 1) return false;
    std::memcpy(bitmap.data() + lo, in + at, hi - lo + 1);
    at += hi - lo + 1;
  }
  // Index k of the decoded words stands for the k-th word the bitmap holds (0 always); indices
  // past the last (corrupt data) for 0.
  s.lut.assign(65536, 0);
  unsigned k = 1;
  for (unsigned byte = lo; byte <= hi && byte < kBitmapBytes; ++byte)
    for (unsigned bit = 0, b = bitmap[byte]; b; ++bit, b >>= 1)
      if ((b & 1) && (byte != 0 || bit != 0))
        s.lut[k++] = static_cast<std::uint16_t>(byte * 8 + bit);
  const auto max_index = static_cast<std::uint16_t>(k - 1);
  if (n - at < 4) return false;
  const std::uint32_t length = u16(at) | std::uint32_t(u16(at + 2)) << 16;
  at += 4;
  if (length > n - at || length > std::uint32_t(INT32_MAX) || total > std::size_t(INT32_MAX))
    return false;
  s.words.resize(total);
  if (!huf_decode(in + at, length, s.words.data(), total, s.huf)) return false;
  std::size_t start = 0;
  for (const WordChannel& c : channels) {  // a channel read past needs no wavelet
    if (c.at >= 0) wavelet_decode_block(s.words.data() + start, width, c.words, lines, max_index);
    start += std::size_t(c.words) * width * lines;
  }
  return true;
}

/// The channels R, G, B and A of a file fast_reader gives to read_piz, into `img` (the data
/// window's size), the chunks decoded on as many threads as exr_threads' pool has; without
/// `alpha`, A is read past (not decoded) and alpha is 1. False, with `img` in any state, when a
/// chunk cannot be decoded: the C++ reader then reads the file and reports the problem in its
/// words.
bool read_piz(const std::string& path, bool alpha, Image& img) {
  exr_context_t ctxt = open_silently(path);
  if (!ctxt) return false;
  exr_attr_box2i_t dw{};
  int32_t lines = 0, chunks = 0;
  const exr_attr_chlist_t* list = nullptr;
  bool ok = chunk_layout(ctxt, img, dw, lines, chunks) &&
            exr_get_channels(ctxt, 0, &list) == EXR_ERR_SUCCESS && list;
  std::vector<WordChannel> channels;
  int words = 0;  // per pixel, every channel
  for (int i = 0; ok && i < list->num_channels; ++i) {
    const exr_attr_chlist_entry_t& e = list->entries[i];
    const bool half = e.pixel_type == EXR_PIXEL_HALF;
    channels.push_back({half ? 1 : 2, placed_index(e.name.str, alpha), half});
    words += channels.back().words;
    ok = e.x_sampling == 1 && e.y_sampling == 1;
  }
  const int width = img.width();
  const auto decode = [&](PizScratch& s, int c) {
    exr_chunk_info_t ci{};
    if (exr_read_scanline_chunk_info(ctxt, 0, dw.min.y + c * lines, &ci) != EXR_ERR_SUCCESS)
      return false;
    const int rows = ci.height;
    const std::size_t total = std::size_t(words) * width * std::size_t(rows);
    if (rows <= 0 || ci.start_y < dw.min.y || (long long)ci.start_y + rows - 1 > dw.max.y ||
        ci.unpacked_size != 2 * total || ci.packed_size > ci.unpacked_size)
      return false;
    s.packed.resize(ci.packed_size);
    if (exr_read_chunk(ctxt, 0, &ci, s.packed.data()) != EXR_ERR_SUCCESS) return false;
    const bool raw = ci.packed_size == ci.unpacked_size;
    try {
      if (raw) {
        s.words.resize(total);
        for (std::size_t i = 0; i < total; ++i)
          s.words[i] = static_cast<std::uint16_t>(s.packed[2 * i] | s.packed[2 * i + 1] << 8);
      } else if (!piz_words(s.packed.data(), s.packed.size(), channels, width, rows, total, s)) {
        return false;
      }
    } catch (const std::exception&) {
      return false;
    }
    // Channel block by block (PIZ) or line by line (raw): where row 0 of each channel starts,
    // and the step from row to row.
    static const std::vector<std::uint16_t> identity = [] {
      std::vector<std::uint16_t> v(65536);
      for (unsigned i = 0; i < 65536; ++i) v[i] = static_cast<std::uint16_t>(i);
      return v;
    }();
    const std::uint16_t* lut = raw ? identity.data() : s.lut.data();
    const std::uint16_t* first[kChannels] = {};
    std::size_t step[kChannels] = {};
    bool half_at[kChannels] = {};
    std::size_t start = 0;
    for (const WordChannel& ch : channels) {
      const std::size_t row_words = std::size_t(ch.words) * width;
      if (ch.at >= 0) {
        first[ch.at] = s.words.data() + start;
        step[ch.at] = raw ? std::size_t(words) * width : row_words;
        half_at[ch.at] = ch.half;
      }
      start += raw ? row_words : row_words * rows;
    }
    for (int y = 0; y < rows; ++y) {
      const std::uint16_t* w[kChannels];
      for (int i = 0; i < kChannels; ++i) w[i] = first[i] ? first[i] + y * step[i] : nullptr;
      float* out = img.data() + std::size_t(ci.start_y - dw.min.y + y) * width * kChannels;
      for (int x = 0; x < width; ++x, out += kChannels)
        for (int i = 0; i < kChannels; ++i) {
          if (!w[i]) {
            if (i == 3) out[3] = 1.0f;  // no alpha read: 1, in the same pass
            continue;
          }
          if (half_at[i]) {
            half h;
            h.setBits(lut[w[i][x]]);
            out[i] = h;
          } else {
            const std::uint32_t bits =
                std::uint32_t(lut[w[i][2 * x]]) | std::uint32_t(lut[w[i][2 * x + 1]]) << 16;
            std::memcpy(out + i, &bits, sizeof bits);
          }
        }
    }
    return true;
  };
  ok = ok && on_io_threads(chunks, [] { return PizScratch{}; }, decode);
  exr_finish(&ctxt);
  return ok;
}

/// The faster reader of part `chosen` of `file`, where there is one. Both take the only part,
/// scanline, with R, G and B (A optional), none subsampled:
/// - read_piz PIZ files in HALF or FLOAT, every channel unsubsampled (its chunk layout);
/// - read_core FLOAT files uncompressed or compressed by RLE, ZIPS or ZIP. Not HALF:
///   OpenEXRCore 3.1 converts a file of exactly the four half channels A, B, G, R (RenderDoc's
///   EXR save of a 16-bit float target) to float in reverse channel order (tests/test_io.cpp
///   writes that file). Core 3.1's Huffman decoder is the slower one, hence read_piz.
/// PXR24, B44 and DWA are left to the C++ reader.
enum class FastReader { none, core, piz };
FastReader fast_reader(const Imf::MultiPartInputFile& file, int chosen) {
  if (file.parts() != 1 || chosen != 0) return FastReader::none;
  const Imf::Header& h = file.header(0);
  if (h.hasTileDescription() || (h.hasType() && h.type() != Imf::SCANLINEIMAGE))
    return FastReader::none;
  const bool piz = h.compression() == Imf::PIZ_COMPRESSION;
  int colour = 0;
  for (auto it = h.channels().begin(); it != h.channels().end(); ++it) {
    const Imf::Channel& c = it.channel();
    const bool sampled = c.xSampling == 1 && c.ySampling == 1;
    const int at = rgba_index(it.name());
    if (at < 0) {
      if (piz && !sampled) return FastReader::none;
      continue;
    }
    if (!sampled || c.type == Imf::UINT || (!piz && c.type != Imf::FLOAT)) return FastReader::none;
    colour += at < 3;
  }
  if (colour != 3) return FastReader::none;
  switch (h.compression()) {
    case Imf::PIZ_COMPRESSION:
      return FastReader::piz;
    case Imf::NO_COMPRESSION:
    case Imf::RLE_COMPRESSION:
    case Imf::ZIPS_COMPRESSION:
    case Imf::ZIP_COMPRESSION:
      return FastReader::core;
    default:
      return FastReader::none;
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
    if (const FastReader reader = fast_reader(file, chosen); reader != FastReader::none) {
      Image fast = Image::uninitialised(static_cast<int>(w), static_cast<int>(ht));
      if (reader == FastReader::piz ? read_piz(path, alpha, fast)
                                    : read_core(path, alpha, fast)) {
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
                      const ImageInfo* windows) {
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
  // PIZ (lossless: wavelet + Huffman): on the demo scene's 3840x2160 output 82 MB against ZIP's
  // 89 MB, written in ~1.35 s against ~2.0 s on two threads, read as fast.
  header.compression() = Imf::PIZ_COMPRESSION;
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
