// libFuzzer target: the sequence options' text (cli/batch/): frame-name patterns, frame lists
// and shard specifications with the job engines' variables. The input is split at newlines:
// line 1 a frame pattern, line 2 a frame list, line 3 a --shard argument, line 4 a
// --shard-count, the rest NAME=VALUE variables. A bad value must come out as a ParamError
// (exit 2); anything else, or a broken property below, is a finding:
// - a pattern names each frame with a name it reads back as that frame;
// - format_frame_list and parse_frame_list are inverses on a parsed (sorted) list;
// - a shard's positions are ascending, inside the list, and the shards of a count cover every
//   position once.
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "batch/frames.h"
#include "batch/shard.h"
#include "bloomref/error.h"

namespace batch = bloomref::batch;

namespace {

std::vector<std::string> lines_of(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> lines;
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  while (lines.size() < 4) lines.emplace_back();
  return lines;
}

void check_pattern(const std::string& text, const std::vector<int>& frames) {
  const batch::FramePattern p = batch::FramePattern::parse(text);
  if (!p.has_wildcard()) return;
  for (int f : frames) {
    const std::optional<int> back = p.frame_of(p.name(f));
    if (!back || *back != f) std::abort();  // a name that does not read back as its frame
  }
}

void check_list(const std::vector<int>& frames) {
  for (std::size_t i = 1; i < frames.size(); ++i)
    if (frames[i - 1] >= frames[i]) std::abort();  // not sorted, or a frame twice
  if (frames.size() > 100000) return;              // formatting is linear; keep runs fast
  if (batch::parse_frame_list(batch::format_frame_list(frames)) != frames) std::abort();
}

void check_shard(const std::string& arg, const std::string& count_text,
                 const batch::Environment& env) {
  int count = 0;
  if (!count_text.empty()) {
    char* end = nullptr;
    const long v = std::strtol(count_text.c_str(), &end, 10);
    if (*end || v < 0 || v > 1000000) return;  // the CLI's integer option refuses these itself
    count = static_cast<int>(v);
  }
  const std::optional<batch::Shard> shard = batch::resolve_shard(arg, count, env);
  if (!shard) return;
  if (shard->count < 1 || shard->index < 0 || shard->index >= shard->count) std::abort();
  const std::size_t items = 97;
  std::vector<int> seen(items, 0);
  for (int k = 0; k < shard->count && k < 200; ++k) {
    batch::Shard s = *shard;
    s.index = k;
    std::size_t last = 0;
    bool first = true;
    for (std::size_t pos : batch::shard_positions(items, s)) {
      if (pos >= items || (!first && pos <= last)) std::abort();
      ++seen[pos];
      last = pos;
      first = false;
    }
  }
  if (shard->count <= 200)
    for (int n : seen)
      if (n != 1) std::abort();  // an item in no shard, or in two
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;
  const std::vector<std::string> lines = lines_of(data, size);
  std::vector<int> frames;
  try {
    frames = batch::parse_frame_list(lines[1]);
    check_list(frames);
  } catch (const bloomref::Error&) {
  }
  if (frames.size() > 1000) frames.resize(1000);
  try {
    check_pattern(lines[0], frames.empty() ? std::vector<int>{0, 1, -7, 1234567} : frames);
  } catch (const bloomref::Error&) {
  }
  batch::Environment env;
  for (std::size_t i = 4; i < lines.size(); ++i) {
    const std::size_t eq = lines[i].find('=');
    if (eq != std::string::npos) env[lines[i].substr(0, eq)] = lines[i].substr(eq + 1);
  }
  try {
    check_shard(lines[2], lines[3], env);
  } catch (const bloomref::Error&) {
  }
  return 0;
}
