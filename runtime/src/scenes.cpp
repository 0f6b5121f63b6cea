#include "bloomref/scenes.h"

#include <cmath>
#include <cstdint>
#include <functional>

#include "bloomref/error.h"
#include "bloomref/parallel.h"

namespace bloomref {
namespace {

// Deterministic value noise in [0, 1) (integer hash; no global RNG state).
float hash01(std::uint32_t x, std::uint32_t y, std::uint32_t seed) {
  std::uint32_t h = x * 0x8da6b343u ^ y * 0xd8163841u ^ seed * 0xcb1ab31fu;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return static_cast<float>(h & 0xffffffu) / 16777216.0f;
}

// Every pixel from its coordinates alone, so rows are filled in parallel (all hardware threads),
// as a large scene is slow to fill on one, with the same result as in order.
void fill(Image& img, const std::function<void(int, int, float*)>& f) {
  parallel_rows(img.height(), 0, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < img.width(); ++x) f(x, y, img.pixel(x, y));
  });
}

void set(float* p, float r, float g, float b) {
  p[0] = r; p[1] = g; p[2] = b; p[3] = 1.0f;
}

// The seeds' demo (seed 000): a dark, textured room with four coloured light cubes whose
// colours are LearnOpenGL's lightColors (5,5,5), (10,0,0), (0,0,15), (0,5,0) -- luminance 5,
// 2.126, 1.083 and 3.576, all above the default threshold of 1; the blue one is cut by the right
// edge (clamp-to-edge matters there) -- and lit wooden crates whose faces stay below the
// threshold (sub-threshold detail the bloom must not pick up), one with a label exactly at it.
Image demo(int w, int h) {
  Image img(w, h);
  const float s = std::min(w, h) / 720.0f;
  fill(img, [&](int x, int y, float* p) {
    // Floor planks: stripes with grain, dark (0.01 .. 0.12).
    const float plank = std::floor(y / (36.0f * s));
    const float grain = 0.5f + 0.5f * std::sin(x * 0.05f / s + plank * 1.7f + 3.0f * hash01(x / 8, y / 8, 1));
    const float v = 0.015f + 0.06f * grain + 0.02f * hash01(x, y, 2);
    const bool seam = std::fmod(y, 36.0f * s) < 1.5f * s;
    const float k = seam ? 0.3f : 1.0f;
    set(p, v * 1.2f * k, v * 0.8f * k, v * 0.5f * k);
  });
  auto box = [&](float cx, float cy, float half, const std::function<void(float, float, float*)>& f) {
    const int x0 = std::max(0, int((cx - half) * w)), x1 = std::min(w, int((cx + half) * w) + 1);
    const float hh = half * w / h;
    const int y0 = std::max(0, int((cy - hh) * h)), y1 = std::min(h, int((cy + hh) * h) + 1);
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x)
        f(float(x - x0) / std::max(1, x1 - x0 - 1), float(y - y0) / std::max(1, y1 - y0 - 1),
          img.pixel(x, y));
  };
  // Crates: container texture, lit up to ~0.8 -- below the threshold everywhere.
  const float crates[][3] = {{0.22f, 0.62f, 0.07f}, {0.55f, 0.72f, 0.06f}, {0.78f, 0.40f, 0.05f}};
  for (const auto& c : crates)
    box(c[0], c[1], c[2], [&](float u, float v, float* p) {
      const bool rim = u < 0.08f || u > 0.92f || v < 0.08f || v > 0.92f;
      const float shade = 0.35f + 0.45f * (1.0f - v) * (0.6f + 0.4f * hash01(int(u * 40), int(v * 40), 3));
      if (rim) set(p, 0.25f * shade, 0.25f * shade, 0.27f * shade);
      else set(p, 0.62f * shade, 0.41f * shade, 0.20f * shade);
    });
  // A white label on the middle crate at exactly (1, 1, 1): luminance 1, a tie with the default
  // threshold (not bright; `>=` would make it so).
  box(0.55f, 0.70f, 0.012f, [&](float, float, float* p) { set(p, 1.0f, 1.0f, 1.0f); });
  const float lights[][6] = {{0.12f, 0.25f, 0.018f, 5.0f, 5.0f, 5.0f},
                             {0.42f, 0.30f, 0.014f, 10.0f, 0.0f, 0.0f},
                             {0.985f, 0.18f, 0.016f, 0.0f, 0.0f, 15.0f},  // cut by the edge
                             {0.66f, 0.55f, 0.012f, 0.0f, 5.0f, 0.0f}};
  for (const auto& l : lights)
    box(l[0], l[1], l[2], [&](float u, float v, float* p) {
      // Faces of a lit cube: slightly brighter centre, darker edges.
      const float f = 0.85f + 0.15f * (1.0f - std::fabs(u - 0.5f) - std::fabs(v - 0.5f));
      set(p, l[3] * f, l[4] * f, l[5] * f);
    });
  return img;
}

Image impulse(int w, int h) {
  Image img(w, h);
  fill(img, [](int, int, float* p) { set(p, 0, 0, 0); });
  set(img.pixel(w / 2, h / 2), 10.0f, 10.0f, 10.0f);
  return img;
}

Image constant(int w, int h) {
  Image img(w, h);
  fill(img, [](int, int, float* p) { set(p, 2.0f, 2.0f, 2.0f); });
  return img;
}

Image hot_edge(int w, int h) {
  Image img(w, h);
  fill(img, [](int x, int y, float* p) {
    const float v = 0.05f + 0.02f * hash01(x, y, 4);
    set(p, v, v, v);
  });
  set(img.pixel(0, h / 2), 50.0f, 40.0f, 30.0f);         // left edge
  set(img.pixel(w - 1, h - 1), 30.0f, 40.0f, 50.0f);     // bottom-right corner
  return img;
}

// Luminance of (1, 1, 1) is exactly 1 in f32 (left to right: 0.2126f + 0.7152f = 0.9278f,
// + 0.0722f = 1.0f) and in f64: a tie with the default threshold, so not bright. Beside it the
// next float up (bright) and the next float down (not bright).
Image threshold_tie(int w, int h) {
  Image img(w, h);
  const float up = std::nextafter(1.0f, 2.0f), down = std::nextafter(1.0f, 0.0f);
  fill(img, [&](int x, int, float* p) {
    const int band = 3 * x / w;
    const float v = band == 0 ? 1.0f : band == 1 ? up : down;
    set(p, v, v, v);
  });
  return img;
}

// Dense: gamma noise (shape 2, scale 0.35: a sum of two exponentials from the hash; about 22% of
// its pixels above the default threshold, P(X > 1) = e^-2.857 (1 + 2.857)) on every row, and 40
// sources (discs of radius 1.5-6 pixels, red 2-20) placed by the hash. The adaptive plan's
// worst case: bright pixels everywhere, so tracking the blur's support saves nothing.
Image noise(int w, int h) {
  Image img(w, h);
  fill(img, [](int x, int y, float* p) {
    const float u1 = 1.0f - hash01(x, y, 5), u2 = 1.0f - hash01(x, y, 6);  // in (0, 1]
    const float v = -0.35f * (std::log(u1) + std::log(u2));
    set(p, v, 0.9f * v, 0.8f * v);
  });
  for (std::uint32_t i = 0; i < 40; ++i) {
    const int cx = int(hash01(i, 0, 7) * w), cy = int(hash01(i, 1, 7) * h);
    const float r = 1.5f + 4.5f * hash01(i, 2, 7), v = 2.0f + 18.0f * hash01(i, 3, 7);
    for (int y = std::max(0, int(cy - r)); y <= std::min(h - 1, int(cy + r)); ++y)
      for (int x = std::max(0, int(cx - r)); x <= std::min(w - 1, int(cx + r)); ++x)
        if (float((x - cx) * (x - cx) + (y - cy) * (y - cy)) <= r * r)
          set(img.pixel(x, y), v, v * (0.5f + 0.5f * hash01(i, 4, 7)),
              v * (0.5f + 0.5f * hash01(i, 5, 7)));
  }
  return img;
}

struct Entry {
  SceneInfo info;
  Image (*make)(int, int);
};

const std::vector<Entry>& entries() {
  static const std::vector<Entry> e = {
      {{"demo", "the seeds' demo: four light cubes (luminance 1.08 to 5, colours 5..15) on a dark, "
                "detailed room with sub-threshold crates", 1280, 720}, demo},
      {{"impulse", "one pixel of (10, 10, 10) at the centre of black: the blur's impulse response",
        63, 63}, impulse},
      {{"constant", "every pixel (2, 2, 2): a constant field the blur must keep constant", 64, 48},
       constant},
      {{"hot-edge", "hot pixels at the middle of the left edge and at the bottom-right corner "
                    "(clamp-to-edge)", 96, 64}, hot_edge},
      {{"threshold-tie", "three bands of luminance exactly 1, one float above and one below "
                         "(threshold strictness)", 96, 32}, threshold_tie},
      {{"noise", "dense: gamma noise (about 22% of the pixels above the threshold, on every row) "
                 "and 40 sources (brightness 2 to 20): the adaptive plan's worst case", 383, 257},
       noise},
  };
  return e;
}

}  // namespace

const std::vector<SceneInfo>& scene_list() {
  static const std::vector<SceneInfo> list = [] {
    std::vector<SceneInfo> l;
    for (const Entry& e : entries()) l.push_back(e.info);
    return l;
  }();
  return list;
}

Image make_scene(const std::string& name, int width, int height) {
  for (const Entry& e : entries()) {
    if (e.info.name != name) continue;
    const int w = width > 0 ? width : e.info.width, h = height > 0 ? height : e.info.height;
    if (w > 65536 || h > 65536 || static_cast<long long>(w) * h > (1LL << 27))
      throw ParamError("scene size " + std::to_string(w) + "x" + std::to_string(h) +
                       " is beyond the limits (65536 per side, 2^27 pixels)");
    return e.make(w, h);
  }
  std::string known;
  for (const Entry& e : entries()) known += (known.empty() ? "" : ", ") + e.info.name;
  throw ParamError("unknown scene '" + name + "'; the built-in scenes are: " + known);
}

}  // namespace bloomref
