// Test helpers: the corpus folder (BLOOMREF_CORPUS) and small image utilities.
#pragma once

#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/params.h"

namespace bloomref::test {

/// Paths of every image in $BLOOMREF_CORPUS (sorted); empty when the variable is unset.
std::vector<std::string> corpus_files();

/// Every built-in scene at its own size, then every corpus image (named by file name), then
/// `extra` -- the inputs of the "on scenes and corpus" tests.
std::vector<std::pair<std::string, Image>> scenes_and_corpus(
    std::vector<std::pair<std::string, Image>> extra = {});

/// The display output of a CPU run with these parameters.
Image run_output(const Image& scene, const BloomParams& p);

/// A w x h image with every pixel set to (v, v, v, 1).
Image constant_image(int w, int h, float v);

/// Max |a - b| over RGB, skipping pixels where either is non-finite.
double max_abs_diff(ConstImageView a, ConstImageView b);

/// True when both images have identical bits in every channel.
bool bit_identical(ConstImageView a, ConstImageView b);

/// bit_identical, except that any NaN equals any NaN. When two NaNs meet (an input NaN and an
/// Inf - Inf), IEEE 754 leaves open which one comes out, and on x86 the compiler may commute
/// an addition's operands, which decides it: sign and payload of NaN are not part of "same bits".
bool same_bits_nan_agnostic(ConstImageView a, ConstImageView b);

/// Count of NaN values over all channels.
std::size_t count_nan(ConstImageView img);

}  // namespace bloomref::test
