#include "batch/frames.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <set>

#include "bloomref/error.h"

namespace bloomref::batch {
namespace {

constexpr int kMaxPadding = 16;
constexpr long long kMaxFrame = 1000000000;   // +-1e9: printf'd frames stay within an int
constexpr std::size_t kMaxFrames = 10000000;  // a list longer than this is a typo

// A wildcard found in a name: where it starts, its length and its padding.
struct Wildcard {
  std::size_t at = 0, length = 0;
  int padding = 0;
};

[[noreturn]] void bad_pattern(const std::string& text, const std::string& why) {
  throw ParamError("frame pattern '" + text + "': " + why);
}

// The wildcard starting at text[i], if one does ('#'/'@' runs, "%0Nd", "%d").
std::optional<Wildcard> wildcard_at(const std::string& text, std::size_t i) {
  const char c = text[i];
  if (c == '#' || c == '@') {
    std::size_t j = i;
    while (j < text.size() && (text[j] == '#' || text[j] == '@')) ++j;
    const std::string run = text.substr(i, j - i);
    const bool hashes = run.find('@') == std::string::npos,
               ats = run.find('#') == std::string::npos;
    if (!hashes && !ats) bad_pattern(text, "'" + run + "' mixes '#' and '@'; use one kind");
    if (run.size() > static_cast<std::size_t>(kMaxPadding))
      bad_pattern(text, "'" + run + "' pads to more than " + std::to_string(kMaxPadding) + " digits");
    const int n = static_cast<int>(run.size());
    return Wildcard{i, run.size(), hashes && n == 1 ? 4 : n};
  }
  if (c != '%') return std::nullopt;
  std::size_t j = i + 1;
  while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) ++j;
  if (j >= text.size() || text[j] != 'd') return std::nullopt;  // a literal '%'
  const std::string width = text.substr(i + 1, j - i - 1);
  if (!width.empty() && width[0] != '0')
    bad_pattern(text, "'%" + width + "d' pads with spaces; write '%0" + width + "d'");
  const int padding = width.size() > 1 ? std::stoi(width.substr(1).substr(0, 3)) : 0;
  if (width.size() > 4 || padding > kMaxPadding)
    bad_pattern(text,
                "'%" + width + "d' pads to more than " + std::to_string(kMaxPadding) + " digits");
  return Wildcard{i, j + 1 - i, padding};
}

long long parse_number(const std::string& spec, const std::string& part, const std::string& s) {
  const std::size_t digits = !s.empty() && s[0] == '-' ? 1 : 0;
  if (s.size() == digits || s.size() > digits + 10 ||
      !std::all_of(s.begin() + digits, s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    throw ParamError("--frames '" + spec + "': '" + part +
                     "' is not a frame, a range A-B or a range "
                     "with a step A-BxS (e.g. 1-100x2,120)");
  const long long v = std::stoll(s);
  if (v > kMaxFrame || v < -kMaxFrame)
    throw ParamError("--frames '" + spec + "': " + s +
                     " is beyond the frame numbers bloomref takes "
                     "(-1000000000 to 1000000000)");
  return v;
}

// Splits "A-B" where either number may carry a minus: the separating '-' is the first one after
// the first character.
bool split_range(const std::string& s, std::string& a, std::string& b) {
  const std::size_t dash = s.find('-', 1);
  if (dash == std::string::npos) return false;
  a = s.substr(0, dash);
  b = s.substr(dash + 1);
  return true;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

}  // namespace

FramePattern FramePattern::parse(const std::string& text) {
  FramePattern p;
  p.text_ = text;
  std::optional<Wildcard> found;
  for (std::size_t i = 0; i < text.size();) {
    const std::optional<Wildcard> w = wildcard_at(text, i);
    if (!w) {
      ++i;
      continue;
    }
    if (found)
      bad_pattern(text, "has two frame wildcards ('" + text.substr(found->at, found->length) +
                            "' and '" + text.substr(w->at, w->length) + "'); a name takes one");
    found = w;
    i += w->length;
  }
  if (!found) {
    p.prefix_ = text;
    return p;
  }
  p.wildcard_ = true;
  p.padding_ = found->padding;
  p.prefix_ = text.substr(0, found->at);
  p.suffix_ = text.substr(found->at + found->length);
  return p;
}

std::string FramePattern::frame_text(int frame) const {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%0*d", padding_, frame);
  return buf;
}

std::string FramePattern::name(int frame) const {
  return wildcard_ ? prefix_ + frame_text(frame) + suffix_ : text_;
}

std::optional<int> FramePattern::frame_of(const std::string& name) const {
  if (!wildcard_ || name.size() <= prefix_.size() + suffix_.size()) return std::nullopt;
  if (name.compare(0, prefix_.size(), prefix_) != 0 ||
      name.compare(name.size() - suffix_.size(), suffix_.size(), suffix_) != 0)
    return std::nullopt;
  const std::string mid =
      name.substr(prefix_.size(), name.size() - prefix_.size() - suffix_.size());
  const std::size_t sign = mid[0] == '-' ? 1 : 0;
  const std::size_t digits = mid.size() - sign;
  // Up to 10 significant digits (|frame| <= 1e9), more when the padding asks for zeros.
  if (digits == 0 || digits > static_cast<std::size_t>(std::max(10, padding_)) ||
      static_cast<int>(mid.size()) < padding_ ||
      !std::all_of(mid.begin() + sign, mid.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return std::nullopt;
  const long long v = std::stoll(mid);
  if (v > kMaxFrame || v < -kMaxFrame) return std::nullopt;
  // Only the spelling name() gives: "7" is not frame 7 of "%04d", nor "00007".
  if (frame_text(static_cast<int>(v)) != mid) return std::nullopt;
  return static_cast<int>(v);
}

bool has_frame_wildcard(const std::string& text) {
  try {
    return FramePattern::parse(text).has_wildcard();
  } catch (const ParamError&) {
    return true;  // malformed, but meant as a pattern: parse() will say why
  }
}

std::vector<int> parse_frame_list(const std::string& spec) {
  if (trim(spec).empty())
    throw ParamError("--frames is empty: give frames such as 1-240 or 1-100x2,120");
  std::vector<long long> frames;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = spec.find(',', start);
    const std::string part =
        trim(spec.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (part.empty()) throw ParamError("--frames '" + spec + "': an empty part between commas");
    std::string range = part, a, b;
    long long step = 1;
    bool complement = false;
    const std::size_t x = part.find_first_of("xy");
    if (x != std::string::npos) {
      complement = part[x] == 'y';
      range = part.substr(0, x);
      step = parse_number(spec, part, part.substr(x + 1));
      if (step < 1)
        throw ParamError("--frames '" + spec + "': the step of '" + part + "' must be 1 or more");
    }
    long long first = 0, last = 0;
    if (split_range(range, a, b)) {
      first = parse_number(spec, part, a);
      last = parse_number(spec, part, b);
    } else if (x != std::string::npos) {
      throw ParamError("--frames '" + spec + "': '" + part + "' has a step but no range (A-BxS)");
    } else {
      first = last = parse_number(spec, part, range);
    }
    const long long dir = first <= last ? 1 : -1;
    if ((last - first) * dir + 1 > static_cast<long long>(kMaxFrames))
      throw ParamError("--frames '" + spec + "': '" + part + "' lists more than 10000000 frames");
    for (long long f = first, i = 0;; f += dir, ++i) {
      if ((i % step == 0) != complement) frames.push_back(f);
      if (f == last) break;
    }
    if (frames.size() > kMaxFrames)
      throw ParamError("--frames '" + spec + "' lists more than 10000000 frames");
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  std::sort(frames.begin(), frames.end());
  const auto twice = std::adjacent_find(frames.begin(), frames.end());
  if (twice != frames.end())
    throw ParamError("--frames '" + spec + "': frame " + std::to_string(*twice) +
                     " is listed twice");
  if (frames.empty())
    throw ParamError("--frames '" + spec + "' lists no frame (a 'y' range leaves every frame out)");
  return std::vector<int>(frames.begin(), frames.end());
}

std::string format_frame_list(const std::vector<int>& f) {
  std::string out;
  for (std::size_t i = 0; i < f.size();) {
    std::size_t j = i + 1;
    const long long d = j < f.size() ? static_cast<long long>(f[j]) - f[i] : 0;
    while (j < f.size() && static_cast<long long>(f[j]) - f[j - 1] == d) ++j;
    const std::size_t n = j - i;  // f[i..j) steps by d
    if (!out.empty()) out += ",";
    if (n >= 3 || (n == 2 && d == 1)) {
      out += std::to_string(f[i]) + "-" + std::to_string(f[j - 1]);
      if (d != 1) out += "x" + std::to_string(d);
      i = j;
    } else {
      out += std::to_string(f[i]);
      ++i;
    }
  }
  return out;
}

}  // namespace bloomref::batch
