// bloomref engine — the adaptive plan's blur of a sparse scene in boxes: each cluster of bright
// pixels is blurred on its own, in buffers the size of its box, so that a run touches memory in
// proportion to the support instead of whole images (blur_boxes.cpp).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "bloomref/engine/fast_stages.h"

namespace bloomref {

/// Texels [x0, x1) x [y0, y1) of the image.
struct Box {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::size_t area() const { return std::size_t(x1 - x0) * std::size_t(y1 - y0); }
};

struct BoxedBlurLayout;  // blur_boxes.cpp

/// Where stages bright and blur.1 ... blur.n of a sparse scene (the adaptive plan, f32, the fast
/// blur) go: the supports of every pass (blur_support_spans from the bright pixels', the same
/// sets the adaptive plan tracks), the tiles each pass computes (those its support touches,
/// blur_pass_fast's listing), and the boxes: rectangles, disjoint, each holding every texel a
/// group of those tiles reads or writes, which no other box's tiles read or write. Inside a
/// box, the passes of its tiles see the values the whole image would hold (+0 outside the
/// supports), so each box is blurred alone with blur_pass_fast's bits.
class BoxedBlur {
 public:
  /// Lays the blur out from the bright pixels' support (sorted, disjoint spans per row: the
  /// texels of stage bright whose RGB is not +0). Empty (`ok()` false) where a pass's tables lack
  /// the spans' shape (blur_support_spans gives nothing), or where the boxes cover more than
  /// `max_fraction` of the image.
  BoxedBlur(int width, int height, RowSpans bright_support, const std::vector<Axis>& axes,
            const Kernel& kernel, int subtexel_bits, double max_fraction, int threads);
  BoxedBlur();  ///< empty
  ~BoxedBlur();
  BoxedBlur(BoxedBlur&&) noexcept;
  BoxedBlur& operator=(BoxedBlur&&) noexcept;

  bool ok() const { return layout_ != nullptr; }
  const std::vector<Box>& boxes() const;
  /// The support after pass k (k = 0: stage bright's), k in [0, n].
  const RowSpans& support(int k) const;
  /// Texels in the support after pass k.
  std::size_t support_count(int k) const;

  /// What the blur hands its boxes to: rows [box.y0, box.y1) of the last pass, columns
  /// [box.x0, box.x1), row box.y0 + i at rows[i], texel box.x0 first (alpha unspecified). Called
  /// once per box, from any thread, boxes in any order, two at once on two threads; the rows are
  /// scratch, valid during the call.
  using Sink = std::function<void(const Box& box, const float* const* rows)>;

  /// Runs it: per box, stage bright of the scene's box (extract_bright's values) into a zeroed
  /// buffer, then every pass over the box's tiles into a second one and back, then `sink`. Small
  /// boxes run side by side, one thread each (their buffers reused from box to box); a box with
  /// a large share of the work runs alone, its passes' tiles shared between the threads.
  /// `bright_rows` (one entry a row, optional): rows without a bright pixel, not read.
  /// `also` (optional): other work for the same threads, also(i) for i in [0, also_items), taken
  /// after the small boxes (the largest first) from one queue, so that no thread waits while
  /// another finishes the last box.
  void run(BasicView<const float> scene, float threshold, const std::uint8_t* bright_rows,
           const Sink& sink, int threads, BlurIsa isa = BlurIsa::best,
           const std::function<void(int)>& also = {}, int also_items = 0) const;

 private:
  std::unique_ptr<BoxedBlurLayout> layout_;
};

/// Stage bright's support as spans per row: the texels with luminance > threshold (extract_bright's
/// test) whose RGB is not +0 (nonzero_support's), scanning only the rows whose `bright_rows`
/// entry (optional) is set. Returns how many.
std::size_t bright_support_spans(BasicView<const float> scene, float threshold,
                                 const std::uint8_t* bright_rows, RowSpans& out, int threads);

/// The texels outside `boxes` as spans per row (height rows of width texels).
RowSpans outside_boxes(const std::vector<Box>& boxes, int width, int height);

}  // namespace bloomref
