// bloomref — images and views.
//
// Conventions shared by every bloomref function (read once here):
//  * Pixels are linear, scene-referred RGBA, 4 interleaved channels per pixel.
//  * Row 0 is the top row; the centre of texel (x, y) is at (x + 0.5, y + 0.5).
//  * Outside the image, sampling clamps to the edge (GL_CLAMP_TO_EDGE).
//  * Row ranges are half-open [y0, y1).
//  * `threads = 0` means all hardware threads, `1` runs serially; every result is bit-identical
//    for any thread count.
//  * Errors come back as exceptions derived from bloomref::Error (see error.h); nothing is
//    clamped silently.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "bloomref/pixel_memory.h"

namespace bloomref {

constexpr int kChannels = 4;


/// The allocator of image buffers. Every buffer starts on a 64-byte (cache line) boundary, so
/// that a row whose byte length is a multiple of 32 starts every 32-byte vector load of the blur
/// kernels inside one cache line (malloc's large blocks start 16 bytes into a page: half of those
/// loads straddled two lines). Elements are default-initialised: `PixelBuffer<float>(n)` leaves
/// the values unwritten (for a producer that writes them all); BasicImage's constructor fills.
template <class T>
struct CacheAlignedAllocator {
  using value_type = T;
  CacheAlignedAllocator() = default;
  template <class U>
  CacheAlignedAllocator(const CacheAlignedAllocator<U>&) {}
  T* allocate(std::size_t n) { return static_cast<T*>(allocate_pixels(n * sizeof(T))); }
  void deallocate(T* p, std::size_t n) noexcept { free_pixels(p, n * sizeof(T)); }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0) ::new (static_cast<void*>(p)) U;  // default-init
    else ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U>
  bool operator==(const CacheAlignedAllocator<U>&) const { return true; }
  template <class U>
  bool operator!=(const CacheAlignedAllocator<U>&) const { return false; }
};

/// The pixel buffer of an image: contiguous values, cache-line aligned.
template <class T>
using PixelBuffer = std::vector<T, CacheAlignedAllocator<T>>;

/// A non-owning view of RGBA pixels, passed by value. `stride` counts pixels per row.
template <class T>
struct BasicView {
  int width = 0;
  int height = 0;
  std::ptrdiff_t stride = 0;
  T* data = nullptr;

  T* row(int y) const { return data + static_cast<std::ptrdiff_t>(y) * stride * kChannels; }
  T* pixel(int x, int y) const { return row(y) + static_cast<std::ptrdiff_t>(x) * kChannels; }
  bool empty() const { return width <= 0 || height <= 0; }
};

/// An owning RGBA image with a flat, tightly packed buffer (what OpenEXR, OIIO and
/// glReadPixels read and write directly).
template <class T>
class BasicImage {
 public:
  using value_type = T;
  BasicImage() = default;
  BasicImage(int width, int height, T fill = T(0))
      : width_(width), height_(height),
        pixels_(static_cast<std::size_t>(width) * height * kChannels, fill) {}

  /// An image whose values are not written (for a destination its producer fills whole).
  static BasicImage uninitialised(int width, int height) {
    BasicImage img;
    img.width_ = width;
    img.height_ = height;
    img.pixels_ = PixelBuffer<T>(static_cast<std::size_t>(width) * height * kChannels);
    return img;
  }

  /// An image of +0 in every channel, alpha included, whose pages are only materialised where
  /// they are written (zero_lazily): for a destination written in a few places.
  static BasicImage zeroed(int width, int height) {
    BasicImage img = uninitialised(width, height);
    zero_lazily(img.pixels_.data(), img.pixels_.size() * sizeof(T));
    return img;
  }

  int width() const { return width_; }
  int height() const { return height_; }
  std::size_t pixel_count() const { return static_cast<std::size_t>(width_) * height_; }
  bool empty() const { return pixels_.empty(); }

  T* data() { return pixels_.data(); }
  const T* data() const { return pixels_.data(); }
  PixelBuffer<T>& values() { return pixels_; }
  const PixelBuffer<T>& values() const { return pixels_; }

  T* pixel(int x, int y) { return view().pixel(x, y); }
  const T* pixel(int x, int y) const { return cview().pixel(x, y); }

  BasicView<T> view() { return {width_, height_, width_, pixels_.data()}; }
  BasicView<const T> view() const { return cview(); }
  BasicView<const T> cview() const { return {width_, height_, width_, pixels_.data()}; }

 private:
  int width_ = 0;
  int height_ = 0;
  PixelBuffer<T> pixels_;
};

using Image = BasicImage<float>;
using ImageF64 = BasicImage<double>;
using ImageView = BasicView<float>;
using ConstImageView = BasicView<const float>;

/// Element-wise conversion between precisions (float -> double is exact).
template <class To, class From>
BasicImage<To> convert_image(BasicView<const From> src) {
  BasicImage<To> out(src.width, src.height);
  for (int y = 0; y < src.height; ++y) {
    const From* s = src.row(y);
    To* d = out.view().row(y);
    for (int i = 0; i < src.width * kChannels; ++i) d[i] = static_cast<To>(s[i]);
  }
  return out;
}

}  // namespace bloomref
