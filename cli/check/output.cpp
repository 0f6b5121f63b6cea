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

ordered_json text_or_null(const std::string& s) { return s.empty() ? ordered_json(nullptr) : ordered_json(s); }

// The report's images of a stage that did not pass (--report, when it holds them).
ordered_json report_images(const CheckRun& run, const ItemResult& r, const parity::StageComparison& s) {
  ordered_json images = ordered_json::array();
  if (s.verdict == parity::Verdict::pass || s.oracle.empty() || run.report_dir.empty()) return images;
  for (const char* image : {".ratio.png", ".diff.png", ".mask.png"})
    images.push_back((fs::path(run.report_dir) / r.id / (s.stage + image)).string());
  return images;
}

ordered_json device_json(const DeviceKeys& d) {
  return {{"api", d.api}, {"vendor", d.vendor}, {"renderer", d.renderer}, {"driver", d.driver}};
}

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
           {"action", text_or_null(r.first_line(i, action_line(s)))},
           {"explanation", text_or_null(cause_line(s))},
           {"expectation", o.expectation ? ordered_json({{"item", o.expectation->item},
                                                         {"stage", o.expectation->stage},
                                                         {"device", o.expectation->device},
                                                         {"reason", o.expectation->reason}})
                                         : ordered_json(nullptr)},
           {"carried", s.carried_from.empty()
                           ? ordered_json(nullptr)
                           : ordered_json({{"from", s.carried_from}, {"share_of_bound", s.carried_share}})},
           {"isolated", stage_json(s)},
           {"end_to_end", stage_json(r.parity.end_to_end[i])},
           {"cause", s.causes.empty() ? ordered_json(nullptr) : cause_json(s.causes.front())},
           {"causes", causes},
           {"residual", s.residual.empty() ? ordered_json(nullptr) : ordered_json(s.residual)},
           {"sensitivity", stage_sensitivity_json(r, s.stage)},
           {"report_images", report_images(run, r, s)}});
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
          {"unused_expectations", [&run] {
             ordered_json e = ordered_json::array();
             for (const Expectation& x : run.unused_expectations)
               e.push_back({{"item", x.item}, {"stage", x.stage}, {"device", x.device}, {"reason", x.reason}});
             return e;
           }()},
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

}  // namespace bloomref::cli
