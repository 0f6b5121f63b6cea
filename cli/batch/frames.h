// Frame sequences as oiiotool names them: a file or folder name with one frame-number wildcard,
// and a frame list such as "1-100x2,120".
//
// Conventions of this folder (cli/batch/): pure functions over strings and JSON, no files, no
// environment; bad input throws bloomref::ParamError whose message names the value and the
// problem (the CLI turns it into exit 2). Frames are ints; lists come back sorted, no frame twice.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace bloomref::batch {

/// A name with one frame-number wildcard:
/// - `%0Nd` (printf: N digits, zero-padded) or `%d` (no padding);
/// - `@` runs: one digit of padding per `@` (oiiotool, FCheck);
/// - `#` runs: a lone `#` is four digits (oiiotool's `#`); a run of several is one digit per `#`
///   (`####` = 4 digits, as Nuke, RV, Houdini and Deadline read it; oiiotool would read
///   `####` as 16 digits, which no one writes on purpose).
/// A frame with more digits than the padding is written in full; a negative one as printf
/// writes it (`-001`).
class FramePattern {
 public:
  /// ParamError for two wildcards, `#` and `@` mixed in one run, `%Nd` without the zero (spaces
  /// in file names) or a width over 16. A name without a wildcard gives has_wildcard() false.
  static FramePattern parse(const std::string& text);

  bool has_wildcard() const { return wildcard_; }
  const std::string& text() const { return text_; }
  int padding() const { return padding_; }
  /// The name of `frame` (the text itself when there is no wildcard).
  std::string name(int frame) const;
  /// The frame number a file name stands for, or nullopt when it does not match (digits in place
  /// of the wildcard, at least `padding` of them, an optional leading minus).
  std::optional<int> frame_of(const std::string& name) const;
  /// The frame as the wildcard writes it, without prefix and suffix ("0042").
  std::string frame_text(int frame) const;

 private:
  std::string text_, prefix_, suffix_;
  int padding_ = 0;
  bool wildcard_ = false;
};

/// Whether `text` holds a frame-number wildcard (parse(text).has_wildcard(), never throwing).
bool has_frame_wildcard(const std::string& text);

/// Parses oiiotool's frame list: comma-separated parts, each `A`, `A-B` (inclusive; B < A counts
/// down, the same frames), `A-BxS` (every S-th frame from A) or `A-ByS` (the frames `A-BxS`
/// leaves out). Numbers may be negative (`-10--2x2`). ParamError naming the part and the problem:
/// an empty part, a non-number, a step below 1, a frame listed twice, more than 10 million
/// frames, a number beyond +-1e9.
std::vector<int> parse_frame_list(const std::string& spec);

/// The frames as a compact list ("1-10,12,20-30x5"): the inverse of parse_frame_list for a
/// sorted list, used in messages and results.
std::string format_frame_list(const std::vector<int>& frames);

}  // namespace bloomref::batch
