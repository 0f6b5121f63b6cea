// libFuzzer target: bloomref merge's reading of results files (cli/batch/merge.h). The input is
// up to four JSON documents separated by lines "----", each one shard's results file (of `run`
// over frames or of `check`). A document that is not JSON is skipped (the command refuses it
// earlier, naming the file). A bad file must come out as an InputError naming it (exit 2); any
// other exception (exit 4), a crash, a leak or undefined behaviour is a finding, and so is a
// merge whose exit code is 0 while it reports items missing or run twice.
#include <cstdint>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "batch/merge.h"
#include "bloomref/error.h"

namespace batch = bloomref::batch;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 65536) return 0;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<batch::ResultsFile> files;
  std::size_t start = 0;
  while (start <= text.size() && files.size() < 4) {
    std::size_t cut = text.find("\n----\n", start);
    if (cut == std::string::npos) cut = text.size();
    nlohmann::ordered_json doc =
        nlohmann::ordered_json::parse(text.substr(start, cut - start), nullptr, false);
    if (!doc.is_discarded())
      files.push_back({"shard" + std::to_string(files.size() + 1) + ".json", std::move(doc)});
    start = cut + 6;
  }
  if (files.empty()) return 0;
  try {
    const batch::Merged m = batch::merge_results(files);
    if ((!m.missing.empty() || !m.duplicates.empty()) && m.exit_code == 0) std::abort();
    (void)batch::merged_junit(m);
    (void)batch::merged_markdown(m);
    (void)batch::merged_html(m, {"a", "0001"});
  } catch (const bloomref::Error&) {
  }
  return 0;
}
