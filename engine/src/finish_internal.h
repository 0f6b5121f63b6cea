// bloomref — what the fast f32 finishing stages (composite, tonemap, output) share between
// stages_fast.cpp and the per-ISA row kernels (finish_kernels.inc).
#pragma once

#include <cstddef>

#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"

namespace bloomref::detail {

/// What one row goes through: composite when bloom is given, then the tone map and the output
/// encoding where asked.
struct FinishRow {
  float strength = 1.0f;
  bool tonemap = false;
  float exposure = 1.0f;
  bool encode = false;
  float inv_gamma = 1.0f;  ///< 1 / gamma computed in float, as encode_output does
  /// With tonemap and encode and a bloom given in spans: the finished value (tone map, output)
  /// of every binary16 value, indexed by its bit pattern (65536 floats; finish_fast). Outside
  /// the spans a pixel whose values s + strength * +0 are all binary16 values is finished from
  /// it instead of computed.
  const float* table = nullptr;
};

/// Pixels [x0, x1) of a row, packed into the scratch line from pixel k0 on.
struct PackedRun {
  int x0, x1;
  std::size_t k0;
};

/// Floats of the scratch line a row of `width` pixels needs: its RGB values padded to whole
/// vectors of the widest kernel.
inline std::size_t finish_line_floats(int width) {
  return (static_cast<std::size_t>(width) * 3 + 15) / 16 * 16;
}
/// Floats the scratch line has after finish_line_floats(width): its two-pixel packing and
/// unpacking store and load eight floats for six.
constexpr std::size_t kFinishLineSlack = 8;

/// The bloom of one row: its pixels, and with `in_spans`, the only places its R, G and B may
/// differ from +0 (spans[0, span_count), sorted, disjoint; none: the row is +0): elsewhere the
/// composite adds strength * +0 without reading it.
struct BloomRow {
  const float* pixels = nullptr;
  bool in_spans = false;
  const Span* spans = nullptr;
  std::size_t span_count = 0;
};

/// One row of `width` RGBA pixels: scene (+ strength * bloom when bloom.pixels is not null),
/// tone mapped, encoded, into dst (which may be scene); alpha is the scene's. `line` is scratch
/// of finish_line_floats(width) + kFinishLineSlack floats, `runs` of `width` runs (raw
/// buffers: the per-ISA kernels instantiate no std::vector member, see blur_internal.h,
/// `TileScratch`). Returns the pixels finished from job.table.
using FinishKernel = int (*)(const FinishRow& job, const float* scene, const BloomRow& bloom,
                             float* dst, int width, float* line, PackedRun* runs);

int finish_row_generic(const FinishRow&, const float*, const BloomRow&, float*, int, float*,
                       PackedRun*);
int finish_row_avx2(const FinishRow&, const float*, const BloomRow&, float*, int, float*,
                    PackedRun*);
int finish_row_avx512(const FinishRow&, const float*, const BloomRow&, float*, int, float*,
                      PackedRun*);

}  // namespace bloomref::detail
