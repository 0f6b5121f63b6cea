#include "corpus.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "bloomref/scenes.h"

namespace bloomref::test {

std::vector<std::string> corpus_files() {
  std::vector<std::string> files;
  const char* dir = std::getenv("BLOOMREF_CORPUS");
  if (!dir || !*dir || !std::filesystem::is_directory(dir)) return files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (ext == ".exr" || ext == ".hdr") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<std::pair<std::string, Image>> scenes_and_corpus(
    std::vector<std::pair<std::string, Image>> extra) {
  std::vector<std::pair<std::string, Image>> inputs;
  for (const SceneInfo& s : scene_list()) inputs.emplace_back(s.name, make_scene(s.name));
  for (const std::string& f : corpus_files())
    inputs.emplace_back(std::filesystem::path(f).filename().string(), load_image(f).image);
  for (auto& e : extra) inputs.push_back(std::move(e));
  return inputs;
}

Image run_output(const Image& scene, const BloomParams& p) {
  return execute(make_plan(p, scene.cview()), scene.cview()).final_image();
}

Image constant_image(int w, int h, float v) {
  Image img(w, h);
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    float* p = img.data() + i * kChannels;
    p[0] = p[1] = p[2] = v;
    p[3] = 1.0f;
  }
  return img;
}

double max_abs_diff(ConstImageView a, ConstImageView b) {
  double m = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double u = a.pixel(x, y)[c], v = b.pixel(x, y)[c];
        if (std::isfinite(u) && std::isfinite(v)) m = std::max(m, std::fabs(u - v));
      }
  return m;
}

bool bit_identical(ConstImageView a, ConstImageView b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y)
    if (std::memcmp(a.row(y), b.row(y), sizeof(float) * kChannels * a.width) != 0) return false;
  return true;
}

bool same_bits_nan_agnostic(ConstImageView a, ConstImageView b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y) {
    const float* p = a.row(y);
    const float* q = b.row(y);
    for (int i = 0; i < a.width * kChannels; ++i) {
      if (std::isnan(p[i]) && std::isnan(q[i])) continue;
      if (std::memcmp(p + i, q + i, sizeof(float)) != 0) return false;
    }
  }
  return true;
}

std::size_t count_nan(ConstImageView img) {
  std::size_t n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int i = 0; i < img.width * kChannels; ++i) n += std::isnan(img.row(y)[i]);
  return n;
}

}  // namespace bloomref::test
