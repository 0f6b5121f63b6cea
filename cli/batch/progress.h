// What a batch prints while it runs: on a terminal one line redrawn in place (frames done, per
// second, time left), otherwise one line per item. These functions only format; the caller
// chooses the stream and when to print.
#pragma once

#include <cstddef>
#include <string>

namespace bloomref::batch {

/// "0.4s", "12s", "3m05s", "2h07m": seconds as a person reads a duration.
std::string format_duration(double seconds);

/// The bar: "[=======>            ]  37/240 frames  2.41/s  1m24s left" in `width` columns at most
/// (the bar shrinks first). The rate is items done over `elapsed` seconds and the time left
/// assumes it holds; both read "--" before the first item is done. `noun` names the items.
std::string progress_bar(std::size_t done, std::size_t total, double elapsed, int width,
                         const std::string& noun = "frames");

}  // namespace bloomref::batch
