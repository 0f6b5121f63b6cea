#include "results.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <vector>

#include "escape.h"

using nlohmann::ordered_json;

namespace bloomref::results {
namespace {

// Readers that never throw: a field that is missing or of another type reads as nothing.
const ordered_json& field(const ordered_json& j, const char* key) {
  static const ordered_json none;
  if (!j.is_object()) return none;
  const auto it = j.find(key);
  return it == j.end() ? none : *it;
}
std::string str(const ordered_json& j, const char* key) {
  const ordered_json& v = field(j, key);
  return v.is_string() ? v.get<std::string>() : "";
}
// A number, where JSON has "infinite" and "nan" for what it cannot hold; NaN when absent.
double num(const ordered_json& j, const char* key) {
  const ordered_json& v = field(j, key);
  if (v.is_number()) return v.get<double>();
  if (v == "infinite") return std::numeric_limits<double>::infinity();
  return std::numeric_limits<double>::quiet_NaN();
}
bool flag(const ordered_json& j, const char* key) {
  const ordered_json& v = field(j, key);
  return v.is_boolean() && v.get<bool>();
}
const ordered_json& list(const ordered_json& j, const char* key) {
  static const ordered_json empty = ordered_json::array();
  const ordered_json& v = field(j, key);
  return v.is_array() ? v : empty;
}
std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

bool is_merged(const ordered_json& doc) { return field(field(doc, "batch"), "shards").is_array(); }

// A stage's status counted as a failure: fail, and warn with --warn-as-error.
bool failing(const ordered_json& doc, const std::string& status) {
  return status == "fail" || (status == "warn" && flag(doc, "warn_as_error"));
}

struct Counts {
  int items = 0, stages = 0, pass = 0, warn = 0, fail = 0, expected = 0, fixed = 0, errors = 0;
};

Counts count(const ordered_json& doc) {
  Counts c;
  for (const ordered_json& it : list(doc, "items")) {
    ++c.items;
    c.errors += !str(it, "error").empty();
    for (const ordered_json& s : list(it, "stages")) {
      const std::string st = str(s, "status");
      ++c.stages;
      c.pass += st == "pass";
      c.warn += st == "warn";
      c.fail += st == "fail";
      c.expected += st == "expected-fail";
      c.fixed += st == "fixed";
    }
  }
  return c;
}

// What a person acts on first, for a stage that did not pass: its "action"; for a stage that
// fails only end to end (it has none), that; from an older document, the stage and its verdict.
std::string action(const ordered_json& s) {
  if (const std::string a = str(s, "action"); !a.empty()) return a;
  const ordered_json& iso = field(s, "isolated");
  if (field(s, "action").is_null() && s.contains("action") && str(iso, "verdict") == "PASS")
    return str(s, "stage") + ": " + str(field(s, "end_to_end"), "verdict") +
           " end to end \u2014 " + str(field(s, "end_to_end"), "reason");
  return str(s, "stage") + ": " + str(iso, "verdict");
}

// The best-supported cause in one line (its "explanation"; from an older document, the cause's
// description and detail), "" when none, or when the stage only follows from an earlier one.
std::string explanation(const ordered_json& s) {
  if (!str(s, "follows_from").empty()) return "";
  if (field(s, "explanation").is_string()) return str(s, "explanation");
  const ordered_json& c = field(s, "cause");
  if (!c.is_object()) return "";
  const std::string detail = str(c, "detail");
  return "cause: " + str(c, "description") + (detail.empty() ? "" : " (" + detail + ")");
}

// The line JUnit's failure and Markdown say of a stage.
std::string stage_line(const ordered_json& s) {
  const std::string cause = explanation(s);
  return action(s) + "; " + str(field(s, "isolated"), "reason") + (cause.empty() ? "" : "; " + cause);
}

// A count or size: 0 where the document has none.
int whole(const ordered_json& j, const char* key) {
  const double v = num(j, key);
  return std::isfinite(v) && std::fabs(v) < 1e9 ? static_cast<int>(v) : 0;
}

const ordered_json* first_divergent(const ordered_json& item) {
  const std::string first = str(item, "first_divergent_stage");
  for (const ordered_json& s : list(item, "stages"))
    if (!first.empty() && str(s, "stage") == first) return &s;
  return nullptr;
}

// One figure of a sensitivity ladder ({"smallest_failed", "first_failing_stage"}) in words.
std::string seen_part(const ordered_json& seen, double scale, double offset, const char* f,
                      const char* none) {
  const double v = num(seen, "smallest_failed");
  if (!(v > 0)) return none;
  return fmt(f, scale * (v - offset)) + " (at " + str(seen, "first_failing_stage") + ")";
}

std::string shape_parts(const ordered_json& s) {
  std::string out = ", " + seen_part(field(s, "shift_texels"), 1, 0, "a shift of %g texel(s)",
                                     "no shift up to 8 texels");
  if (field(s, "spread").is_object())
    out += ", " + seen_part(field(s, "spread"), 100, 1, "a spread %.3g%% wider",
                            "no wider spread up to 50%");
  return out;
}

bool weak(const ordered_json& sensitivity) { return flag(sensitivity, "weak"); }

std::string device_line(const ordered_json& doc) {
  std::string d;
  for (const char* k : {"api", "vendor", "renderer", "driver"})
    if (const std::string v = str(field(doc, "device"), k); !v.empty()) d += (d.empty() ? "" : ", ") + v;
  return d;
}

}  // namespace

std::string sensitivity_line(const ordered_json& s) {
  if (!s.is_object()) return "not measured";
  const ordered_json& gain = field(s, "gain");
  std::string out = seen_part(gain, 1, 0,
                              flag(gain, "at_most") ? "a bloom gain of %.3gx or less" : "a bloom gain of %.3gx",
                              "no bloom gain up to 4x");
  return field(s, "shift_texels").is_object() ? out + shape_parts(s) : out;
}

std::string stage_sensitivity_line(const ordered_json& s) {
  return seen_part(field(s, "gain"), 1, 0, "a gain of %.3gx", "no gain up to 4x") + shape_parts(s);
}

std::string carried_line(const ordered_json& stage) {
  const ordered_json& c = field(stage, "carried");
  const ordered_json& from = list(c, "from");
  if (!c.is_object() || from.empty()) return "";
  std::vector<std::string> names;
  for (const ordered_json& n : from) names.push_back(n.is_string() ? n.get<std::string>() : "?");
  std::string stages;
  if (names.size() > 4) {
    stages = names.front() + " ... " + names.back() + " (" + std::to_string(names.size()) +
             " stages, not captured)";
  } else {
    for (const std::string& n : names) stages += (stages.empty() ? "" : ", ") + n;
    stages += " (not captured)";
  }
  // Rounded down: a share short of all of it is not called all of it.
  return fmt("%.0f%% of its bound is what ", std::floor(100 * num(c, "share_of_bound"))) + stages +
         " may carry";
}

std::string weak_line(const ordered_json& s) {
  std::string out = fmt("a bloom %.3gx too strong would not have failed", num(s, "required_gain"));
  if (const std::string more = str(s, "strengthen_with"); !more.empty())
    out += "; " + more + " to see more";
  return out;
}

std::string console(const ordered_json& doc) {
  std::string o;
  for (const ordered_json& e : list(doc, "unused_expectations"))
    o += "note: expectation (item " + str(e, "item") + ", stage " + str(e, "stage") +
         ") matched no stage\n";
  const std::string profile = str(field(doc, "profile"), "name");
  const ordered_json& items = list(doc, "items");
  for (const ordered_json& r : items) {
    const std::string id = str(r, "id");
    if (const std::string err = str(r, "error"); !err.empty()) {
      o += id + ": ERROR, not judged: " + err + "\n";
      continue;
    }
    const ordered_json& stages = list(r, "stages");
    const std::string from = str(r, "stages_from");
    o += id + ": " + str(r, "scene") + " " + std::to_string(whole(r, "width")) + "x" +
         std::to_string(whole(r, "height")) + ", profile " + profile + ", " +
         std::to_string(stages.size()) + " stage image(s)" + (from.empty() ? "" : " from " + from) + "\n";
    if (!list(r, "ignored_files").empty()) {
      o += "  ignored (not a stage name):";
      for (const ordered_json& f : list(r, "ignored_files")) o += " " + (f.is_string() ? f.get<std::string>() : "");
      o += "\n";
    }
    if (stages.empty()) continue;
    char line[512];
    std::snprintf(line, sizeof line, "  %-10s %-13s %-10s %-8s %-10s %s\n", "stage", "isolated",
                  "err/bound", "end2end", "err/bound", "file");
    o += line;
    for (const ordered_json& s : stages) {
      std::string status = str(s, "status");
      status = status == "expected-fail" ? "XFAIL (known)" : status == "fixed" ? "FIXED (known)" : status;
      for (char& ch : status)
        if (ch >= 'a' && ch <= 'z') ch = static_cast<char>(ch - 'a' + 'A');
      const ordered_json& iso = field(s, "isolated");
      const ordered_json& e2e = field(s, "end_to_end");
      std::snprintf(line, sizeof line, "  %-10s %-13s %-10.3g %-8s %-10.3g ",
                    str(s, "stage").substr(0, 64).c_str(), status.c_str(),
                    num(iso, "max_error_over_bound"), str(e2e, "verdict").c_str(),
                    num(e2e, "max_error_over_bound"));
      o += line + std::filesystem::path(str(s, "file")).filename().string() + "\n";
      if (str(iso, "verdict") == "PASS") continue;
      o += "             " + action(s) + "\n";
      o += "             " + str(iso, "reason") + "\n";
      if (const std::string cause = explanation(s); !cause.empty()) o += "             " + cause + "\n";
    }
    const std::string nf = str(r, "first_nonfinite_stage");
    for (const ordered_json& s : stages)
      if (!nf.empty() && str(s, "stage") == nf)
        o += "  NaN/Inf first stand against finite values at " + nf + " (" +
             fmt("%.0f", num(field(s, "isolated"), "nonfinite_mismatch")) +
             " values): the stages after it inherit them\n";
    // What a stage that does not fail was judged through: an error entering at a stage
    // without capture is seen at it only beyond what that stage may legitimately carry.
    bool through = false;
    for (const ordered_json& s : stages) {
      const std::string carried = carried_line(s);
      if (carried.empty() || str(field(s, "isolated"), "verdict") == "FAIL") continue;
      if (!through)
        o += "  judged through stages not captured (an error entering there shows only beyond "
             "what they may carry):\n";
      through = true;
      std::snprintf(line, sizeof line, "    %-10s ", str(s, "stage").substr(0, 64).c_str());
      o += line + carried + "\n";
    }
    const ordered_json& sens = field(r, "sensitivity");
    if (sens.is_object()) {
      o += "  could see: " + sensitivity_line(sens) + "\n";
      bool heading = false;
      for (const ordered_json& s : stages) {
        if (!field(s, "sensitivity").is_object()) continue;
        if (!heading) o += "  could see, of an error entering at:\n";
        heading = true;
        std::snprintf(line, sizeof line, "    %-10s ", str(s, "stage").c_str());
        o += line + stage_sensitivity_line(field(s, "sensitivity")) + "\n";
      }
    }
    const std::string first = str(r, "first_divergent_stage");
    o += "  verdict " + str(r, "verdict") + (weak(sens) ? ": weak verdict: " + weak_line(sens) : "") +
         "; first divergent stage: " + (first.empty() ? "none" : first) + "\n";
  }
  if (str(doc, "verdict") == "NOTHING")
    o += "nothing compared: no stage image found (names as --dump-stages writes them: "
         "bright.exr, blur.1.exr ... output.exr)\n";
  else if (items.size() > 1)
    o += std::to_string(items.size()) + " items: verdict " + str(doc, "verdict") + "\n";
  return o;
}

std::string junit(const ordered_json& doc) {
  using escape::xml;
  const bool merged = is_merged(doc);
  const ordered_json& batch = field(doc, "batch");
  const ordered_json& missing = list(batch, "missing");
  const ordered_json& twice = list(batch, "duplicates");
  const std::string profile = str(field(doc, "profile"), "name");
  std::string suites;
  int tests = 0, failures = 0;
  for (const ordered_json& r : list(doc, "items")) {
    const std::string id = str(r, "id");
    const std::string cls = "bloomref.check." + xml(id);
    std::string props;
    auto property = [&props](const std::string& name, const std::string& value) {
      if (!value.empty())  // keys nobody declared are left out
        props += "      <property name=\"" + xml(name) + "\" value=\"" + xml(value) + "\"/>\n";
    };
    property("shard", str(r, "shard"));
    if (const std::string err = str(r, "error"); !err.empty()) {
      ++tests;
      suites += "  <testsuite name=\"" + xml(id) + "\" tests=\"1\" failures=\"0\" errors=\"1\" "
                "skipped=\"0\" time=\"0\">\n" +
                (props.empty() ? "" : "    <properties>\n" + props + "    </properties>\n") +
                "    <testcase classname=\"" + cls + "\" name=\"stages\"><error message=\"" +
                xml(err) + "\" type=\"input\"/></testcase>\n  </testsuite>\n";
      continue;
    }
    property("scene", str(r, "scene"));
    property("profile", profile);
    for (const char* k : {"api", "vendor", "renderer", "driver"})
      property(std::string("device.") + k, str(field(doc, "device"), k));
    const ordered_json& sens = field(r, "sensitivity");
    const ordered_json& stages = list(r, "stages");
    if (sens.is_object()) {
      property("sensitivity", sensitivity_line(sens));
      if (weak(sens)) property("weak-verdict", weak_line(sens));
      for (const ordered_json& s : stages)
        if (field(s, "sensitivity").is_object())
          property("sensitivity." + str(s, "stage"), stage_sensitivity_line(field(s, "sensitivity")));
    }
    int fails = 0, skipped = 0;
    std::string cases;
    if (stages.empty())
      cases += "    <testcase classname=\"" + cls + "\" name=\"stages\"><failure message=\"nothing "
               "compared: no stage image\" type=\"nothing\"/></testcase>\n";
    for (const ordered_json& s : stages) {
      const std::string status = str(s, "status");
      const ordered_json& iso = field(s, "isolated");
      cases += "    <testcase classname=\"" + cls + "\" name=\"" + xml(str(s, "stage")) + "\">";
      const std::string line = stage_line(s);
      if (failing(doc, status)) {
        ++fails;
        const std::string type = str(iso, "verdict");
        cases += "\n      <failure message=\"" + xml(line) + "\" type=\"" + xml(type.empty() ? status : type) +
                 "\">" + xml("end to end: " + str(field(s, "end_to_end"), "reason")) + "</failure>";
      } else if (status == "expected-fail") {
        ++skipped;
        cases += "\n      <skipped message=\"" +
                 xml("expected failure: " + str(field(s, "expectation"), "reason") + " (" + line + ")") +
                 "\"/>";
      }
      // One <system-out> per testcase: a WARN's or a fixed deviation's note, a passing stage's
      // margin, then one attachment line per image of a failing stage (the Jenkins JUnit
      // attachments convention).
      std::string out;
      if (status == "warn") out = line + "\n";
      if (status == "pass")
        out = fmt("largest error / bound: %.3g isolated, ", num(iso, "max_error_over_bound")) +
              fmt("%.3g end to end\n", num(field(s, "end_to_end"), "max_error_over_bound"));
      if (const std::string carried = carried_line(s);
          (status == "pass" || status == "warn") && !carried.empty())
        out += "judged through stages not captured: " + carried + "\n";
      if (status == "fixed")
        out = "a known deviation (" + str(field(s, "expectation"), "reason") +
              ") now passes: remove the expectation\n";
      for (const ordered_json& image : list(s, "report_images"))
        if (image.is_string()) out += "[[ATTACHMENT|" + image.get<std::string>() + "]]\n";
      if (!out.empty()) cases += "\n      <system-out>" + xml(out) + "</system-out>";
      cases += "</testcase>\n";
    }
    if (stages.empty()) ++fails;  // nothing compared
    tests += stages.empty() ? 1 : int(stages.size());
    failures += fails;
    const ordered_json& t = field(r, "timings_ms");
    double seconds = 0;
    for (const char* k : {"load", "oracle", "judge"})
      if (std::isfinite(num(t, k))) seconds += num(t, k) / 1000;
    suites += "  <testsuite name=\"" + xml(id) + "\" tests=\"" +
              std::to_string(stages.empty() ? 1 : stages.size()) + "\" failures=\"" +
              std::to_string(fails) + "\" errors=\"0\" skipped=\"" +
              std::to_string(skipped) + "\" time=\"" + std::to_string(seconds) + "\">\n" +
              "    <properties>\n" + props + "    </properties>\n" + cases + "  </testsuite>\n";
  }
  auto error_suite = [&suites](const std::string& name, const std::string& id,
                               const std::string& test, const std::string& message,
                               const std::string& type) {
    suites += "  <testsuite name=\"" + xml(name) + "\" tests=\"1\" failures=\"0\" errors=\"1\" "
              "skipped=\"0\">\n    <testcase classname=\"bloomref.check." + xml(id) + "\" name=\"" +
              test + "\"><error message=\"" + message + "\" type=\"" + type +
              "\"/></testcase>\n  </testsuite>\n";
  };
  for (const ordered_json& id : missing)
    if (id.is_string())
      error_suite(id.get<std::string>(), id.get<std::string>(), "stages", "missing: no shard's results have this item", "missing");
  for (const ordered_json& id : twice)
    if (id.is_string())
      error_suite(id.get<std::string>() + " (run twice)", id.get<std::string>(), "once", "run by more than one shard",
                  "duplicate");
  const Counts n = count(doc);
  int errors = n.errors;
  for (const ordered_json* ids : {&missing, &twice})
    for (const ordered_json& id : *ids) errors += id.is_string();
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"bloomref check" +
         std::string(merged ? " (merged)" : "") + "\" tests=\"" +
         std::to_string(tests + errors - n.errors) +
         "\" failures=\"" + std::to_string(failures) + "\" errors=\"" + std::to_string(errors) +
         "\" skipped=\"" + std::to_string(n.expected) + "\">\n" + suites + "</testsuites>\n";
}

std::string markdown(const ordered_json& doc) {
  using escape::markdown_cell;
  using escape::markdown_code;
  const bool merged = is_merged(doc);
  const Counts n = count(doc);
  const ordered_json& problems = list(doc, "problems");
  const std::string verdict = problems.empty() ? str(doc, "verdict") : "INCOMPLETE";
  const char* icon = verdict == "PASS" ? ":white_check_mark:" : verdict == "WARN" ? ":warning:" : ":x:";
  std::string out = "### bloomref check" + std::string(merged ? " (merged)" : "") + ": " + icon +
                    " " + markdown_cell(verdict) + "\n\n";
  if (merged) {
    const ordered_json& batch = field(doc, "batch");
    out += fmt("%.0f items from ", num(batch, "items_total")) +
           std::to_string(list(batch, "shards").size()) + " results file(s); exit code " +
           fmt("%.0f", num(doc, "exit_code")) + ".\n\n";
    for (const ordered_json& p : problems)
      if (p.is_string()) out += "- :x: " + markdown_cell(p.get<std::string>()) + "\n";
    if (!problems.empty()) out += "\n";
  }
  out += std::to_string(n.items) + " item(s), " + std::to_string(n.stages) + " stage(s): " +
         std::to_string(n.pass) + " pass, " + std::to_string(n.warn) + " warn, " +
         std::to_string(n.fail) + " fail";
  if (n.expected) out += ", " + std::to_string(n.expected) + " expected failure(s)";
  if (n.fixed) out += ", " + std::to_string(n.fixed) + " known deviation(s) now passing";
  if (n.errors) out += ", " + std::to_string(n.errors) + " item(s) not read";
  out += ". Profile " + markdown_code(str(field(doc, "profile"), "name"));
  if (const std::string d = device_line(doc); !d.empty()) out += ", device " + markdown_cell(d);
  out += std::string(".\n\n| item | verdict | divergent stage | cause |") +
         (merged ? " shard |\n|---|---|---|---|---|\n" : "\n|---|---|---|---|\n");
  // Past kListedItems items, only those that did not pass cleanly: a CI page has room for a
  // summary (GitHub's step summary holds 1 MiB), the JSON for every item.
  constexpr int kListedItems = 50;
  auto listed = [&](const ordered_json& r) {
    return n.items <= kListedItems || str(r, "verdict") != "PASS" || weak(field(r, "sensitivity"));
  };
  int unlisted = 0;
  for (const ordered_json& r : list(doc, "items")) {
    if (!listed(r)) {
      ++unlisted;
      continue;
    }
    const ordered_json& sens = field(r, "sensitivity");
    const ordered_json* first = first_divergent(r);
    const std::string first_stage = str(r, "first_divergent_stage");
    const std::string shard = merged ? " " + markdown_cell(str(r, "shard")) + " |" : "";
    std::string why = "-";
    if (first) why = markdown_cell(field(*first, "action").is_string() ? action(*first)
                                   : field(r, "first_divergent_cause").is_object()
                                       ? "cause: " + str(field(r, "first_divergent_cause"), "description")
                                       : action(*first));
    else if (const std::string err = str(r, "error"); !err.empty()) why = markdown_cell(err);
    out += "| " + markdown_cell(str(r, "id")) + " | " + markdown_cell(str(r, "verdict")) +
           (weak(sens) ? " (weak verdict: " + markdown_cell(weak_line(sens)) + ")" : "") + " | " +
           (first_stage.empty() ? "-" : markdown_code(first_stage)) + " | " + why + " |" + shard + "\n";
    // Every later stage that diverges on its own (not only because it was judged from an
    // earlier wrong capture): a second bug is not hidden behind the first.
    bool after = false;
    for (const ordered_json& s : list(r, "stages")) {
      if (first && &s == first) after = true;
      if (!after || &s == first || str(field(s, "isolated"), "verdict") == "PASS" ||
          !str(s, "follows_from").empty())
        continue;
      out += "| " + markdown_cell(str(r, "id")) + " | also | " + markdown_code(str(s, "stage")) +
             " | " + markdown_cell(action(s)) + " |" + shard + "\n";
    }
  }
  if (unlisted)
    out += "\n" + std::to_string(unlisted) + " item(s) that passed are not listed.\n";
  // What each verdict could have seen: the bloom's, then an error entering at each stage.
  bool heading = false;
  for (const ordered_json& r : list(doc, "items")) {
    const ordered_json& sens = field(r, "sensitivity");
    if (!sens.is_object() || !listed(r)) continue;
    if (!heading) out += "\n| item | error entering at | could see |\n|---|---|---|\n";
    heading = true;
    const std::string id = markdown_cell(str(r, "id"));
    out += "| " + id + " | the bloom | " + markdown_cell(sensitivity_line(sens)) + " |\n";
    for (const ordered_json& s : list(r, "stages"))
      if (field(s, "sensitivity").is_object())
        out += "| " + id + " | " + markdown_code(str(s, "stage")) + " | " +
               markdown_cell(stage_sensitivity_line(field(s, "sensitivity"))) + " |\n";
  }
  return out;
}

}  // namespace bloomref::results
