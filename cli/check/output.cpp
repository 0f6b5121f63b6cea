#include "check/output.h"

#include <sys/resource.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "escape.h"
#include "json_out.h"
#include "report.h"

namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace bloomref::cli {
namespace {

// A number, or "infinite" / "nan" where JSON has none.
ordered_json finite_or_string(double v) {
  if (std::isfinite(v)) return v;
  return std::isnan(v) ? ordered_json("nan") : ordered_json("infinite");
}
ordered_json finite_or_string(const std::array<double, 3>& v) {
  return {finite_or_string(v[0]), finite_or_string(v[1]), finite_or_string(v[2])};
}

// The smallest amount of a ladder that failed, and the first stage that failed it.
ordered_json seen(double v, const std::string& stage) {
  return v > 0 ? ordered_json{{"smallest_failed", v}, {"first_failing_stage", stage}}
               : ordered_json{{"smallest_failed", nullptr}, {"first_failing_stage", nullptr}};
}

ordered_json sensitivity_json(const ItemResult& r) {
  if (!r.sensitivity) return nullptr;
  const parity::Sensitivity& s = *r.sensitivity;
  ordered_json gain = seen(s.gain, s.gain_stage);
  gain["at_most"] = s.gain_at_most;
  return {{"gain", gain},
          {"shift_texels", s.shape ? seen(s.shift, s.shift_stage) : ordered_json(nullptr)},
          {"spread", s.spread_measured ? seen(s.spread, s.spread_stage) : ordered_json(nullptr)},
          {"ladders", {{"gain", parity::Sensitivity::gain_ladder()},
                       {"shift_texels", parity::Sensitivity::shift_ladder()},
                       {"spread", parity::Sensitivity::spread_ladder()}}},
          {"required_gain", r.required_gain},
          {"weak", r.weak()},
          {"strengthen_with", r.strengthen.empty() ? ordered_json(nullptr) : ordered_json(r.strengthen)}};
}

// What an error entering at `stage` would have shown (--sensitivity full), or null.
ordered_json stage_sensitivity_json(const ItemResult& r, const std::string& stage) {
  if (!r.sensitivity) return nullptr;
  for (const parity::StageSensitivity& s : r.sensitivity->stages)
    if (s.stage == stage)
      return {{"gain", seen(s.gain, s.gain_stage)},
              {"shift_texels", seen(s.shift, s.shift_stage)},
              {"spread", s.spread_measured ? seen(s.spread, s.spread_stage) : ordered_json(nullptr)}};
  return nullptr;
}

ordered_json stage_json(const parity::StageComparison& s) {
  ordered_json worst = ordered_json::array();
  for (const parity::WorstValue& w : s.worst) {
    ordered_json terms = ordered_json::object();
    for (const parity::Term& t : w.terms) terms[t.name] = t.value;
    worst.push_back({{"x", w.x}, {"y", w.y}, {"channel", std::string(1, "RGB"[w.channel])},
                     {"oracle", w.oracle}, {"captured", w.gl},
                     {"error", std::isfinite(w.error) ? ordered_json(w.error) : ordered_json("non-finite")},
                     {"bound", w.bound}, {"terms", terms}});
  }
  return {{"verdict", parity::to_string(s.verdict)}, {"reason", s.reason},
          {"values", s.values}, {"over_bound", s.over_bound},
          {"nonfinite_mismatch", s.nonfinite_mismatch}, {"within_fraction", s.within()},
          {"max_abs", s.max_abs}, {"max_rel", s.max_rel}, {"max_f16_ulps", s.max_ulp16},
          {"max_error_over_bound", std::isfinite(s.max_ratio) ? ordered_json(s.max_ratio)
                                                              : ordered_json("infinite")},
          {"mean_excess", s.mean_excess}, {"worst_window", s.worst_window},
          {"worst_window_at", {s.worst_window_x, s.worst_window_y}}, {"gate", s.gate},
          {"gate_id", s.gate_id}, {"gain", finite_or_string(s.gain)},
          {"gain_allowed", finite_or_string(s.gain_allowed)},
          {"gain_gate", finite_or_string(s.gain_ratio)},
          {"tile_gain_gate", finite_or_string(s.tile_gain_ratio)},
          {"tile_gain_at", {s.tile_x, s.tile_y}},
          {"envelope_gate", s.envelope_ratio < 0 ? ordered_json(nullptr) : finite_or_string(s.envelope_ratio)},
          {"envelope_outside_fraction", s.envelope_outside < 0 ? ordered_json(nullptr) : ordered_json(s.envelope_outside)},
          {"ulp_histogram_minus8_to_plus8", s.ulp_histogram}, {"worst", worst}};
}

ordered_json cause_json(const parity::CauseFit& c) {
  return {{"id", c.id}, {"description", c.description}, {"detail", c.detail},
          {"within_fraction", c.within}, {"oracle_within_fraction", c.oracle_within},
          {"likely", c.likely()}, {"as_likely", c.as_likely}, {"params", c.params},
          {"fitted", std::isfinite(c.low) && std::isfinite(c.high)
                         ? ordered_json{{"value", c.value}, {"low", c.low}, {"high", c.high}}
                         : ordered_json(nullptr)}};
}

ordered_json device_json(const DeviceKeys& d) {
  return {{"api", d.api}, {"vendor", d.vendor}, {"renderer", d.renderer}, {"driver", d.driver}};
}

using escape::xml;
using escape::markdown_cell;

// The cause of an item's first divergent stage, if one was found.
const parity::StageComparison* first_divergent(const ItemResult& r) {
  if (!r.parity.first_divergent_stage) return nullptr;
  for (const auto& s : r.parity.isolated)
    if (s.stage == *r.parity.first_divergent_stage) return &s;
  return nullptr;
}

struct Counts {
  int stages = 0, pass = 0, warn = 0, fail = 0, expected = 0, fixed = 0, errors = 0;
};

Counts count(const CheckRun& run) {
  Counts c;
  for (const ItemResult& r : run.items) {
    c.errors += !r.error.empty();
    for (const StageOutcome& o : r.outcomes) {
      ++c.stages;
      if (o.status == "pass") ++c.pass;
      else if (o.status == "warn") ++c.warn;
      else if (o.status == "fail") ++c.fail;
      else if (o.status == "expected-fail") ++c.expected;
      else if (o.status == "fixed") ++c.fixed;
    }
  }
  return c;
}

}  // namespace

ordered_json check_json(const CheckRun& run) {
  const Counts n = count(run);
  ordered_json items = ordered_json::array();
  for (const ItemResult& r : run.items) {
    ordered_json stages = ordered_json::array();
    for (std::size_t i = 0; i < r.parity.isolated.size(); ++i) {
      const auto& s = r.parity.isolated[i];
      const StageOutcome& o = r.outcomes[i];
      ordered_json causes = ordered_json::array();
      for (const parity::CauseFit& c : s.causes) causes.push_back(cause_json(c));
      const auto f = r.file_of.find(s.stage);
      stages.push_back(
          {{"stage", s.stage},
           {"file", f == r.file_of.end() || f->second.empty() ? ordered_json(nullptr)
                                                              : ordered_json(f->second)},
           {"status", o.status},
           {"follows_from", r.follows_from(i).empty() ? ordered_json(nullptr)
                                                       : ordered_json(r.follows_from(i))},
           {"expectation", o.expectation ? ordered_json({{"item", o.expectation->item},
                                                         {"stage", o.expectation->stage},
                                                         {"device", o.expectation->device},
                                                         {"reason", o.expectation->reason}})
                                         : ordered_json(nullptr)},
           {"isolated", stage_json(s)},
           {"end_to_end", stage_json(r.parity.end_to_end[i])},
           {"cause", s.causes.empty() ? ordered_json(nullptr) : cause_json(s.causes.front())},
           {"causes", causes},
           {"residual", s.residual.empty() ? ordered_json(nullptr) : ordered_json(s.residual)},
           {"sensitivity", stage_sensitivity_json(r, s.stage)}});
    }
    const parity::StageComparison* first = first_divergent(r);
    items.push_back(
        {{"id", r.id}, {"scene", r.source},
         {"stages_from", r.stages_from.empty() ? ordered_json(nullptr) : ordered_json(r.stages_from)},
         {"width", r.width}, {"height", r.height}, {"verdict", r.verdict},
         {"first_divergent_stage", r.parity.first_divergent_stage
                                       ? ordered_json(*r.parity.first_divergent_stage)
                                       : ordered_json(nullptr)},
         {"first_divergent_cause", first && !first->causes.empty()
                                       ? cause_json(first->causes.front())
                                       : ordered_json(nullptr)},
         {"first_nonfinite_stage", r.first_nonfinite().empty() ? ordered_json(nullptr)
                                                                : ordered_json(r.first_nonfinite())},
         {"ignored_files", r.ignored},
         {"error", r.error.empty() ? ordered_json(nullptr) : ordered_json(r.error)},
         {"sensitivity", sensitivity_json(r)},
         {"timings_ms", {{"load", r.load_ms}, {"oracle", r.oracle_ms}, {"judge", r.judge_ms},
                         {"sensitivity", r.sensitivity_ms}}},
         {"stages", stages}});
  }
  const parity::DeviceProfile& p = run.profile;
  return {{"version", 1},
          {"tool", "bloomref check"},
          {"verdict", run.verdict},
          {"exit_code", run.exit_code},
          {"warn_as_error", run.warn_as_error},
          {"params", params_json(run.params)},
          {"profile", {{"name", p.name}, {"source", p.source},
                       {"subtexel_bits", p.subtexel_bits},
                       {"half_nearest_even", p.half_nearest_even},
                       {"half_toward_zero", p.half_toward_zero},
                       {"flush_denormals", p.flush_denormals}, {"fma", p.fma}}},
          {"device", device_json(run.device)},
          {"expectations_file", run.expectations_file ? ordered_json(*run.expectations_file)
                                                      : ordered_json(nullptr)},
          {"peak_rss_bytes", [] {
             rusage u{};
             getrusage(RUSAGE_SELF, &u);
             return static_cast<long long>(u.ru_maxrss) * 1024;  // Linux: KiB
           }()},
          {"summary", {{"items", run.items.size()}, {"stages", n.stages}, {"pass", n.pass},
                       {"warn", n.warn}, {"fail", n.fail}, {"expected_fail", n.expected},
                       {"fixed", n.fixed}, {"errors", n.errors}}},
          {"batch", run.batch},
          {"output_errors", [&run] {
             ordered_json e = ordered_json::array();
             for (const CheckRun::OutputError& o : run.output_errors)
               e.push_back({{"option", o.option}, {"path", o.path}, {"error", o.why}});
             return e;
           }()},
          {"items", items}};
}

std::string junit_xml(const CheckRun& run) {
  const Counts n = count(run);
  auto failed = [&](const std::string& status) {
    return status == "fail" || (status == "warn" && run.warn_as_error);
  };
  std::string out = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  out += "<testsuites name=\"bloomref check\" tests=\"" + std::to_string(n.stages + n.errors) +
         "\" failures=\"" + std::to_string(n.fail + (run.warn_as_error ? n.warn : 0)) +
         "\" errors=\"" + std::to_string(n.errors) + "\" skipped=\"" + std::to_string(n.expected) +
         "\">\n";
  for (const ItemResult& r : run.items) {
    if (!r.error.empty()) {
      out += "  <testsuite name=\"" + xml(r.id) + "\" tests=\"1\" failures=\"0\" errors=\"1\" "
             "skipped=\"0\" time=\"0\">\n    <testcase classname=\"bloomref.check." + xml(r.id) +
             "\" name=\"stages\"><error message=\"" + xml(r.error) +
             "\" type=\"input\"/></testcase>\n  </testsuite>\n";
      continue;
    }
    int fails = 0, skipped = 0;
    for (const StageOutcome& o : r.outcomes) {
      fails += failed(o.status);
      skipped += o.status == "expected-fail";
    }
    const double seconds = (r.load_ms + r.oracle_ms + r.judge_ms) / 1000;
    out += "  <testsuite name=\"" + xml(r.id) + "\" tests=\"" + std::to_string(r.outcomes.size()) +
           "\" failures=\"" + std::to_string(fails) + "\" errors=\"0\" skipped=\"" +
           std::to_string(skipped) + "\" time=\"" + std::to_string(seconds) + "\">\n";
    out += "    <properties>\n";
    const std::pair<const char*, std::string> props[] = {
        {"scene", r.source},         {"profile", run.profile.name},
        {"device.api", run.device.api}, {"device.vendor", run.device.vendor},
        {"device.renderer", run.device.renderer}, {"device.driver", run.device.driver}};
    for (const auto& [k, v] : props)  // device keys nobody declared are left out
      if (!v.empty())
        out += "      <property name=\"" + std::string(k) + "\" value=\"" + xml(v) + "\"/>\n";
    if (r.sensitivity) {
      out += "      <property name=\"sensitivity\" value=\"" + xml(sensitivity_line(r)) + "\"/>\n";
      if (r.weak())
        out += "      <property name=\"weak-verdict\" value=\"" + xml(weak_line(r)) + "\"/>\n";
      for (const parity::StageSensitivity& st : r.sensitivity->stages)
        out += "      <property name=\"sensitivity." + xml(st.stage) + "\" value=\"" +
               xml(stage_sensitivity_line(st)) + "\"/>\n";
    }
    out += "    </properties>\n";
    if (r.outcomes.empty()) {
      out += "    <testcase classname=\"bloomref.check." + xml(r.id) +
             "\" name=\"stages\"><failure message=\"nothing compared: no stage image\" "
             "type=\"nothing\"/></testcase>\n";
    }
    for (std::size_t i = 0; i < r.outcomes.size(); ++i) {
      const auto& s = r.parity.isolated[i];
      const StageOutcome& o = r.outcomes[i];
      out += "    <testcase classname=\"bloomref.check." + xml(r.id) + "\" name=\"" + xml(s.stage) +
             "\">";
      const std::string cause = cause_line(s);
      const std::string line = r.first_line(i, action_line(s)) + "; " + s.reason +
                               (cause.empty() || !r.follows_from(i).empty() ? "" : "; " + cause);
      if (failed(o.status)) {
        out += "\n      <failure message=\"" + xml(line) + "\" type=\"" +
               parity::to_string(s.verdict) + "\">" +
               xml("end to end: " + r.parity.end_to_end[i].reason) + "</failure>";
      } else if (o.status == "expected-fail") {
        out += "\n      <skipped message=\"" + xml("expected failure: " + o.expectation->reason +
                                                    " (" + line + ")") + "\"/>";
      }
      // One <system-out> per testcase: a WARN's or a fixed deviation's note, then one
      // attachment line per image of a failing stage (the Jenkins JUnit attachments convention).
      std::string system_out;
      if (o.status == "warn") system_out = line + "\n";
      if (o.status == "pass") {  // the margin a passing stage had
        char b[128];
        std::snprintf(b, sizeof b, "largest error / bound: %.3g isolated, %.3g end to end\n",
                      s.max_ratio, r.parity.end_to_end[i].max_ratio);
        system_out = b;
      }
      if (o.status == "fixed")
        system_out = "a known deviation (" + o.expectation->reason +
                     ") now passes: remove the expectation\n";
      if (s.verdict != parity::Verdict::pass && !s.oracle.empty() && !run.report_dir.empty())
        for (const char* image : {".ratio.png", ".diff.png", ".mask.png"})
          system_out += "[[ATTACHMENT|" +
                        (fs::path(run.report_dir) / r.id / (s.stage + image)).string() + "]]\n";
      if (!system_out.empty()) out += "\n      <system-out>" + xml(system_out) + "</system-out>";
      out += "</testcase>\n";
    }
    out += "  </testsuite>\n";
  }
  return out + "</testsuites>\n";
}

namespace {

// One figure of a sensitivity ladder in words: `fmt` with the amount and the stage that failed
// it, or `none` when nothing of the ladder failed.
std::string seen_part(double v, const char* fmt, const char* none, const std::string& stage) {
  if (v <= 0) return none;
  char buf[160];
  std::snprintf(buf, sizeof buf, fmt, v);
  return std::string(buf) + " (at " + stage + ")";
}

std::string shape_parts(double shift, const std::string& shift_stage, bool spread_measured,
                        double spread, const std::string& spread_stage) {
  std::string out =
      ", " + seen_part(shift, "a shift of %g texel(s)", "no shift up to 8 texels", shift_stage);
  if (spread_measured)
    out += ", " + seen_part(spread > 0 ? 100 * (spread - 1) : 0, "a spread %.3g%% wider",
                            "no wider spread up to 50%", spread_stage);
  return out;
}

}  // namespace

std::string sensitivity_line(const ItemResult& r) {
  if (!r.sensitivity) return "not measured";
  const parity::Sensitivity& s = *r.sensitivity;
  std::string out = seen_part(s.gain, s.gain_at_most ? "a bloom gain of %.3gx or less" : "a bloom gain of %.3gx",
                              "no bloom gain up to 4x", s.gain_stage);
  if (!s.shape) return out;
  return out + shape_parts(s.shift, s.shift_stage, s.spread_measured, s.spread, s.spread_stage);
}

std::string stage_sensitivity_line(const parity::StageSensitivity& s) {
  return seen_part(s.gain, "a gain of %.3gx", "no gain up to 4x", s.gain_stage) +
         shape_parts(s.shift, s.shift_stage, s.spread_measured, s.spread, s.spread_stage);
}

std::string weak_line(const ItemResult& r) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "a bloom %.3gx too strong would not have failed", r.required_gain);
  std::string out = buf;
  if (!r.strengthen.empty()) out += "; " + r.strengthen + " to see more";
  return out;
}

std::string markdown_summary(const CheckRun& run) {
  const Counts n = count(run);
  const char* icon = run.verdict == "PASS" ? ":white_check_mark:" : run.verdict == "WARN" ? ":warning:" : ":x:";
  std::string out = "### bloomref check: " + std::string(icon) + " " + run.verdict + "\n\n";
  out += std::to_string(run.items.size()) + " item(s), " + std::to_string(n.stages) +
         " stage(s): " + std::to_string(n.pass) + " pass, " + std::to_string(n.warn) + " warn, " +
         std::to_string(n.fail) + " fail";
  if (n.expected) out += ", " + std::to_string(n.expected) + " expected failure(s)";
  if (n.fixed) out += ", " + std::to_string(n.fixed) + " known deviation(s) now passing";
  if (n.errors) out += ", " + std::to_string(n.errors) + " item(s) not read";
  out += ". Profile " + escape::markdown_code(run.profile.name);
  if (run.device.any()) {
    std::string d;
    for (const std::string& k : {run.device.api, run.device.vendor, run.device.renderer, run.device.driver})
      if (!k.empty()) d += (d.empty() ? "" : ", ") + k;
    out += ", device " + markdown_cell(d);
  }
  out += ".\n\n| item | verdict | first divergent stage | cause |\n|---|---|---|---|\n";
  for (const ItemResult& r : run.items) {
    const parity::StageComparison* first = first_divergent(r);
    out += "| " + markdown_cell(r.id) + " | " + markdown_cell(r.verdict) + (r.weak() ? " (weak verdict: " + markdown_cell(weak_line(r)) + ")" : "") + " | " +
           (r.parity.first_divergent_stage ? escape::markdown_code(*r.parity.first_divergent_stage) : "-") +
           " | " + (first ? markdown_cell(action_line(*first)) : !r.error.empty() ? markdown_cell(r.error) : "-") + " |\n";
  }
  // What each verdict could have seen: the bloom's, then an error entering at each stage.
  bool heading = false;
  for (const ItemResult& r : run.items) {
    if (!r.sensitivity) continue;
    if (!heading) out += "\n| item | error entering at | could see |\n|---|---|---|\n";
    heading = true;
    out += "| " + markdown_cell(r.id) + " | the bloom | " + markdown_cell(sensitivity_line(r)) + " |\n";
    for (const parity::StageSensitivity& st : r.sensitivity->stages)
      out += "| " + markdown_cell(r.id) + " | " + escape::markdown_code(st.stage) + " | " +
             markdown_cell(stage_sensitivity_line(st)) + " |\n";
  }
  return out;
}

}  // namespace bloomref::cli
