#include "arrays.h"

#include <algorithm>
#include <cstdint>
#include <mutex>
#include <utility>

#include "bloomref/error.h"
#include "bloomref/io.h"

namespace py = pybind11;

namespace bloomref::python {
namespace {

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// Whole 16-byte pixels, rows of whole pixels, float32 in this machine's byte order.
bool viewable(const py::array& a) {
  constexpr py::ssize_t pixel = kChannels * sizeof(float);
  return a.dtype().is(py::dtype::of<float>()) && a.shape(2) == kChannels &&
         a.strides(2) == sizeof(float) && a.strides(1) == pixel && a.strides(0) > 0 &&
         a.strides(0) % pixel == 0 && a.strides(0) / pixel >= a.shape(1) &&
         reinterpret_cast<std::uintptr_t>(a.data()) % alignof(float) == 0;
}

// The buffer of the last array Python released (to_array's capsule), for kept_buffer. Runs take
// it without the GIL, capsules give it back with it: a mutex of its own.
struct KeptBuffer {
  std::mutex mutex;
  Image image;
};

KeptBuffer& kept() {
  static KeptBuffer* k = new KeptBuffer;  // never destroyed: capsules may outlive static data
  return *k;
}

}  // namespace

SceneArray scene_array(const py::handle& obj, const std::string& what) {
  SceneArray s;
  if (!py::isinstance<py::array>(obj))
    throw py::value_error(what + ": expected a numpy array of H x W x 4 (or x 3) floats, got " +
                          std::string(py::str(py::type::of(obj).attr("__name__"))));
  s.array = py::reinterpret_borrow<py::array>(obj);
  const py::array& a = s.array;
  if (a.ndim() != 3 || (a.shape(2) != 3 && a.shape(2) != 4))
    throw py::value_error(what + ": shape " + shape_text(a) +
                          " is not H x W x 4 (RGBA) or H x W x 3 (RGB)");
  if (a.dtype().kind() != 'f')
    throw py::value_error(what + ": dtype " + std::string(py::str(a.dtype())) +
                          " is not floating point (float32, float64 or float16)");
  const int h = static_cast<int>(std::min<py::ssize_t>(a.shape(0), 1 << 30));
  const int w = static_cast<int>(std::min<py::ssize_t>(a.shape(1), 1 << 30));
  if (w < 1 || h < 1) throw py::value_error(what + ": shape " + shape_text(a) + " is empty");
  try {
    check_size(what, a.shape(1), a.shape(0), SizeLimits{});
  } catch (const InputError& e) {
    throw py::value_error(e.what());
  }
  if (viewable(a)) {
    s.view = {w, h, a.strides(0) / py::ssize_t(kChannels * sizeof(float)),
              static_cast<const float*>(a.data())};
    return s;
  }
  // float32, C order: numpy converts (any dtype, any strides) in one pass.
  const auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!f) throw py::error_already_set();
  const int channels = static_cast<int>(a.shape(2));
  s.copy = Image(w, h, 1.0f);
  const float* src = f.data();
  float* dst = s.copy.data();
  const std::size_t n = std::size_t(w) * h;
  if (channels == kChannels) {
    std::copy(src, src + n * kChannels, dst);
  } else {
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) dst[i * kChannels + c] = src[i * 3 + c];
  }
  s.view = s.copy.cview();
  s.copied = true;
  return s;
}

// The name of to_array's capsules, by which out_array knows an array whose buffer is an Image.
constexpr const char* kImageCapsule = "bloomref.image";

OutArray out_array(const py::handle& obj, int width, int height, const std::string& what) {
  if (!py::isinstance<py::array>(obj))
    throw py::value_error(what + ": expected a numpy array, got " +
                          std::string(py::str(py::type::of(obj).attr("__name__"))));
  OutArray o;
  o.array = py::reinterpret_borrow<py::array>(obj);
  const py::array& a = o.array;
  const std::string wanted = "(" + std::to_string(height) + ", " + std::to_string(width) + ", 4)";
  if (a.ndim() != 3 || a.shape(0) != height || a.shape(1) != width || a.shape(2) != kChannels)
    throw py::value_error(what + ": shape " + shape_text(a) + " is not the output's, " + wanted);
  if (!a.dtype().is(py::dtype::of<float>()))
    throw py::value_error(what + ": dtype " + std::string(py::str(a.dtype())) +
                          " is not float32");
  if (!(a.flags() & py::array::c_style))
    throw py::value_error(what + ": not C-contiguous (the output is written whole, row by row)");
  if (!a.writeable()) throw py::value_error(what + ": read-only");
  o.data = static_cast<float*>(o.array.mutable_data());
  const py::object base = a.base();
  if (base && PyCapsule_IsValid(base.ptr(), kImageCapsule)) {
    auto* img = static_cast<Image*>(PyCapsule_GetPointer(base.ptr(), kImageCapsule));
    if (img && img->data() == o.data && img->width() == width && img->height() == height)
      o.image = img;
  }
  return o;
}

py::array to_array(Image&& image) {
  auto* owner = new Image(std::move(image));
  py::capsule release(owner, [](void* p) {
    Image* img = static_cast<Image*>(p);
    Image old;  // freed outside the lock
    {
      std::lock_guard<std::mutex> lock(kept().mutex);
      old = std::move(kept().image);
      kept().image = std::move(*img);
    }
    delete img;
  });
  if (PyCapsule_SetName(release.ptr(), kImageCapsule) != 0) throw py::error_already_set();
  const py::ssize_t w = owner->width(), h = owner->height();
  constexpr py::ssize_t f = sizeof(float);
  return py::array_t<float>({h, w, py::ssize_t(kChannels)}, {w * kChannels * f, kChannels * f, f},
                            owner->data(), release);
}

Image kept_buffer(int width, int height) {
  std::lock_guard<std::mutex> lock(kept().mutex);
  Image& k = kept().image;
  if (k.empty() || k.width() != width || k.height() != height) return Image();
  return std::exchange(k, Image());  // a moved-from image keeps its size: left empty instead
}

}  // namespace bloomref::python
