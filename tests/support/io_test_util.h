// Small EXR files for the I/O and command-line tests, written with OpenEXR directly (not through
// the code under test).
#pragma once

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.h"

namespace bloomref::test {

/// Writes a float EXR (no compression unless given) with the named channels, all holding
/// `values` (one value per pixel, row-major), through OpenEXR.
inline void write_test_exr(const std::string& path, int width, int height,
                           const std::vector<std::string>& channels,
                           const std::vector<float>& values,
                           Imf::Compression compression = Imf::NO_COMPRESSION) {
  Imf::Header header(width, height);
  header.compression() = compression;
  for (const auto& c : channels) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
  Imf::FrameBuffer fb;
  char* base = reinterpret_cast<char*>(const_cast<float*>(values.data()));
  for (const auto& c : channels)
    fb.insert(c, Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * width));
  Imf::OutputFile file(path.c_str(), header);
  file.setFrameBuffer(fb);
  file.writePixels(height);
}

/// Writes a valid 8x8 EXR (no compression) through OpenEXR, then rewrites the bytes of its
/// dataWindow attribute to (0, 0) - (xmax, ymax): a header that claims far more than the file.
inline void write_forged_window_exr(const std::string& path, std::int32_t xmax, std::int32_t ymax) {
  write_test_exr(path, 8, 8, {"R", "G", "B"}, std::vector<float>(64, 1.0f));
  std::string bytes = read_bytes(path);
  // Attribute layout: name\0 type\0 int32 size, then the value (box2i: xmin ymin xmax ymax),
  // little-endian in the file as on the machines this runs on.
  const std::string key("dataWindow\0box2i\0", 17);
  const auto at = bytes.find(key);
  if (at == std::string::npos) throw std::runtime_error("no dataWindow attribute in " + path);
  const std::size_t value = at + key.size() + 4;
  std::memcpy(&bytes[value + 8], &xmax, 4);
  std::memcpy(&bytes[value + 12], &ymax, 4);
  write_bytes(path, bytes);
}

}  // namespace bloomref::test
