// OpenEXR's inverse 2-D wavelet (the second stage of PIZ), its finest level 8 values at a time
// (internal to io).
#pragma once

#include <cstdint>

namespace bloomref::detail {

/// Decodes, in place, a channel block of a PIZ chunk: `lines` rows of `width` values, each
/// value `words` 16-bit words side by side (1 for HALF, 2 for FLOAT), every word position
/// wavelet-coded on its own, as OpenEXR's wav2Decode (ImfWav.cpp) decodes each word position
/// with x step `words` and y step `width * words`; `max` is the largest word index (under 2^14:
/// the 14-bit transform, else the 16-bit one). The same values as wav2Decode, word for word.
void wavelet_decode_block(std::uint16_t* block, int width, int words, int lines,
                          std::uint16_t max);

}  // namespace bloomref::detail
