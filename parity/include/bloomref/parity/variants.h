// bloomref parity — the stages with one thing changed, as the usual bloom bugs change them: the
// building blocks of the cause hypotheses (compare.h, CauseFit). Each is a straightforward
// scalar loop in f32, the shaders' operation order; with nothing changed each gives the
// reference stage's bits (tested), so what a hypothesis changes is the change alone.
//
// Conventions as image.h. A Sampling describes the texture unit: filter (GL_LINEAR or
// GL_NEAREST), wrap mode, and a shift of every lookup's coordinate by `shift` texels on both
// axes (a half-texel shift is the classic error of mapping texel corners instead of centres).
#pragma once

#include <vector>

#include "bloomref/image.h"
#include "bloomref/kernel.h"
#include "bloomref/sampler.h"
#include "bloomref/stages.h"

namespace bloomref::parity {

/// border: GL_CLAMP_TO_BORDER with a black border, as a render target larger than the image
/// whose padding is cleared to black reads past the image's edge.
enum class Wrap { clamp_to_edge, repeat, mirrored_repeat, border };

struct Sampling {
  bool nearest = false;
  Wrap wrap = Wrap::clamp_to_edge;
  float shift = 0.0f;  ///< texels added to both coordinates
  int subtexel_bits = 0;
  bool is_default() const { return !nearest && wrap == Wrap::clamp_to_edge && shift == 0.0f; }
};

/// Texel index i on an axis of n texels after the wrap mode (GL 4.6, 8.14.2).
int wrap_index(int i, int n, Wrap wrap);

/// One axis of a lookup at normalised coordinate s, computed in float (sampler.h's gl_axis_tap
/// when the sampling is the default). NEAREST: texel floor(s n), weight 1.
AxisTap<float> variant_axis_tap(float s, int n, const Sampling& smp);

/// Stage blur.k with `offsets` and `weights` (a kernel's, or fitted ones: the same count) and
/// `smp`: blur_pass<float>'s arithmetic. `texel_step` (0: 1 / n along the axis) is the
/// normalised size of one offset unit: seed 001's vertical pass offsets along x by
/// 1 / height (a horizontal pass with texel_step 1 / height).
void blur_pass_variant(ConstImageView src, ImageView dst, Axis axis,
                       const std::vector<float>& offsets, const std::vector<float>& weights,
                       const Sampling& smp, int threads, float texel_step = 0.0f);

/// Stage down.k with `smp`; `tie_kept` false makes the first level drop taps whose luminance
/// equals the threshold (the specification keeps them: L < threshold -> 0). downsample<float>'s
/// arithmetic.
void downsample_variant(ConstImageView src, ImageView dst, bool first, float threshold,
                        bool karis, bool tie_kept, const Sampling& smp, int threads,
                        const LumaRule& luma = {});

/// Stage up.k / bloom with `smp`: upsample_tent<float>'s arithmetic.
void upsample_variant(ConstImageView small, ConstImageView current, ImageView dst,
                      const Sampling& smp, int threads);

/// Stage bright with `>=` in place of `>` (ge), and/or its values clamped to [0, 1].
void extract_bright_variant(ConstImageView src, ImageView dst, float threshold, bool ge,
                            bool clamp01, int threads, const LumaRule& luma = {});

/// Capture transforms (each its own inverse): rows in reverse order; R and B exchanged.
void flip_vertically(Image& img);
void swap_red_blue(Image& img);

}  // namespace bloomref::parity
