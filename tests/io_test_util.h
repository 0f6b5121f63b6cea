// Helpers shared by the I/O and command-line tests: temporary folders, file bytes, the corpus
// folder, and small EXR files written with OpenEXR directly (not through the code under test).
#pragma once

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace bloomref::test {

namespace fs = std::filesystem;

/// A fresh folder under the system temporary folder, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "bloomref-test-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

  /// Names of everything in the folder (not recursive), sorted.
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  fs::path path_;
};

inline std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open " + path);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

inline void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!f) throw std::runtime_error("cannot write " + path);
}

/// The corpus folder (../shared/data/hdr, README.md there) from BLOOMREF_CORPUS, or "" when
/// unset. A relative value is tried from the working folder, then from the repository root.
inline std::string corpus_dir() {
  const char* env = std::getenv("BLOOMREF_CORPUS");
  if (!env || !*env) return "";
  fs::path p(env);
  if (p.is_relative() && !fs::is_directory(p)) p = fs::path(BLOOMREF_SOURCE_DIR) / p;
  if (!fs::is_directory(p)) throw std::runtime_error(std::string("BLOOMREF_CORPUS=") + env + " is not a folder");
  return p.string();
}

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
