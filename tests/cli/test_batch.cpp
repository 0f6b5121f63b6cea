// cli/batch/ without files: frame patterns and lists as oiiotool writes them, shard selection from
// an environment map for every engine --shard auto reads, the progress line, and merging results
// documents written here by hand. Expected values are written out by hand.
#include <catch2/catch.hpp>
#include <functional>

#include "batch/frames.h"
#include "batch/merge.h"
#include "batch/progress.h"
#include "batch/shard.h"
#include "results.h"
#include "bloomref/error.h"

using bloomref::ParamError;
using namespace bloomref::batch;

namespace {

// The message of the ParamError `f` throws ("" when it throws none).
template <class F>
std::string error_of(F f) {
  try {
    f();
  } catch (const ParamError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("frame wildcards: #, @, %0Nd", "[batch]") {
  CHECK(FramePattern::parse("shot.####.exr").name(7) == "shot.0007.exr");
  CHECK(FramePattern::parse("shot.#.exr").name(7) == "shot.0007.exr");  // oiiotool: # = 4 digits
  CHECK(FramePattern::parse("shot.##.exr").name(7) == "shot.07.exr");
  CHECK(FramePattern::parse("shot.@@@.exr").name(7) == "shot.007.exr");
  CHECK(FramePattern::parse("shot.@.exr").name(7) == "shot.7.exr");
  CHECK(FramePattern::parse("shot.%04d.exr").name(7) == "shot.0007.exr");
  CHECK(FramePattern::parse("shot.%d.exr").name(7) == "shot.7.exr");
  CHECK(FramePattern::parse("shot_%06d").name(123) == "shot_000123");
  CHECK(FramePattern::parse("stages.####/").name(42) == "stages.0042/");
  // More digits than the padding: written in full; negative: as printf writes it.
  CHECK(FramePattern::parse("f.##.exr").name(12345) == "f.12345.exr");
  CHECK(FramePattern::parse("f.####.exr").name(-3) == "f.-003.exr");
  // A name without a wildcard, and a '%' that is not one.
  const FramePattern plain = FramePattern::parse("50%.exr");
  CHECK_FALSE(plain.has_wildcard());
  CHECK(plain.name(3) == "50%.exr");
  CHECK(FramePattern::parse("out.####.exr").padding() == 4);
  CHECK(has_frame_wildcard("a.#.exr"));
  CHECK_FALSE(has_frame_wildcard("a.exr"));
}

TEST_CASE("frame wildcards: the frame a file name stands for", "[batch]") {
  const FramePattern p = FramePattern::parse("dir/shot.####.exr");
  CHECK(p.frame_of("dir/shot.0042.exr") == 42);
  CHECK(p.frame_of("dir/shot.12345.exr") == 12345);
  CHECK(p.frame_of("dir/shot.-003.exr") == -3);
  CHECK_FALSE(p.frame_of("dir/shot.42.exr"));     // not the pattern's spelling
  CHECK_FALSE(p.frame_of("dir/shot.00042.exr"));  // nor this one
  CHECK_FALSE(p.frame_of("dir/shot.004a.exr"));
  CHECK_FALSE(p.frame_of("dir/shot.0042.exr.tmp"));
  CHECK_FALSE(p.frame_of("other/shot.0042.exr"));
  CHECK(FramePattern::parse("f.%d.exr").frame_of("f.7.exr") == 7);
  // Padding beyond 10 digits (found by fuzzing): the zeros are the pattern's, the frame reads back.
  const FramePattern wide = FramePattern::parse("f.################.exr");  // 16
  CHECK(wide.name(7) == "f.0000000000000007.exr");
  CHECK(wide.frame_of("f.0000000000000007.exr") == 7);
  CHECK(wide.frame_of("f.-000000000000007.exr") == -7);
  CHECK(FramePattern::parse("f.%016d.exr").frame_of("f.0000001234567890.exr") == std::nullopt);
  CHECK(FramePattern::parse("f.%016d.exr").frame_of("f.0000000123456789.exr") == 123456789);
}

TEST_CASE("bad frame patterns are named", "[batch]") {
  CHECK_THAT(error_of([] { FramePattern::parse("a.####.b.%04d.exr"); }),
             Catch::Contains("two frame wildcards") && Catch::Contains("'####' and '%04d'"));
  CHECK_THAT(error_of([] { FramePattern::parse("a.#@.exr"); }),
             Catch::Contains("mixes '#' and '@'"));
  CHECK_THAT(error_of([] { FramePattern::parse("a.%4d.exr"); }), Catch::Contains("write '%04d'"));
  CHECK_THAT(error_of([] { FramePattern::parse("a.%020d.exr"); }),
             Catch::Contains("more than 16 digits"));
  CHECK_THAT(error_of([] { FramePattern::parse("a.#################.exr"); }),  // 17
             Catch::Contains("more than 16 digits"));
  CHECK_THAT(error_of([] { FramePattern::parse("a.@@@@@@@@@@@@@@@@@.exr"); }),
             Catch::Contains("more than 16 digits"));
  CHECK(has_frame_wildcard("a.#@.exr"));  // malformed, still meant as a sequence
}

TEST_CASE("frame lists: ranges, steps, complements, lists", "[batch]") {
  using V = std::vector<int>;
  CHECK(parse_frame_list("1-5") == V{1, 2, 3, 4, 5});
  CHECK(parse_frame_list("7") == V{7});
  CHECK(parse_frame_list("1-10x3") == V{1, 4, 7, 10});
  CHECK(parse_frame_list("1-10y3") == V{2, 3, 5, 6, 8, 9});
  CHECK(parse_frame_list("1-9x2,12") == V{1, 3, 5, 7, 9, 12});
  CHECK(parse_frame_list("120,1-3") == V{1, 2, 3, 120});  // sorted
  CHECK(parse_frame_list("5-1") == V{1, 2, 3, 4, 5});     // counting down: the same frames
  CHECK(parse_frame_list("10-1x4") == V{2, 6, 10});       // 10, 6, 2
  CHECK(parse_frame_list("-10--2x4") == V{-10, -6, -2});
  CHECK(parse_frame_list("-2-1") == V{-2, -1, 0, 1});
  CHECK(parse_frame_list(" 1-2 , 4 ") == V{1, 2, 4});
  CHECK(parse_frame_list("1-100x2,120").size() == 51);
}

TEST_CASE("bad frame lists are named", "[batch]") {
  CHECK_THAT(error_of([] { parse_frame_list(""); }), Catch::Contains("--frames is empty"));
  CHECK_THAT(error_of([] { parse_frame_list("1-10,,20"); }), Catch::Contains("empty part"));
  CHECK_THAT(error_of([] { parse_frame_list("1-a"); }), Catch::Contains("'1-a' is not a frame"));
  CHECK_THAT(error_of([] { parse_frame_list("1-10x0"); }), Catch::Contains("must be 1 or more"));
  CHECK_THAT(error_of([] { parse_frame_list("1-10x"); }),
             Catch::Contains("'1-10x' is not a frame"));
  CHECK_THAT(error_of([] { parse_frame_list("5x2"); }), Catch::Contains("has a step but no range"));
  CHECK_THAT(error_of([] { parse_frame_list("1-10,5"); }),
             Catch::Contains("frame 5 is listed twice"));
  CHECK_THAT(error_of([] { parse_frame_list("1-20000000"); }),
             Catch::Contains("more than 10000000"));
  CHECK_THAT(error_of([] { parse_frame_list("1-2000000000"); }),
             Catch::Contains("beyond the frame numbers"));
  CHECK_THAT(error_of([] { parse_frame_list("1-2y1"); }), Catch::Contains("lists no frame"));
}

TEST_CASE("frame lists written compactly", "[batch]") {
  CHECK(format_frame_list({1, 2, 3, 4}) == "1-4");
  CHECK(format_frame_list({1, 3, 5, 7, 12}) == "1-7x2,12");
  CHECK(format_frame_list({4, 9}) == "4,9");
  CHECK(format_frame_list({4}) == "4");
  CHECK(format_frame_list({}) == "");
}

TEST_CASE("shard K/N takes every N-th item from K", "[batch]") {
  const Shard s = *resolve_shard("2/3", 0, {});
  CHECK(s.index == 1);
  CHECK(s.count == 3);
  CHECK(s.label() == "2/3");
  using P = std::vector<std::size_t>;
  CHECK(shard_positions(8, s) == P{1, 4, 7});
  CHECK(shard_positions(8, *resolve_shard("3/3", 0, {})) == P{2, 5});
  CHECK(shard_positions(2, *resolve_shard("3/3", 0, {})).empty());  // exit 5 in the CLI
  CHECK(shard_positions(5, *resolve_shard("1/1", 0, {})) == P{0, 1, 2, 3, 4});
  CHECK_FALSE(resolve_shard("", 0, {}));
}

TEST_CASE("bad --shard values are named", "[batch]") {
  CHECK_THAT(error_of([] { resolve_shard("3/2", 0, {}); }),
             Catch::Contains("shard 3 of 2 does not exist"));
  CHECK_THAT(error_of([] { resolve_shard("0/2", 0, {}); }), Catch::Contains("from 1 to"));
  CHECK_THAT(error_of([] { resolve_shard("2", 0, {}); }), Catch::Contains("is not K/N"));
  CHECK_THAT(error_of([] { resolve_shard("a/b", 0, {}); }), Catch::Contains("is 'b'"));
  CHECK_THAT(error_of([] { resolve_shard("1/0", 0, {}); }), Catch::Contains("is '0'"));
  CHECK_THAT(error_of([] { resolve_shard("1/2", 4, {}); }),
             Catch::Contains("--shard-count goes with --shard auto"));
  CHECK_THAT(error_of([] { resolve_shard("", 4, {}); }),
             Catch::Contains("--shard-count goes with"));
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 0, {{"PATH", "/bin"}});
             }),
             Catch::Contains("no shard variables are set"));
}

TEST_CASE("shard auto: Slurm arrays, dense and sparse", "[batch]") {
  // sbatch --array=1-4: ids 1..4 (Slurm 22.05 sets MIN, MAX, STEP, COUNT as below).
  const Shard a = *resolve_shard("auto", 0,
                                 {{"SLURM_ARRAY_TASK_ID", "3"},
                                  {"SLURM_ARRAY_TASK_MIN", "1"},
                                  {"SLURM_ARRAY_TASK_MAX", "4"},
                                  {"SLURM_ARRAY_TASK_STEP", "1"},
                                  {"SLURM_ARRAY_TASK_COUNT", "4"}});
  CHECK(a.label() == "3/4");
  CHECK_THAT(a.source, Catch::Contains("SLURM_ARRAY_TASK_ID=3"));
  // --array=0-9:3: ids 0, 3, 6, 9; id 6 is the third.
  const Shard b = *resolve_shard("auto", 0,
                                 {{"SLURM_ARRAY_TASK_ID", "6"},
                                  {"SLURM_ARRAY_TASK_MIN", "0"},
                                  {"SLURM_ARRAY_TASK_MAX", "9"},
                                  {"SLURM_ARRAY_TASK_STEP", "3"},
                                  {"SLURM_ARRAY_TASK_COUNT", "4"}});
  CHECK(b.label() == "3/4");
  // --array=1,2,5: measured MIN 1, MAX 5, STEP 1, COUNT 3: not evenly spaced.
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 0,
                             {{"SLURM_ARRAY_TASK_ID", "5"},
                              {"SLURM_ARRAY_TASK_MIN", "1"},
                              {"SLURM_ARRAY_TASK_MAX", "5"},
                              {"SLURM_ARRAY_TASK_STEP", "1"},
                              {"SLURM_ARRAY_TASK_COUNT", "3"}});
             }),
             Catch::Contains("not evenly spaced"));
  CHECK_THAT(
      error_of([] {
        resolve_shard("auto", 0, {{"SLURM_ARRAY_TASK_ID", "3"}, {"SLURM_ARRAY_TASK_MIN", "1"}});
      }),
      Catch::Contains("SLURM_ARRAY_TASK_COUNT is not"));
  // Slurm comes first even when a CI's variables are set too.
  const Shard c = *resolve_shard("auto", 0,
                                 {{"SLURM_ARRAY_TASK_ID", "0"},
                                  {"SLURM_ARRAY_TASK_MIN", "0"},
                                  {"SLURM_ARRAY_TASK_COUNT", "2"},
                                  {"CI_NODE_INDEX", "2"},
                                  {"CI_NODE_TOTAL", "2"}});
  CHECK(c.label() == "1/2");
}

TEST_CASE("shard auto: Kubernetes, GitLab, Bazel, GoogleTest, Buildkite, CircleCI", "[batch]") {
  CHECK(resolve_shard("auto", 5, {{"JOB_COMPLETION_INDEX", "0"}})->label() == "1/5");
  CHECK(resolve_shard("auto", 5, {{"JOB_COMPLETION_INDEX", "4"}})->label() == "5/5");
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 0, {{"JOB_COMPLETION_INDEX", "0"}});
             }),
             Catch::Contains("pass --shard-count"));
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 5, {{"JOB_COMPLETION_INDEX", "5"}});
             }),
             Catch::Contains("shard 6 of 5"));
  // GitLab counts from 1.
  CHECK(resolve_shard("auto", 0, {{"CI_NODE_INDEX", "1"}, {"CI_NODE_TOTAL", "3"}})->label() ==
        "1/3");
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 0, {{"CI_NODE_INDEX", "0"}, {"CI_NODE_TOTAL", "3"}});
             }),
             Catch::Contains("CI_NODE_INDEX is '0'"));
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 0, {{"CI_NODE_INDEX", "1"}});
             }),
             Catch::Contains("CI_NODE_TOTAL is not"));
  // The others from 0.
  const Shard bazel = *resolve_shard("auto", 0,
                                     {{"TEST_SHARD_INDEX", "1"},
                                      {"TEST_TOTAL_SHARDS", "2"},
                                      {"TEST_SHARD_STATUS_FILE", "/tmp/x"}});
  CHECK(bazel.label() == "2/2");
  CHECK(bazel.status_file == "/tmp/x");
  CHECK(resolve_shard("auto", 0, {{"GTEST_SHARD_INDEX", "0"}, {"GTEST_TOTAL_SHARDS", "4"}})
            ->label() == "1/4");
  CHECK(resolve_shard("auto", 0,
                      {{"BUILDKITE_PARALLEL_JOB", "3"}, {"BUILDKITE_PARALLEL_JOB_COUNT", "4"}})
            ->label() == "4/4");
  CHECK(
      resolve_shard("auto", 0, {{"CIRCLE_NODE_INDEX", "2"}, {"CIRCLE_NODE_TOTAL", "3"}})->label() ==
      "3/3");
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 0, {{"CIRCLE_NODE_INDEX", "3"}, {"CIRCLE_NODE_TOTAL", "3"}});
             }),
             Catch::Contains("shard 4 of 3"));
  // A --shard-count must agree with the engine's own total.
  CHECK_THAT(error_of([] {
               resolve_shard("auto", 2, {{"CI_NODE_INDEX", "1"}, {"CI_NODE_TOTAL", "3"}});
             }),
             Catch::Contains("contradicts GitLab"));
  CHECK(resolve_shard("auto", 3, {{"CI_NODE_INDEX", "1"}, {"CI_NODE_TOTAL", "3"}})->label() ==
        "1/3");
}

// --- progress ---

TEST_CASE("progress: durations and the bar", "[batch]") {
  CHECK(format_duration(0.44) == "0.4s");
  CHECK(format_duration(12.4) == "12s");
  CHECK(format_duration(185) == "3m05s");
  CHECK(format_duration(7620) == "2h07m");
  // 37 of 240 in 15.35 s: 2.4104/s, 203 left / 2.4104 = 84.2 s; a 40-column bar 37/240 full = 6.
  CHECK(progress_bar(37, 240, 15.35, 80) ==
        "[======>" + std::string(33, ' ') + "]  37/240 frames  2.41/s  1m24s left");
  CHECK(progress_bar(0, 10, 0, 80) ==
        "[>" + std::string(39, ' ') + "]  0/10 frames  --/s  -- left");
  CHECK(progress_bar(10, 10, 5, 80) ==
        "[" + std::string(40, '=') + "]  10/10 frames  2.00/s  0.0s left");
  CHECK(progress_bar(37, 240, 15.35, 30) ==
        "37/240 frames  2.41/s  1m24s left");  // no room for a bar
  CHECK(progress_bar(3, 4, 1, 80, "items") ==
        "[" + std::string(30, '=') + ">" + std::string(9, ' ') + "]  3/4 items  3.00/s  0.3s left");
}

// --- merge ---

namespace {

using nlohmann::ordered_json;

ordered_json run_item(const std::string& id, const std::string& status = "done") {
  return {{"id", id}, {"status", status}, {"wall_ms", 10.0}};
}

ordered_json run_doc(const std::string& label, ordered_json items, bool finished = true,
                     int threads = 2, int passes = 10) {
  return {{"version", 1},
          {"tool", "bloomref run"},
          {"kind", "sequence"},
          {"params", {{"passes", passes}, {"threads", threads}}},
          {"batch",
           {{"item_ids", {"1", "2", "3"}},
            {"shard", {{"label", label}, {"source", "test"}}},
            {"finished", finished},
            {"interrupted", !finished}}},
          {"exit_code", 0},
          {"items", items}};
}

ordered_json check_item(const std::string& id, const std::string& verdict,
                        std::vector<std::string> stage_statuses) {
  ordered_json stages = ordered_json::array();
  for (const std::string& s : stage_statuses)
    stages.push_back({{"stage", "blur.1"}, {"status", s}, {"isolated", {{"reason", "r"}}}});
  return {{"id", id}, {"verdict", verdict}, {"error", nullptr}, {"stages", stages}};
}

ordered_json check_doc(ordered_json items, bool warn_as_error = false) {
  return {{"version", 1},
          {"tool", "bloomref check"},
          {"verdict", "PASS"},
          {"exit_code", 0},
          {"warn_as_error", warn_as_error},
          {"params", {{"passes", 10}}},
          {"batch", {{"item_ids", {"a", "b"}}, {"shard", nullptr}, {"finished", true}}},
          {"items", items}};
}

std::vector<std::string> ids_of(const ordered_json& doc) {
  std::vector<std::string> v;
  for (const auto& it : doc["items"]) v.push_back(it["id"]);
  return v;
}

template <class F>
std::string input_error_of(F f) {
  try {
    f();
  } catch (const bloomref::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("merge: every item once gives the items in list order", "[batch]") {
  // Shard 1/2 ran items 1 and 3, shard 2/2 item 2, on a machine with another thread count.
  const Merged m =
      merge_results({{"r1.json", run_doc("1/2", {run_item("1"), run_item("3", "resumed")})},
                     {"r2.json", run_doc("2/2", {run_item("2")}, true, 16)}});
  CHECK(m.exit_code == 0);
  CHECK(m.problems.empty());
  CHECK(ids_of(m.doc) == std::vector<std::string>{"1", "2", "3"});
  CHECK(m.doc["items"][1]["shard"] == "2/2");
  CHECK(m.doc["items"][1]["results_file"] == "r2.json");
  CHECK(m.doc["summary"]["done"] == 2);
  CHECK(m.doc["summary"]["resumed"] == 1);
  CHECK(m.doc["batch"]["complete"] == true);
  CHECK(m.doc["batch"]["shards"].size() == 2);
}

TEST_CASE("merge: a missing item, an item run twice, an unfinished shard", "[batch]") {
  const Merged missing =
      merge_results({{"r1.json", run_doc("1/2", {run_item("1"), run_item("3")})}});
  CHECK(missing.exit_code == 2);
  CHECK(missing.missing == std::vector<std::string>{"2"});
  REQUIRE_FALSE(missing.problems.empty());
  CHECK(missing.problems[0] == "1 of 3 items missing: 2");
  CHECK(missing.doc["batch"]["complete"] == false);

  const Merged twice = merge_results({{"r1.json", run_doc("1/2", {run_item("1"), run_item("3")})},
                                      {"r2.json", run_doc("2/2", {run_item("2"), run_item("3")})}});
  CHECK(twice.exit_code == 2);
  CHECK(twice.duplicates == std::vector<std::string>{"3"});
  CHECK(twice.missing.empty());
  REQUIRE(twice.problems.size() == 1);
  CHECK(twice.problems[0] == "item 3 was run 2 times (r1.json, r2.json)");

  const Merged unfinished = merge_results(
      {{"r1.json", run_doc("1/1", {run_item("1"), run_item("2"), run_item("3")}, false)}});
  CHECK(unfinished.exit_code == 2);
  REQUIRE(unfinished.problems.size() == 1);
  CHECK_THAT(unfinished.problems[0], Catch::Contains("did not finish (interrupted)"));
}

TEST_CASE("merge: run items' errors decide the exit code", "[batch]") {
  ordered_json bad = run_item("2", "error");
  bad["error"] = "in.0002.exr: no such file";
  bad["exit_code"] = 2;
  ordered_json internal = run_item("3", "error");
  internal["exit_code"] = 4;
  const Merged m = merge_results({{"r.json", run_doc("1/1", {run_item("1"), bad, internal})}});
  CHECK(m.problems.empty());
  CHECK(m.exit_code == 4);
  CHECK(m.doc["summary"]["error"] == 2);
  const std::string junit = merged_junit(m);
  CHECK_THAT(junit,
             Catch::Contains("tests=\"3\" failures=\"0\" errors=\"1\""));  // item 3 has no message
  CHECK_THAT(junit, Catch::Contains("<error message=\"in.0002.exr: no such file\""));
}

TEST_CASE("merge: check verdicts and counts over all shards", "[batch]") {
  const Merged pass =
      merge_results({{"a.json", check_doc({check_item("a", "PASS", {"pass", "pass"})})},
                     {"b.json", check_doc({check_item("b", "WARN", {"pass", "warn"})})}});
  CHECK(pass.exit_code == 0);
  CHECK(pass.doc["verdict"] == "WARN");
  CHECK(pass.doc["summary"]["stages"] == 4);
  CHECK(pass.doc["summary"]["pass"] == 3);
  CHECK(pass.doc["summary"]["warn"] == 1);

  const Merged strict = merge_results(
      {{"a.json",
        check_doc({check_item("a", "PASS", {"pass"}), check_item("b", "WARN", {"warn"})}, true)}});
  CHECK(strict.doc["verdict"] == "FAIL");
  CHECK(strict.exit_code == 1);

  ordered_json error = check_item("b", "ERROR", {});
  error["error"] = "st.0002/: is not a folder";
  const Merged err =
      merge_results({{"a.json", check_doc({check_item("a", "FAIL", {"fail"}), error})}});
  CHECK(err.doc["verdict"] == "ERROR");
  CHECK(err.exit_code == 2);
  CHECK(err.doc["summary"]["errors"] == 1);
  CHECK(err.doc["summary"]["fail"] == 1);

  const Merged half = merge_results({{"a.json", check_doc({check_item("a", "PASS", {"pass"})})}});
  CHECK(half.exit_code == 2);
  CHECK(half.missing == std::vector<std::string>{"b"});
  const std::string junit = merged_junit(half);
  CHECK_THAT(junit, Catch::Contains("type=\"missing\""));
  CHECK_THAT(junit, Catch::Contains("tests=\"2\" failures=\"0\" errors=\"1\""));
  const std::string md = merged_markdown(half);
  CHECK_THAT(md, Catch::Contains("### bloomref check (merged): :x: INCOMPLETE"));
  CHECK_THAT(md, Catch::Contains("- :x: 1 of 2 items missing: b"));
  const std::string html = merged_html(half, {"a"});
  CHECK_THAT(html, Catch::Contains("<a href=\"a/index.html\">a</a>"));
  CHECK_THAT(html, Catch::Contains("MISSING"));
  CHECK_THAT(html, Catch::Contains("INCOMPLETE"));
}

TEST_CASE("merge keeps the cause check named, in JUnit and Markdown", "[batch]") {
  ordered_json a = check_item("a", "FAIL", {"fail"});
  const ordered_json cause = {{"id", "tap-spacing"}, {"description", "taps spaced another distance apart"},
                              {"detail", "taps 2x as far apart on x"}};
  a["stages"][0]["cause"] = cause;
  a["first_divergent_stage"] = "blur.1";
  a["first_divergent_cause"] = cause;
  const Merged m = merge_results(
      {{"a.json", check_doc({a, check_item("b", "PASS", {"pass"})})}});
  CHECK_THAT(merged_junit(m),
             Catch::Contains("cause: taps spaced another distance apart (taps 2x as far apart on x)"));
  CHECK_THAT(merged_markdown(m), Catch::Contains("cause: taps spaced another distance apart"));
}

TEST_CASE("merge refuses files of different runs, naming them", "[batch]") {
  CHECK_THAT(input_error_of([] {
               ordered_json other = run_doc("2/2", {run_item("2")});
               other["batch"]["item_ids"] = {"1", "2"};
               merge_results({{"r1.json", run_doc("1/2", {run_item("1")})}, {"r2.json", other}});
             }),
             Catch::Contains("r2.json: lists other items (2) than r1.json (3)"));
  CHECK_THAT(input_error_of([] {
               merge_results({{"r1.json", run_doc("1/2", {run_item("1")})},
                              {"r2.json", run_doc("2/2", {run_item("2")}, true, 2, 8)}});
             }),
             Catch::Contains("r2.json: was run with other parameters"));
  CHECK_THAT(input_error_of([] {
               merge_results({{"r1.json", run_doc("1/2", {run_item("1")})},
                              {"c.json", check_doc(ordered_json::array())}});
             }),
             Catch::Contains("c.json: holds bloomref check results"));
  CHECK_THAT(input_error_of([] {
               ordered_json one = run_doc("1/1", ordered_json::array());
               one.erase("kind");
               merge_results({{"one.json", one}});
             }),
             Catch::Contains("one.json: holds the results of one image"));
  CHECK_THAT(input_error_of([] {
               ordered_json plain = check_doc(ordered_json::array());
               plain.erase("batch");
               merge_results({{"plain.json", plain}});
             }),
             Catch::Contains("plain.json: has no item list"));
  CHECK_THAT(input_error_of([] {
               merge_results({{"x.json", ordered_json::array()}});
             }),
             Catch::Contains("x.json: is not a bloomref results file"));
}

TEST_CASE("merge refuses a field of another type than it reads, naming file and field",
          "[batch]") {
  // Found by fuzzing: such a field made nlohmann's value() throw a type_error (exit 4).
  struct Case {
    const char* what;
    std::function<void(ordered_json&)> spoil;
  };
  const Case cases[] = {
      {"\"version\" is not a number", [](ordered_json& d) { d["version"] = {{"a", 1}}; }},
      {"\"kind\" is not a string", [](ordered_json& d) { d["kind"] = 3; }},
      {"batch: \"finished\" is not true or false", [](ordered_json& d) { d["batch"]["finished"] = "yes"; }},
      {"batch.shard: \"label\" is not a string", [](ordered_json& d) { d["batch"]["shard"]["label"] = 2; }},
      {"batch.item_ids: an id is not a string", [](ordered_json& d) { d["batch"]["item_ids"][1] = 2; }},
      {"item \"1\": \"wall_ms\" is not a number", [](ordered_json& d) { d["items"][0]["wall_ms"] = "10"; }},
      {"item \"1\": \"status\" is not a string", [](ordered_json& d) { d["items"][0]["status"] = true; }},
      {"item \"1\": \"outputs\" is not an array", [](ordered_json& d) { d["items"][0]["outputs"] = "o.exr"; }},
  };
  for (const Case& c : cases) {
    ordered_json d = run_doc("1/1", {run_item("1")});
    c.spoil(d);
    INFO(c.what);
    CHECK_THAT(input_error_of([&] { merge_results({{"r.json", d}}); }),
               Catch::Contains(std::string("r.json: ") + c.what));
  }
  ordered_json c = check_doc({check_item("a", "PASS", {"pass"})});
  c["items"][0]["stages"][0]["isolated"] = "r";
  CHECK_THAT(input_error_of([&] { merge_results({{"c.json", c}}); }),
             Catch::Contains("c.json: item \"a\": stage: \"isolated\" is not an object"));
}

TEST_CASE("merge: a known deviation is unused only when no shard used it", "[batch]") {
  const ordered_json a = {{"item", "*"}, {"stage", "blur.3"}, {"device", ""}, {"reason", "a"}};
  const ordered_json b = {{"item", "*"}, {"stage", "up.1"}, {"device", ""}, {"reason", "b"}};
  ordered_json one = check_doc({check_item("a", "PASS", {"pass"})});
  ordered_json two = check_doc({check_item("b", "PASS", {"pass"})});
  one["unused_expectations"] = {a, b};  // shard 1 used neither
  two["unused_expectations"] = {b};     // shard 2 used a
  const Merged m = merge_results({{"1.json", one}, {"2.json", two}});
  CHECK(m.doc["unused_expectations"] == ordered_json({b}));
}

TEST_CASE("results: a stage that fails only end to end says so", "[batch]") {
  ordered_json item = check_item("a", "FAIL", {"fail"});
  ordered_json& s = item["stages"][0];
  s["action"] = nullptr;  // it passes in isolation
  s["isolated"] = {{"verdict", "PASS"}, {"reason", "every value within its bound"}};
  s["end_to_end"] = {{"verdict", "FAIL"}, {"reason", "12 values exceed 4x their bound"}};
  const std::string junit = bloomref::results::junit(check_doc({item}));
  CHECK_THAT(junit, Catch::Contains("message=\"blur.1: FAIL end to end \u2014 12 values exceed"));
}

TEST_CASE("results: past 50 items the Markdown lists those that did not pass", "[batch]") {
  ordered_json items = ordered_json::array();
  for (int i = 0; i < 54; ++i) items.push_back(check_item("p" + std::to_string(i), "PASS", {"pass"}));
  items.push_back(check_item("bad", "FAIL", {"fail"}));
  const std::string md = bloomref::results::markdown(check_doc(items));
  CHECK_THAT(md, Catch::Contains("| bad | FAIL |"));
  CHECK_THAT(md, !Catch::Contains("| p0 |"));
  CHECK_THAT(md, Catch::Contains("54 item(s) that passed are not listed."));
  items.erase(items.begin() + 10, items.begin() + 54);  // 11 items: every one listed
  CHECK_THAT(bloomref::results::markdown(check_doc(items)), Catch::Contains("| p0 | PASS |"));
}

TEST_CASE("results: documents with missing fields or other types are written, not thrown",
          "[batch]") {
  using bloomref::results::console;
  using bloomref::results::junit;
  using bloomref::results::markdown;
  const char* odd[] = {
      R"({})",
      R"({"items": 5, "batch": "x", "profile": 1})",
      R"({"items": [1, "a", null]})",
      R"({"items": [{"id": 7, "width": "wide", "height": 1e300, "stages": "x"}]})",
      R"({"items": [{"stages": [{"status": 3, "isolated": 2, "action": 1,
                                 "report_images": [1, "x"], "sensitivity": {"gain": 4}}],
                     "sensitivity": {"gain": {"smallest_failed": "big"}}}],
          "batch": {"shards": 1, "missing": [1, "m"], "duplicates": "d"}})"};
  for (const char* text : odd) {
    INFO(text);
    const ordered_json d = ordered_json::parse(text);
    CHECK_NOTHROW(console(d));
    CHECK_NOTHROW(junit(d));
    CHECK_NOTHROW(markdown(d));
  }
}
