// numpy arrays and bloomref images: a scene viewed in place where its layout allows, and images
// handed to numpy without a copy.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "bloomref/image.h"

namespace bloomref::python {

/// A scene given as an array: `view` reads it in place when it is float32, 4 channels, with
/// whole pixels of 16 bytes and rows of whole pixels (C-contiguous H x W x 4, or a crop of
/// one); any other float array of H x W x 3 or H x W x 4 is converted into `copy` (alpha 1
/// where there is none), and `view` reads that. `array` keeps the caller's array alive.
struct SceneArray {
  pybind11::array array;
  Image copy;
  ConstImageView view;
  bool copied = false;
};

/// ValueError (naming `what` and the problem) for anything but a floating-point array of
/// H x W x 3 or H x W x 4 within io.h's size limits.
SceneArray scene_array(const pybind11::handle& obj, const std::string& what);

/// The image as a float32 H x W x 4 array that owns its buffer (no copy). When Python releases
/// the array, its buffer is kept for kept_buffer (one buffer at most: the last released).
pybind11::array to_array(Image&& image);

/// The array `out=` names, checked (ValueError naming `what`): a writeable float32 array of
/// height x width x 4 in C order. `image` is the bloomref image whose buffer it is (an array
/// to_array made, whole), or null: such a buffer can be handed to the executor and taken back.
struct OutArray {
  pybind11::array array;
  Image* image = nullptr;
  float* data = nullptr;
};
OutArray out_array(const pybind11::handle& obj, int width, int height, const std::string& what);

/// The kept buffer of the last array Python released, when it is `width` x `height` (else an
/// empty image), for the executor to write its output into (executor.h): a loop of runs at one
/// size then writes into pages already mapped, where a new buffer pays a page fault per page
/// on its first write (docs/design.md, "Nothing is written where nothing is"). Callable without
/// the GIL.
Image kept_buffer(int width, int height);

}  // namespace bloomref::python
