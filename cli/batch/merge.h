// bloomref merge: the results files of a sharded run (one per shard, from `run` over frames or
// from `check`) made into one, with every item of the whole list accounted for exactly once.
//
// Each results file carries the whole item list ("batch.item_ids") and the items it ran
// ("items", each with its "id"): an id that no file has is missing, one that two files have was
// run twice. Both make the merge fail (exit 2), because a split that loses or repeats work must
// not pass. Files of different runs (another tool, item list or parameters) are refused.
#pragma once

#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

namespace bloomref::batch {

struct ResultsFile {
  std::string name;  ///< the path, as messages name it
  nlohmann::ordered_json doc;
};

struct Merged {
  /// The shards' format ("bloomref run" sequence results, or check's JSON version 1), with the
  /// items of every shard in the order of the item list, each naming its "shard" and
  /// "results_file"; "batch" lists the shards, "missing" and "duplicates"; "summary", "verdict"
  /// (check) and "exit_code" are recomputed over all items.
  nlohmann::ordered_json doc;
  std::vector<std::string> missing;     ///< ids no file has
  std::vector<std::string> duplicates;  ///< ids more than one file has
  std::vector<std::string> problems;    ///< one line each: missing, run twice, a shard unfinished
  int exit_code = 0;                    ///< 2 when there are problems, else from the items
};

/// InputError naming the file when a file is not a results file with an item list, or not of
/// the same run as the first (tool, item list, parameters other than threads).
Merged merge_results(const std::vector<ResultsFile>& files);

/// JUnit XML of a merged document: a testsuite per item (check: a testcase per stage; run: one
/// testcase), an <error> for each item that could not be run and for each missing one.
std::string merged_junit(const Merged& m);

/// A short Markdown summary (a CI job's summary page): the verdict, the problems, the items that
/// failed or are missing.
std::string merged_markdown(const Merged& m);

/// One self-contained HTML page: the verdict, the problems, and a row per item; items whose id
/// is in `item_reports` link to "<id>/index.html" (check --report into the same folder).
std::string merged_html(const Merged& m, const std::set<std::string>& item_reports = {});

}  // namespace bloomref::batch
