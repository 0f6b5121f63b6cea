// bloomref engine — support tracking for the adaptive plan: which texels of the bright image and
// of each blur pass may differ from +0, so that the passes skip the rest with the same bits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "bloomref/stages.h"

namespace bloomref {

/// The texels whose RGB is not +0 in every channel (bit-exact: -0, NaN and Inf count), as a
/// width x height mask. Returns how many.
template <class T>
std::size_t nonzero_support(BasicView<const T> img, std::uint8_t* mask, int threads);

/// The support of a blur pass's output given its input's: a texel is set when any texel one of
/// its lookups may read (both texels of every tap, both rows across) is set in `in`. Uses the
/// pass's own tap tables, so it is exact for this pass's coordinates. Returns how many are set.
template <class T>
std::size_t blur_support(const std::uint8_t* in, std::uint8_t* out, int width, int height,
                         const BlurPassOptions& opt, int threads);

/// The set texels of a width x height mask (0 or 1 per texel) as spans per row. Returns how many.
/// With `rows` (one entry a row), a row whose entry is 0 is taken as empty without reading it.
std::size_t mask_spans(const std::uint8_t* mask, int width, int height, RowSpans& out,
                       int threads, const std::uint8_t* rows = nullptr);

/// blur_support on spans: the same set (tested), in time proportional to the spans. Each pass's
/// lookups read a contiguous range of positions along the blur whose ends never decrease with
/// the position, and one or two adjacent lines across it: an input span maps to an output span
/// found by two binary searches. Returns how many are set, or nothing when a pass's tables lack
/// that shape (then use blur_support).
template <class T>
std::optional<std::size_t> blur_support_spans(const RowSpans& in, RowSpans& out, int width,
                                              int height, const BlurPassOptions& opt,
                                              int threads);

/// The adaptive plan's support through the blur passes, one tracker for the CPU and the GL
/// executors: the bright image's nonzero texels, then each pass's blur_support_spans (as spans,
/// with a mask kept equal to them for the consumers that read texels). The support only
/// grows; once it covers more than `dense_fraction` of the image, tracking it costs more than it
/// saves (scripts/adaptive-table), so the tracker stops and says so: whole passes from there.
class BlurSupportTracker {
 public:
  BlurSupportTracker(int width, int height, double dense_fraction)
      : width_(width), height_(height), dense_fraction_(dense_fraction) {}
  /// Pass 1's input, the bright image (read once, on the first advance).
  template <class T>
  void start(BasicView<const T> bright, int threads);
  /// Pass 1's input support given directly as a mask (extract_bright's `nonzero`); rows whose
  /// entry in `rows` (optional) is 0 are empty.
  void start(std::vector<std::uint8_t>&& support, int threads,
             const std::uint8_t* rows = nullptr);
  bool started() const { return !mask_.empty(); }
  /// This pass's output support, width x height, row-major; nullptr once dense. T chooses the
  /// tap tables (f32: the shader's coordinates; f64: exact taps).
  template <class T>
  const std::uint8_t* advance(const BlurPassOptions& opt, int threads);
  bool dense() const { return dense_; }
  /// Set texels of the last pass's support (the whole image once dense).
  std::size_t count() const { return count_; }
  /// The last pass's support as spans per row (the same set as advance's mask); nullptr once
  /// dense.
  const RowSpans* spans() const { return dense_ ? nullptr : &spans_; }

 private:
  int width_, height_;
  double dense_fraction_;
  bool dense_ = false;
  std::size_t count_ = 0;
  // The support is tracked as spans; the mask is kept equal to them by clearing the old spans
  // and setting the new ones (both in proportion to the support, not to the image).
  std::vector<std::uint8_t> mask_;
  RowSpans spans_, next_;
};

}  // namespace bloomref
