// bloomref merge RESULTS.json... : the shards' results as one JSON, JUnit XML, Markdown and HTML
// report, and one exit code (batch/merge.h).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "batch/merge.h"
#include "escape.h"
#include "bloomref/error.h"
#include "bloomref/io.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace bloomref::cli {
namespace {

struct MergeArgs {
  std::vector<std::string> files;
  std::string json_path, junit_path, markdown_path, report_dir;
  bool quiet = false;
};

batch::ResultsFile read_results(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    return {path, nlohmann::ordered_json::parse(ss.str())};
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range (1e999)
    throw InputError(path,
                     std::string("is not valid JSON (a results file cut short?): ") + e.what());
  }
}

int merge(const MergeArgs& a) {
  // Destinations first: none may be a results file being merged, each must be writable.
  for (const std::string* out : {&a.json_path, &a.junit_path, &a.markdown_path})
    if (!out->empty()) {
      for (const std::string& in : a.files) refuse_overwrite(*out, in);
      const fs::path dir = fs::path(*out).parent_path();
      std::error_code ec;
      if (!dir.empty() && !fs::is_directory(dir, ec))
        throw InputError(*out, "cannot be written: the folder " + dir.string() + " does not exist");
    }
  std::vector<batch::ResultsFile> files;
  for (const std::string& f : a.files) files.push_back(read_results(f));
  batch::Merged m;
  try {
    m = batch::merge_results(files);
  } catch (const nlohmann::json::exception& e) {
    // merge_results checks the type of every field it reads; this is the backstop (exit 2, not 4).
    std::string names;
    for (const std::string& f : a.files) names += (names.empty() ? "" : ", ") + f;
    throw InputError(names, std::string("could not be merged: ") + e.what());
  }

  if (!a.json_path.empty()) save_text(a.json_path, escape::json_text(m.doc) + "\n");
  if (!a.junit_path.empty()) save_text(a.junit_path, batch::merged_junit(m));
  if (!a.markdown_path.empty()) save_text(a.markdown_path, batch::merged_markdown(m));
  if (!a.report_dir.empty()) {
    std::error_code ec;
    fs::create_directories(a.report_dir, ec);
    if (ec) throw InputError(a.report_dir, "cannot create the folder: " + ec.message());
    std::set<std::string> reports;  // check --report into the same folder: a page per item
    for (const auto& it : m.doc["items"]) {
      const std::string id = it["id"].get<std::string>();
      if (fs::exists(fs::path(a.report_dir) / id / "index.html", ec)) reports.insert(id);
    }
    save_text((fs::path(a.report_dir) / "index.html").string(), batch::merged_html(m, reports));
  }
  for (const std::string& p : m.problems) std::fprintf(stderr, "bloomref: merge: %s\n", p.c_str());
  if (!a.quiet) {
    const auto& d = m.doc;
    std::printf("merged %zu results file(s): %zu items; %s", files.size(),
                d["batch"]["items_total"].get<std::size_t>(), d["summary"].dump().c_str());
    if (d.contains("verdict")) std::printf("; verdict %s", d["verdict"].get<std::string>().c_str());
    std::printf("; exit %d\n", m.exit_code);
  }
  return m.exit_code;
}

}  // namespace

std::function<int()> add_merge(CLI::App& app) {
  auto args = std::make_shared<MergeArgs>();
  CLI::App* sub = app.add_subcommand(
      "merge",
      "one result from the shards' results files (run --frames or check, --json): "
      "exit 2 when an item is missing or was run twice");
  sub->add_option("RESULTS", args->files, "the shards' results files (JSON)")->required();
  sub->add_option("--json", args->json_path, "write the merged results as JSON");
  sub->add_option("--junit", args->junit_path, "write JUnit XML (a testsuite per item)");
  sub->add_option("--markdown", args->markdown_path,
                  "write a Markdown summary (a CI job's summary page)");
  sub->add_option("--report", args->report_dir, "write DIR/index.html (a row per item)");
  sub->add_flag("-q,--quiet", args->quiet, "print nothing but problems");
  return [args, sub]() -> int {
    if (!sub->parsed()) return -1;
    return merge(*args);
  };
}

}  // namespace bloomref::cli
