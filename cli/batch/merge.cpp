#include "batch/merge.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>

#include "bloomref/error.h"
#include "escape.h"
#include "results.h"

using nlohmann::ordered_json;

namespace bloomref::batch {
namespace {

bool is_check(const ordered_json& doc) {
  return doc.value("tool", "") == "bloomref check";
}

// The parameters that decide the results: every one but the thread count, which may differ
// between machines and gives the same bits.
ordered_json deciding_params(const ordered_json& doc) {
  ordered_json p = doc.contains("params") ? doc["params"] : ordered_json::object();
  if (p.is_object()) p.erase("threads");
  return p;
}

using TypeTest = bool (ordered_json::*)() const noexcept;

// InputError naming the file and the field when `obj` has `key` of another type than merge
// reads (found by fuzzing: nlohmann's value() throws a type_error deep inside the merge).
void require_type(const ResultsFile& f, const ordered_json& obj, const char* key, TypeTest is,
                  const char* type, const std::string& where, bool null_ok = false) {
  if (obj.is_object() && obj.contains(key) && !(obj[key].*is)() && !(null_ok && obj[key].is_null()))
    throw InputError(f.name, where + "\"" + key + "\" is not " + type);
}

// Every field merge and its writers read, where present, of the type they read it as.
void require_types(const ResultsFile& f) {
  const ordered_json& d = f.doc;
  using J = ordered_json;
  for (const char* k : {"kind", "verdict"}) require_type(f, d, k, &J::is_string, "a string", "");
  require_type(f, d, "version", &J::is_number, "a number", "");
  require_type(f, d, "warn_as_error", &J::is_boolean, "true or false", "");
  require_type(f, d, "batch", &J::is_object, "an object", "");
  if (d.contains("batch")) {
    const ordered_json& b = d["batch"];
    for (const char* k : {"finished", "interrupted"})
      require_type(f, b, k, &J::is_boolean, "true or false", "batch: ");
    require_type(f, b, "shard", &J::is_object, "an object or null", "batch: ", true);
    if (b.contains("shard") && b["shard"].is_object())
      for (const char* k : {"label", "source"})
        require_type(f, b["shard"], k, &J::is_string, "a string", "batch.shard: ");
    if (b.contains("item_ids") && b["item_ids"].is_array())
      for (const ordered_json& id : b["item_ids"])
        if (!id.is_string()) throw InputError(f.name, "batch.item_ids: an id is not a string");
  }
  if (!d.contains("items") || !d["items"].is_array()) return;
  for (const ordered_json& it : d["items"]) {
    if (!it.is_object()) continue;  // require_results names it
    const std::string where = "item " + (it.contains("id") ? it["id"].dump() : "?") + ": ";
    for (const char* k : {"verdict", "status"}) require_type(f, it, k, &J::is_string, "a string", where);
    require_type(f, it, "first_divergent_stage", &J::is_string, "a string or null", where, true);
    for (const char* k : {"exit_code", "wall_ms"}) require_type(f, it, k, &J::is_number, "a number", where);
    require_type(f, it, "first_divergent_cause", &J::is_object, "an object or null", where, true);
    require_type(f, it, "outputs", &J::is_array, "an array", where);
    if (it.contains("outputs"))
      for (const ordered_json& o : it["outputs"])
        if (!o.is_string()) throw InputError(f.name, where + "an output is not a string");
    require_type(f, it, "stages", &J::is_array, "an array", where);
    if (!it.contains("stages")) continue;
    for (const ordered_json& s : it["stages"]) {
      if (!s.is_object()) throw InputError(f.name, where + "a stage is not an object");
      for (const char* k : {"stage", "status"})
        require_type(f, s, k, &J::is_string, "a string", where + "stage: ");
      require_type(f, s, "isolated", &J::is_object, "an object", where + "stage: ");
      if (s.contains("isolated"))
        require_type(f, s["isolated"], "reason", &J::is_string, "a string", where + "stage.isolated: ");
    }
  }
}

// An item's verdict (check) or status (run), and a check stage's status, must be one the
// tools write: merge decides the exit code from them.
void require_known_values(const ResultsFile& f) {
  const bool check = is_check(f.doc);
  static const std::set<std::string> verdicts = {"PASS", "WARN", "FAIL", "NOTHING", "ERROR"};
  static const std::set<std::string> statuses = {"done", "resumed", "error", "not-run"};
  static const std::set<std::string> stage_statuses = {"pass", "warn", "fail", "expected-fail", "fixed"};
  auto list = [](const std::set<std::string>& s) {
    std::string o;
    for (const std::string& v : s) o += (o.empty() ? "" : ", ") + v;
    return o;
  };
  for (const ordered_json& it : f.doc["items"]) {
    const std::string where = "item " + escape::utf8(it["id"].get<std::string>()) + ": ";
    const char* key = check ? "verdict" : "status";
    const std::set<std::string>& known = check ? verdicts : statuses;
    if (!it.contains(key) || !known.count(it[key].get<std::string>()))
      throw InputError(f.name, where + "\"" + key + "\" is " +
                                   (it.contains(key) ? "'" + escape::utf8(it[key].get<std::string>()) + "'" : "missing") +
                                   ", not one of " + list(known));
    if (!check || !it.contains("stages")) continue;
    for (const ordered_json& s : it["stages"]) {
      const std::string st = s.value("status", "");
      if (!stage_statuses.count(st))
        throw InputError(f.name, where + "a stage's \"status\" is '" + escape::utf8(st) +
                                     "', not one of " + list(stage_statuses));
    }
  }
}

void require_results(const ResultsFile& f) {
  const ordered_json& d = f.doc;
  if (!d.is_object() || !d.contains("tool") || !d["tool"].is_string())
    throw InputError(f.name, "is not a bloomref results file (no \"tool\")");
  require_types(f);
  const std::string tool = d["tool"].get<std::string>();
  if (tool != "bloomref check" && tool != "bloomref run")
    throw InputError(f.name, "holds results of '" + tool + "'; merge takes run and check results");
  if (tool == "bloomref run" && d.value("kind", "") != "sequence")
    throw InputError(f.name,
                     "holds the results of one image; merge takes the results of "
                     "sequences (run --frames ... --json)");
  if (d.value("version", 0) != 1)
    throw InputError(f.name, "is results version " + d.value("version", ordered_json(0)).dump() +
                                 "; this bloomref merges version 1");
  if (!d.contains("batch") || !d["batch"].is_object() || !d["batch"].contains("item_ids") ||
      !d["batch"]["item_ids"].is_array())
    throw InputError(f.name,
                     "has no item list (\"batch.item_ids\"): it was written by a check of "
                     "one folder; run check with frames, a manifest or --shard");
  if (!d.contains("items") || !d["items"].is_array())
    throw InputError(f.name, "has no \"items\" array");
  for (const ordered_json& it : d["items"])
    if (!it.is_object() || !it.contains("id") || !it["id"].is_string())
      throw InputError(f.name, "has an item without a string \"id\"");
  require_known_values(f);
}

std::string shard_label(const ordered_json& doc) {
  const ordered_json& s = doc["batch"].value("shard", ordered_json(nullptr));
  return s.is_object() ? s.value("label", "?") : "all";
}

// check: counts, verdict and exit code over the merged items, as a single check decides them
// (cli/check/manifest.cpp, finish_run).
void finish_check(ordered_json& doc) {
  int stages = 0, pass = 0, warn = 0, fail = 0, expected = 0, fixed = 0, errors = 0;
  bool any_fail = false, any_warn = false, any_error = false, nothing = doc["items"].empty();
  const bool warn_as_error = doc.value("warn_as_error", false);
  for (const ordered_json& it : doc["items"]) {
    const std::string v = it.value("verdict", "");
    any_error |= v == "ERROR";
    any_fail |= v == "FAIL";
    any_warn |= v == "WARN";
    nothing |= v == "NOTHING";
    errors += v == "ERROR";
    if (!it.contains("stages") || !it["stages"].is_array()) continue;
    for (const ordered_json& s : it["stages"]) {
      const std::string st = s.value("status", "");
      ++stages;
      pass += st == "pass";
      warn += st == "warn";
      fail += st == "fail";
      expected += st == "expected-fail";
      fixed += st == "fixed";
    }
  }
  std::string verdict = "PASS";
  int code = 0;
  if (any_error)
    verdict = "ERROR", code = 2;
  else if (any_fail || (any_warn && warn_as_error))
    verdict = "FAIL", code = 1;
  else if (nothing)
    verdict = "NOTHING", code = 5;
  else if (any_warn)
    verdict = "WARN";
  doc["verdict"] = verdict;
  doc["exit_code"] = code;
  doc["summary"] = {{"items", doc["items"].size()},
                    {"stages", stages},
                    {"pass", pass},
                    {"warn", warn},
                    {"fail", fail},
                    {"expected_fail", expected},
                    {"fixed", fixed},
                    {"errors", errors}};
}

// run: frames done, resumed, failed; the exit code of the worst failure.
void finish_run(ordered_json& doc) {
  int done = 0, resumed = 0, error = 0, code = 0;
  double wall = 0;
  for (const ordered_json& it : doc["items"]) {
    const std::string st = it.value("status", "");
    done += st == "done";
    resumed += st == "resumed";
    if (st == "error") {
      ++error;
      code = std::max(code, it.value("exit_code", 2));
    }
    wall += it.value("wall_ms", 0.0);
  }
  doc["exit_code"] = code;
  doc["summary"] = {{"done", done}, {"resumed", resumed}, {"error", error}, {"not_run", 0}};
  doc["frame_ms_sum"] = wall;
  doc.erase("wall_ms");
  doc.erase("frames_per_second");
}

using escape::xml;

std::string str(const ordered_json& j, const char* key) {
  return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : "";
}

}  // namespace

Merged merge_results(const std::vector<ResultsFile>& files) {
  if (files.empty()) throw ParamError("merge: give the results files of the shards");
  for (const ResultsFile& f : files) require_results(f);
  const ResultsFile& first = files.front();
  const ordered_json& ids = first.doc["batch"]["item_ids"];
  for (const ResultsFile& f : files) {
    if (f.doc["tool"] != first.doc["tool"])
      throw InputError(f.name, "holds " + f.doc["tool"].get<std::string>() + " results, " +
                                   first.name + " " + first.doc["tool"].get<std::string>() +
                                   " results");
    if (f.doc["batch"]["item_ids"] != ids)
      throw InputError(f.name, "lists other items (" +
                                   std::to_string(f.doc["batch"]["item_ids"].size()) + ") than " +
                                   first.name + " (" + std::to_string(ids.size()) +
                                   "): the files are not shards of one run");
    if (deciding_params(f.doc) != deciding_params(first.doc))
      throw InputError(f.name, "was run with other parameters than " + first.name + ": " +
                                   deciding_params(f.doc).dump() + " against " +
                                   deciding_params(first.doc).dump());
  }

  Merged m;
  std::map<std::string, std::vector<std::pair<const ResultsFile*, const ordered_json*>>> found;
  ordered_json shards = ordered_json::array();
  for (const ResultsFile& f : files) {
    const ordered_json& b = f.doc["batch"];
    shards.push_back(
        {{"file", f.name},
         {"shard", shard_label(f.doc)},
         {"source", b.contains("shard") && b["shard"].is_object() ? b["shard"].value("source", "")
                                                                  : std::string("")},
         {"items", f.doc["items"].size()},
         {"finished", b.value("finished", true)},
         {"interrupted", b.value("interrupted", false)}});
    if (!b.value("finished", true))
      m.problems.push_back(
          f.name + ": shard " + shard_label(f.doc) + " did not finish" +
          (b.value("interrupted", false) ? " (interrupted)" : " (still running, or crashed)"));
    for (const ordered_json& it : f.doc["items"])
      found[it["id"].get<std::string>()].push_back({&f, &it});
  }

  ordered_json items = ordered_json::array();
  std::set<std::string> listed;
  for (const ordered_json& idj : ids) {
    const std::string id = idj.get<std::string>();
    listed.insert(id);
    const auto it = found.find(id);
    if (it == found.end()) {
      m.missing.push_back(id);
      continue;
    }
    if (it->second.size() > 1) {
      m.duplicates.push_back(id);
      std::string where;
      for (const auto& [file, item] : it->second) where += (where.empty() ? "" : ", ") + file->name;
      m.problems.push_back("item " + id + " was run " + std::to_string(it->second.size()) +
                           " times (" + where + ")");
    }
    for (const auto& [file, item] : it->second) {
      ordered_json copy = *item;
      copy["shard"] = shard_label(file->doc);
      copy["results_file"] = file->name;
      items.push_back(std::move(copy));
    }
  }
  for (const auto& [id, where] : found)
    if (!listed.count(id))
      m.problems.push_back(where.front().first->name + ": item " + id + " is not in the item list");
  if (!m.missing.empty()) {
    std::string list;
    for (std::size_t i = 0; i < m.missing.size() && i < 20; ++i)
      list += (i ? ", " : "") + m.missing[i];
    if (m.missing.size() > 20) list += " ... (" + std::to_string(m.missing.size()) + " in all)";
    m.problems.insert(m.problems.begin(), std::to_string(m.missing.size()) + " of " +
                                              std::to_string(ids.size()) +
                                              " items missing: " + list);
  }

  ordered_json doc = first.doc;
  doc["items"] = std::move(items);
  // A known deviation is unused when no shard used it: the shards' lists in common.
  if (doc.contains("unused_expectations")) {
    ordered_json common = ordered_json::array();
    for (const ordered_json& e : doc["unused_expectations"]) {
      bool everywhere = true;
      for (const ResultsFile& f : files) {
        const auto it = f.doc.find("unused_expectations");
        everywhere = everywhere && it != f.doc.end() && it->is_array() &&
                     std::find(it->begin(), it->end(), e) != it->end();
      }
      if (everywhere) common.push_back(e);
    }
    doc["unused_expectations"] = std::move(common);
  }
  doc["batch"] = {{"items_total", ids.size()},  {"item_ids", ids},
                  {"shards", shards},           {"missing", m.missing},
                  {"duplicates", m.duplicates}, {"complete", m.problems.empty()}};
  doc.erase("peak_rss_bytes");
  if (is_check(doc))
    finish_check(doc);
  else
    finish_run(doc);
  if (!m.problems.empty()) doc["exit_code"] = 2;
  doc["problems"] = m.problems;
  m.exit_code = doc["exit_code"].get<int>();
  m.doc = std::move(doc);
  return m;
}

// check's merged results are written as one run's are (results.h); a run's here.
std::string merged_junit(const Merged& m) {
  const ordered_json& d = m.doc;
  if (is_check(d)) return results::junit(d);
  std::string suites;
  int tests = 0, errors = 0;
  for (const ordered_json& it : d["items"]) {
    const std::string id = it["id"].get<std::string>();
    const std::string cls = "bloomref.run." + xml(id);
    const std::string err = str(it, "error");
    ++tests;
    errors += !err.empty();
    suites += "  <testsuite name=\"" + xml(id) + "\" tests=\"1\" failures=\"0\" errors=\"" +
              std::to_string(!err.empty()) + "\">\n" +
              "    <properties><property name=\"shard\" value=\"" + xml(str(it, "shard")) +
              "\"/></properties>\n    <testcase classname=\"" + cls + "\" name=\"frame\"" +
              (err.empty() ? "/>\n"
                           : "><error message=\"" + xml(err) + "\" type=\"input\"/></testcase>\n") +
              "  </testsuite>\n";
  }
  auto error_suite = [&](const std::string& name, const std::string& id, const std::string& test,
                         const std::string& message, const std::string& type) {
    ++tests, ++errors;
    suites += "  <testsuite name=\"" + xml(name) + "\" tests=\"1\" failures=\"0\" errors=\"1\">\n"
              "    <testcase classname=\"bloomref.run." + xml(id) + "\" name=\"" + test +
              "\"><error message=\"" + message + "\" type=\"" + type + "\"/></testcase>\n  </testsuite>\n";
  };
  for (const std::string& id : m.missing)
    error_suite(id, id, "frame", "missing: no shard's results have this item", "missing");
  for (const std::string& id : m.duplicates)
    error_suite(id + " (run twice)", id, "once", "run by more than one shard", "duplicate");
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"bloomref run (merged)\" tests=\"" +
         std::to_string(tests) + "\" failures=\"0\" errors=\"" + std::to_string(errors) + "\">\n" +
         suites + "</testsuites>\n";
}

std::string merged_markdown(const Merged& m) {
  const ordered_json& d = m.doc;
  if (is_check(d)) return results::markdown(d);
  const std::string verdict = !m.problems.empty()            ? "INCOMPLETE"
                              : d.value("exit_code", 0) == 0 ? "OK"
                                                             : "FAILED";
  std::string out = "### bloomref run (merged): " + escape::markdown_cell(verdict) + "\n\n" +
                    std::to_string(d["batch"]["items_total"].get<std::size_t>()) + " items from " +
                    std::to_string(d["batch"]["shards"].size()) + " results file(s); exit code " +
                    std::to_string(m.exit_code) + ".\n\n";
  for (const std::string& p : m.problems) out += "- :x: " + escape::markdown_cell(p) + "\n";
  std::string rows;
  for (const ordered_json& it : d["items"]) {
    const std::string v = str(it, "status");
    if (v == "done" || v == "resumed") continue;
    rows += "| " + escape::markdown_cell(str(it, "id")) + " | " + escape::markdown_cell(v) + " | " +
            escape::markdown_cell(str(it, "error")) + " | " + escape::markdown_cell(str(it, "shard")) + " |\n";
  }
  if (!rows.empty()) out += "\n| item | status | why | shard |\n|---|---|---|---|\n" + rows;
  return out;
}

std::string merged_html(const Merged& m, const std::set<std::string>& item_reports) {
  const ordered_json& d = m.doc;
  const bool check = is_check(d);
  std::string verdict =
      check ? str(d, "verdict") : (d.value("exit_code", 0) == 0 ? "OK" : "FAILED");
  if (!m.problems.empty()) verdict = "INCOMPLETE";
  std::string h =
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>bloomref " +
      std::string(check ? "check" : "run") +
      " (merged)</title>\n<style>body{font:14px sans-serif;"
      "margin:2em}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;"
      "text-align:left}.bad{background:#fdd}.warn{background:#ffd}.ok{background:#dfd}</style>"
      "</head><body>\n<h1>bloomref " +
      std::string(check ? "check" : "run") + ": " + escape::html(verdict) + " (exit " +
      std::to_string(m.exit_code) + ")</h1>\n";
  h += "<p>" + std::to_string(d["batch"]["items_total"].get<std::size_t>()) + " items in " +
       std::to_string(d["batch"]["shards"].size()) +
       " results file(s). Summary: " + escape::html(d["summary"].dump()) + "</p>\n";
  if (!m.problems.empty()) {
    h += "<h2>Problems</h2><ul>\n";
    for (const std::string& p : m.problems) h += "<li class=\"bad\">" + escape::html(p) + "</li>\n";
    h += "</ul>\n";
  }
  h += "<h2>Shards</h2><table><tr><th>file</th><th>shard</th><th>from</th><th>items</th>"
       "<th>finished</th></tr>\n";
  for (const ordered_json& s : d["batch"]["shards"])
    h += "<tr><td>" + escape::html(str(s, "file")) + "</td><td>" + escape::html(str(s, "shard")) + "</td><td>" +
         escape::html(str(s, "source")) + "</td><td>" + std::to_string(s.value("items", 0)) + "</td><td>" +
         (s.value("finished", true) ? "yes" : "no") + "</td></tr>\n";
  h += "</table>\n<h2>Items</h2><table><tr><th>item</th><th>" +
       std::string(check ? "verdict</th><th>first divergent stage</th><th>cause"
                         : "status</th><th>time (ms)</th><th>outputs") +
       "</th><th>shard</th></tr>\n";
  for (const ordered_json& it : d["items"]) {
    const std::string id = str(it, "id");
    const std::string v = check ? str(it, "verdict") : str(it, "status");
    const char* cls = v == "PASS" || v == "done" || v == "resumed" ? "ok"
                      : v == "WARN"                                ? "warn"
                                                                   : "bad";
    std::string name = escape::html(id);
    if (item_reports.count(id)) name = "<a href=\"" + escape::url(id + "/index.html") + "\">" + name + "</a>";
    h += "<tr class=\"" + std::string(cls) + "\"><td>" + name + "</td><td>" + escape::html(v) + "</td><td>";
    if (check) {
      h += escape::html(it.contains("first_divergent_stage") && it["first_divergent_stage"].is_string()
                   ? it["first_divergent_stage"].get<std::string>()
                   : "-") +
           "</td><td>";
      const std::string err = str(it, "error");
      h += escape::html(!err.empty() ? err
               : it.contains("first_divergent_cause") && it["first_divergent_cause"].is_object()
                   ? str(it["first_divergent_cause"], "description")
                   : "-");
    } else {
      char ms[32];
      std::snprintf(ms, sizeof ms, "%.0f", it.value("wall_ms", 0.0));
      h += std::string(ms) + "</td><td>";
      const std::string err = str(it, "error");
      if (!err.empty())
        h += escape::html(err);
      else if (it.contains("outputs"))
        for (const ordered_json& o : it["outputs"]) h += escape::html(o.get<std::string>()) + " ";
    }
    h += "</td><td>" + escape::html(str(it, "shard")) + "</td></tr>\n";
  }
  for (const std::string& id : m.missing)
    h += "<tr class=\"bad\"><td>" + escape::html(id) +
         "</td><td>MISSING</td><td colspan=\"3\">no shard's "
         "results have this item</td></tr>\n";
  return h + "</table>\n</body></html>\n";
}

}  // namespace bloomref::batch
