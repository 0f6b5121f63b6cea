// Frame sequences, shards and merge as a job engine runs them (the build's bloomref, a separate
// process, in a temporary folder): each frame of a sequence has the bits of a single-image run;
// a missing frame is named and the rest go on; --resume redoes only what is not whole; Ctrl-C
// leaves no partial file; every engine's shard variables split the frames so that merge finds
// each exactly once; check takes frames and shards too; bad values are exit 2, named.
#include <signal.h>
#include <sys/wait.h>

#include <chrono>
#include <thread>

#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <nlohmann/json.hpp>

#include "bloomref/io.h"
#include "test_util.h"

using bloomref::test::CliResult;
using bloomref::test::TempDir;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

CliResult run_cli(const TempDir& cwd, const std::string& args, const std::string& env = "") {
  return bloomref::test::run_cli(args, env, cwd.path());
}

// Every variable --shard auto reads unset, so that the job running the tests cannot decide.
const std::string kNoShardVars =
    "env -u SLURM_ARRAY_TASK_ID -u JOB_COMPLETION_INDEX -u CI_NODE_INDEX -u TEST_SHARD_INDEX "
    "-u GTEST_SHARD_INDEX -u BUILDKITE_PARALLEL_JOB -u CIRCLE_NODE_INDEX";

// Frames 1..n of a 48x40 sequence 'in.####.exr': a dim background and a 3x3 light of 8 that
// moves 5 pixels a frame, so that every frame's output differs.
void write_frames(const TempDir& dir, int n, const std::string& prefix = "in.") {
  for (int f = 1; f <= n; ++f) {
    bloomref::Image img = bloomref::test::constant_image(48, 40, 0.2f);
    for (int y = 18; y < 21; ++y)
      for (int x = 5 * f; x < 5 * f + 3; ++x)
        for (int c = 0; c < 3; ++c) img.pixel(x, y)[c] = 8.0f;
    char name[64];
    std::snprintf(name, sizeof name, "%s%04d.exr", prefix.c_str(), f);
    bloomref::save_exr(dir / name, img.cview());
  }
}

bloomref::Image load(const std::string& path) {
  return bloomref::load_image(path).image;
}

// The output of the single-image run of `input` (a separate process, its own folder).
bloomref::Image single_run(const std::string& input, const std::string& extra = "") {
  TempDir d;
  const CliResult r =
      bloomref::test::run_cli("run '" + input + "' -o one.exr -q " + extra, "", d.path());
  REQUIRE(r.code == 0);
  return load(d / "one.exr");
}

json read_json(const std::string& path) {
  return json::parse(bloomref::test::read_bytes(path));
}

std::vector<std::string> ids(const json& results) {
  std::vector<std::string> v;
  for (const json& it : results["items"]) v.push_back(it["id"]);
  return v;
}

bool has_hidden_files(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (!n.empty() && n[0] == '.') return true;
  }
  return false;
}

bool has_hidden_files(const TempDir& dir) {
  return has_hidden_files(dir.path());
}

}  // namespace

TEST_CASE("run over a sequence: each frame has the bits of its single-image run", "[sequence]") {
  TempDir dir;
  write_frames(dir, 4);
  const CliResult r = run_cli(dir,
                              "run 'in.####.exr' --frames 1-4 -o 'out.%04d.exr' -o 'out.@@@@.png' "
                              "--json r.json --progress lines");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("[4/4] 0004: done"));
  for (int f = 1; f <= 4; ++f) {
    const std::string n = "000" + std::to_string(f);
    CHECK(bloomref::test::bit_identical(load(dir / ("out." + n + ".exr")).cview(),
                                        single_run(dir / ("in." + n + ".exr")).cview()));
    CHECK(fs::exists(dir / ("out." + n + ".png")));
  }
  const json j = read_json(dir / "r.json");
  CHECK(j["tool"] == "bloomref run");
  CHECK(j["kind"] == "sequence");
  CHECK(j["exit_code"] == 0);
  CHECK(j["batch"]["items_total"] == 4);
  CHECK(j["batch"]["finished"] == true);
  CHECK(j["batch"]["shard"].is_null());
  CHECK(ids(j) == std::vector<std::string>{"0001", "0002", "0003", "0004"});
  CHECK(j["items"][2]["input"] == "in.0003.exr");
  CHECK(j["items"][2]["outputs"][0] == "out.0003.exr");
  CHECK(j["items"][2]["width"] == 48);
  CHECK(j["summary"]["done"] == 4);

  // Without --frames, the frames are the files that match; two frames at once give the same bits.
  const CliResult found = run_cli(dir, "run 'in.####.exr' -o 'j.####.exr' --jobs 2 -q");
  REQUIRE(found.code == 0);
  for (int f = 1; f <= 4; ++f) {
    const std::string n = "000" + std::to_string(f);
    CHECK(bloomref::test::bit_identical(load(dir / ("j." + n + ".exr")).cview(),
                                        load(dir / ("out." + n + ".exr")).cview()));
  }
}

TEST_CASE("a missing frame is named, the rest go on, and the exit code says so", "[sequence]") {
  TempDir dir;
  write_frames(dir, 4);
  fs::remove(dir / "in.0003.exr");
  const CliResult r = run_cli(
      dir, "run 'in.####.exr' --frames 1-4 -o 'out.####.exr' --json r.json --progress lines");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("frame 0003: in.0003.exr: no such file"));
  CHECK_THAT(r.out, Catch::Contains("1 failed (frame 3)"));
  CHECK(fs::exists(dir / "out.0004.exr"));
  CHECK_FALSE(fs::exists(dir / "out.0003.exr"));
  const json j = read_json(dir / "r.json");
  CHECK(j["exit_code"] == 2);
  CHECK(j["items"][2]["status"] == "error");
  CHECK(j["items"][2]["frame"] == 3);
  CHECK_THAT(j["items"][2]["error"].get<std::string>(), Catch::Contains("no such file"));
  CHECK(j["items"][3]["status"] == "done");
}

TEST_CASE("resume redoes only the frames whose outputs are not whole", "[sequence]") {
  TempDir dir;
  write_frames(dir, 3);
  REQUIRE(run_cli(dir, "run 'in.####.exr' -o 'out.####.exr' --dump-stages 'st.####/' -q").code ==
          0);
  const std::string first = bloomref::test::read_bytes(dir / "out.0001.exr");
  const auto first_time = fs::last_write_time(dir / "out.0001.exr");
  // Frame 2's output cut short (as a copy killed half-way would leave it), frame 3's gone, and a
  // stage of frame 1 gone.
  const std::string two = bloomref::test::read_bytes(dir / "out.0002.exr");
  bloomref::test::write_bytes(dir / "out.0002.exr", two.substr(0, two.size() / 2));
  fs::remove(dir / "out.0003.exr");
  fs::copy_file(dir / "out.0001.exr", dir / "keep.exr");
  const CliResult r = run_cli(dir, "run 'in.####.exr' -o 'out.####.exr' --resume --progress lines");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Catch::Contains("0001: resumed"));
  CHECK_THAT(r.out, Catch::Contains("0002: done"));
  CHECK_THAT(r.out, Catch::Contains("0003: done"));
  CHECK(bloomref::test::read_bytes(dir / "out.0001.exr") == first);
  CHECK(fs::last_write_time(dir / "out.0001.exr") == first_time);
  CHECK(bloomref::test::bit_identical(load(dir / "out.0002.exr").cview(),
                                      single_run(dir / "in.0002.exr").cview()));
  CHECK(fs::exists(dir / "out.0003.exr"));

  // With --dump-stages, a frame is whole when every stage file is.
  fs::remove(dir / "st.0001/blur.4.exr");
  const CliResult s = run_cli(dir,
                              "run 'in.####.exr' -o 'out.####.exr' --dump-stages 'st.####/' "
                              "--resume --progress lines");
  REQUIRE(s.code == 0);
  CHECK_THAT(s.out, Catch::Contains("0001: done"));
  CHECK_THAT(s.out, Catch::Contains("0002: resumed"));
  CHECK(fs::exists(dir / "st.0001/blur.4.exr"));
}

TEST_CASE("SIGINT stops after the frame in flight and leaves no partial file", "[sequence]") {
  TempDir dir;
  // 12 frames of 480x270 (about 0.1 s each on a 2-core machine): the signal comes once the first
  // one exists.
  const std::string cmd =
      "cd '" + dir.path().string() +
      "' && ('" BLOOMREF_EXE
      "' run --scene demo "
      "--size 480x270 --frames 1-12 -o 'o.####.exr' --json r.json --progress lines "
      ">out.txt 2>err.txt & pid=$!; "
      "for i in $(seq 600); do [ -e o.0001.exr ] && break; sleep 0.01; done; "
      "kill -INT $pid; wait $pid; echo $? >rc.txt)";
  REQUIRE(std::system(cmd.c_str()) == 0);
  CHECK(std::stoi(bloomref::test::read_bytes(dir / "rc.txt")) == 130);
  CHECK_THAT(bloomref::test::read_bytes(dir / "err.txt"),
             Catch::Contains("stopping after the items in flight"));
  CHECK_FALSE(has_hidden_files(dir));  // no temporary file left
  int outputs = 0;
  for (const std::string& n : dir.listing())
    if (n.rfind("o.", 0) == 0) {
      ++outputs;
      CHECK(load(dir / n).width() == 480);  // whole files only
    }
  CHECK(outputs >= 1);
  CHECK(outputs < 12);
  const json j = read_json(dir / "r.json");
  CHECK(j["batch"]["finished"] == false);
  CHECK(j["batch"]["interrupted"] == true);
  CHECK(j["exit_code"] == 130);
  CHECK(static_cast<int>(j["items"].size()) == outputs);
  // merge says what is missing; --resume does the rest, and then merge is complete.
  const CliResult partial = run_cli(dir, "merge r.json");
  CHECK(partial.code == 2);
  CHECK_THAT(partial.err, Catch::Contains("items missing"));
  CHECK_THAT(partial.err, Catch::Contains("did not finish (interrupted)"));
  REQUIRE(run_cli(dir,
                  "run --scene demo --size 480x270 --frames 1-12 -o 'o.####.exr' --json r.json "
                  "--resume -q")
              .code == 0);
  CHECK(run_cli(dir, "merge r.json -q").code == 0);
}

TEST_CASE("a sequence killed while it writes, then resumed, has every frame whole, once",
          "[sequence]") {
  TempDir dir;
  write_frames(dir, 8);
  // 8 frames of 48x40 with every stage dumped, written with one thread so that each frame
  // spends a while writing. SIGKILL cannot be caught: whatever the process was writing is cut.
  const std::vector<std::string> args = {
      "run", "in.####.exr", "-o", "out.####.exr", "--dump-stages", "st.####/", "--threads", "1",
      "--json", "r.json", "-q"};
  const int pid = bloomref::test::spawn_cli(args, dir.path(), {});
  const auto t0 = std::chrono::steady_clock::now();
  bool mid = false;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
    if (fs::exists(dir / "out.0002.exr") && bloomref::test::has_open_file_in(pid, dir.path())) {
      mid = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  ::kill(pid, SIGKILL);
  const int status = bloomref::test::wait_cli(pid);
  REQUIRE(mid);
  REQUIRE(status == 128 + SIGKILL);
  int whole_before = 0;
  for (int f = 1; f <= 8; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "out.%04d.exr", f);
    if (fs::exists(dir / name)) ++whole_before;
  }
  CHECK(whole_before < 8);  // killed before the end

  const CliResult r = run_cli(dir,
                              "run 'in.####.exr' -o 'out.####.exr' --dump-stages 'st.####/' "
                              "--json r.json --resume --progress lines");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK_FALSE(has_hidden_files(dir));  // the killed run's temporaries are gone
  const json j = read_json(dir / "r.json");
  std::vector<std::string> expected;
  for (int f = 1; f <= 8; ++f) {
    char id[8];
    std::snprintf(id, sizeof id, "%04d", f);
    expected.push_back(id);
    CHECK_THAT(r.out, Catch::Contains(std::string(id) + ": "));
    const fs::path stages = dir / ("st." + std::string(id));
    CHECK_FALSE(has_hidden_files(stages));
    for (const char* stage : {"input", "bright", "blur.10", "composite", "output"})
      CHECK(load(stages / (std::string(stage) + ".exr")).width() == 48);
  }
  CHECK(ids(j) == expected);  // every frame once, in order
  CHECK(run_cli(dir, "merge r.json -q").code == 0);
  for (int f : {2, 3, 8}) {
    char name[32];
    std::snprintf(name, sizeof name, "in.%04d.exr", f);
    const std::string in = dir / name;
    std::snprintf(name, sizeof name, "out.%04d.exr", f);
    CHECK(bloomref::test::bit_identical(load(dir / name).cview(), single_run(in).cview()));
  }
}

TEST_CASE("every engine's shard variables split a sequence that merge puts together",
          "[sequence]") {
  TempDir dir;
  write_frames(dir, 5);
  REQUIRE(run_cli(dir, "run 'in.####.exr' -o 'all.####.exr' -q").code == 0);
  struct Engine {
    const char* name;
    std::string env1, env2, extra;
  };
  const std::vector<Engine> engines = {
      {"explicit", "", "", ""},
      {"slurm",
       "SLURM_ARRAY_TASK_ID=10 SLURM_ARRAY_TASK_MIN=10 SLURM_ARRAY_TASK_MAX=12 "
       "SLURM_ARRAY_TASK_STEP=2 SLURM_ARRAY_TASK_COUNT=2",
       "SLURM_ARRAY_TASK_ID=12 SLURM_ARRAY_TASK_MIN=10 SLURM_ARRAY_TASK_MAX=12 "
       "SLURM_ARRAY_TASK_STEP=2 SLURM_ARRAY_TASK_COUNT=2",
       ""},
      {"kubernetes", "JOB_COMPLETION_INDEX=0", "JOB_COMPLETION_INDEX=1", "--shard-count 2"},
      {"gitlab", "CI_NODE_INDEX=1 CI_NODE_TOTAL=2", "CI_NODE_INDEX=2 CI_NODE_TOTAL=2", ""},
      {"bazel", "TEST_SHARD_INDEX=0 TEST_TOTAL_SHARDS=2 TEST_SHARD_STATUS_FILE=bazel-status",
       "TEST_SHARD_INDEX=1 TEST_TOTAL_SHARDS=2", ""},
      {"gtest", "GTEST_SHARD_INDEX=0 GTEST_TOTAL_SHARDS=2",
       "GTEST_SHARD_INDEX=1 GTEST_TOTAL_SHARDS=2", ""},
      {"buildkite", "BUILDKITE_PARALLEL_JOB=0 BUILDKITE_PARALLEL_JOB_COUNT=2",
       "BUILDKITE_PARALLEL_JOB=1 BUILDKITE_PARALLEL_JOB_COUNT=2", ""},
      {"circleci", "CIRCLE_NODE_INDEX=0 CIRCLE_NODE_TOTAL=2",
       "CIRCLE_NODE_INDEX=1 CIRCLE_NODE_TOTAL=2", ""},
  };
  for (const Engine& e : engines) {
    SECTION(e.name) {
      const std::string out = std::string(e.name) + ".####.exr";
      std::vector<std::string> envs = {e.env1, e.env2};
      for (int k = 1; k <= 2; ++k) {
        const std::string shard = e.env1.empty() ? std::to_string(k) + "/2" : "auto";
        const CliResult r =
            run_cli(dir,
                    "run 'in.####.exr' -o '" + out + "' --shard " + shard + " " + e.extra +
                        " --json " + e.name + "-" + std::to_string(k) + ".json",
                    kNoShardVars + " " + envs[k - 1]);
        INFO(r.out << r.err);
        REQUIRE(r.code == 0);
        CHECK_THAT(r.out, Catch::Contains("shard " + std::to_string(k) + "/2 ("));  // printed
        const json j = read_json(dir / (std::string(e.name) + "-" + std::to_string(k) + ".json"));
        CHECK(j["batch"]["shard"]["label"] == std::to_string(k) + "/2");  // recorded
        // Shard 1 takes frames 1, 3, 5; shard 2 frames 2, 4.
        CHECK(ids(j) == (k == 1 ? std::vector<std::string>{"0001", "0003", "0005"}
                                : std::vector<std::string>{"0002", "0004"}));
      }
      const CliResult m =
          run_cli(dir, std::string("merge ") + e.name + "-1.json " + e.name +
                           "-2.json --json merged.json --junit merged.xml --report rep");
      INFO(m.out << m.err);
      CHECK(m.code == 0);
      CHECK(ids(read_json(dir / "merged.json")) ==
            std::vector<std::string>{"0001", "0002", "0003", "0004", "0005"});
      CHECK(fs::exists(dir / "merged.xml"));
      CHECK(fs::exists(dir / "rep/index.html"));
      for (int f = 1; f <= 5; ++f) {
        char n[32];
        std::snprintf(n, sizeof n, "%04d.exr", f);
        CHECK(bloomref::test::bit_identical(load(dir / (std::string(e.name) + "." + n)).cview(),
                                            load(dir / (std::string("all.") + n)).cview()));
      }
      if (std::string(e.name) == "bazel") CHECK(fs::exists(dir / "bazel-status"));
    }
  }
}

TEST_CASE("a lost or repeated shard fails merge but a retried shard into its own file does not",
          "[sequence]") {
  TempDir dir;
  write_frames(dir, 5);
  for (int k = 1; k <= 2; ++k)
    REQUIRE(run_cli(dir, "run 'in.####.exr' -o 'o.####.exr' -q --shard " + std::to_string(k) +
                             "/2 --json r" + std::to_string(k) + ".json")
                .code == 0);
  CHECK(run_cli(dir, "merge r1.json r2.json -q").code == 0);
  const CliResult lost = run_cli(dir, "merge r1.json --json m.json");
  CHECK(lost.code == 2);
  CHECK_THAT(lost.err, Catch::Contains("2 of 5 items missing: 0002, 0004"));
  CHECK(read_json(dir / "m.json")["batch"]["missing"] == json({"0002", "0004"}));
  // A shard run again under another name (a retried job with a new id): run twice.
  REQUIRE(run_cli(dir, "run 'in.####.exr' -o 'o.####.exr' -q --shard 2/2 --resume --json r2b.json")
              .code == 0);
  const CliResult twice = run_cli(dir, "merge r1.json r2.json r2b.json");
  CHECK(twice.code == 2);
  CHECK_THAT(twice.err, Catch::Contains("item 0002 was run 2 times (r2.json, r2b.json)"));
  // The same shard retried into its own file: the file is replaced whole, the merge is complete.
  const std::string before = bloomref::test::read_bytes(dir / "o.0002.exr");
  REQUIRE(run_cli(dir, "run 'in.####.exr' -o 'o.####.exr' -q --shard 2/2 --resume --json r2.json")
              .code == 0);
  CHECK(run_cli(dir, "merge r1.json r2.json -q").code == 0);
  CHECK(bloomref::test::read_bytes(dir / "o.0002.exr") == before);
  CHECK(read_json(dir / "r2.json")["summary"]["resumed"] == 2);
}

TEST_CASE("an empty shard exits 5 and shards that do not exist exit 2", "[sequence]") {
  TempDir dir;
  write_frames(dir, 2);
  const CliResult empty =
      run_cli(dir, "run 'in.####.exr' -o 'o.####.exr' --shard 3/3 --json r.json");
  CHECK(empty.code == 5);
  CHECK_THAT(empty.err, Catch::Contains("shard 3/3 has no frame (2 frames in 3 shards)"));
  CHECK(read_json(dir / "r.json")["items"].empty());
  CHECK(read_json(dir / "r.json")["exit_code"] == 5);
  const CliResult beyond = run_cli(dir, "run 'in.####.exr' -o 'o.####.exr' --shard 3/2");
  CHECK(beyond.code == 2);
  CHECK_THAT(beyond.err, Catch::Contains("shard 3 of 2 does not exist"));
  const CliResult none =
      run_cli(dir, "run 'in.####.exr' -o 'o.####.exr' --shard auto", kNoShardVars);
  CHECK(none.code == 2);
  CHECK_THAT(none.err, Catch::Contains("no shard variables are set"));
  CHECK_FALSE(fs::exists(dir / "o.0001.exr"));
}

TEST_CASE("check over frames: an item per frame, a missing folder an error, shards merged",
          "[sequence]") {
  TempDir dir;
  write_frames(dir, 3);
  REQUIRE(run_cli(dir, "run 'in.####.exr' --plan full --dump-stages 'st.####/' -q").code == 0);
  const CliResult all =
      run_cli(dir, "check 'in.####.exr' --stages 'st.####/' --json c.json --junit c.xml -q");
  INFO(all.out << all.err);
  REQUIRE(all.code == 0);
  const json c = read_json(dir / "c.json");
  CHECK(ids(c) == std::vector<std::string>{"0001", "0002", "0003"});
  CHECK(c["items"][1]["scene"] == "in.0002.exr");
  CHECK(c["batch"]["items_total"] == 3);

  for (int k = 1; k <= 2; ++k)
    REQUIRE(run_cli(dir, "check 'in.####.exr' --stages 'st.####/' --frames 1-3 -q --shard " +
                             std::to_string(k) + "/2 --json c" + std::to_string(k) + ".json")
                .code == 0);
  const CliResult m = run_cli(dir, "merge c1.json c2.json --json cm.json --junit cm.xml");
  CHECK(m.code == 0);
  CHECK(read_json(dir / "cm.json")["verdict"] == "PASS");
  CHECK(read_json(dir / "cm.json")["summary"]["items"] == 3);
  // The merged JUnit is the one run's, but for its name, the shards and the times.
  auto normalised = [](const std::string& xml) {
    std::istringstream in(xml);
    std::string out, line;
    while (std::getline(in, line)) {
      if (line.find("<propert") != std::string::npos || line.find("</properties>") != std::string::npos)
        continue;
      line = std::regex_replace(line, std::regex(" time=\"[^\"]*\""), "");
      out += std::regex_replace(line, std::regex(" \\(merged\\)"), "") + "\n";
    }
    return out;
  };
  const std::string one = bloomref::test::read_bytes(dir / "c.xml");
  CHECK_THAT(one, Catch::Contains("largest error / bound:"));
  CHECK(std::count(one.begin(), one.end(), '\n') > 40);
  CHECK(normalised(bloomref::test::read_bytes(dir / "cm.xml")) == normalised(one));

  fs::remove_all(dir / "st.0002");
  const CliResult missing = run_cli(dir,
                                    "check 'in.####.exr' --stages 'st.####/' --frames 1-3 "
                                    "--json e.json --junit e.xml -q");
  CHECK(missing.code == 2);
  CHECK_THAT(missing.err, Catch::Contains("frame 0002: st.0002/"));
  const json e = read_json(dir / "e.json");
  CHECK(e["verdict"] == "ERROR");
  CHECK(e["items"][1]["verdict"] == "ERROR");
  CHECK(e["items"][2]["verdict"] == "PASS");
  CHECK_THAT(bloomref::test::read_bytes(dir / "e.xml"), Catch::Contains("errors=\"1\""));
}

TEST_CASE("check --manifest --shard takes every N-th item of the sorted ids", "[sequence]") {
  TempDir dir;
  write_frames(dir, 3);
  REQUIRE(run_cli(dir, "run 'in.####.exr' --plan full --dump-stages 'st.####/' -q").code == 0);
  bloomref::test::write_bytes(dir / "m.json", R"({"version": 1, "items": [
    {"id": "c", "scene": "in.0003.exr", "stages": "st.0003"},
    {"id": "a", "scene": "in.0001.exr", "stages": "st.0001"},
    {"id": "b", "scene": "in.0002.exr", "stages": "st.0002"}]})");
  const CliResult r = run_cli(dir, "check --manifest m.json --shard 1/2 --json s1.json -q");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  const json s1 = read_json(dir / "s1.json");
  CHECK(ids(s1) == std::vector<std::string>{"c", "a"});  // a and c, in the manifest's order
  CHECK(s1["batch"]["item_ids"] == json({"a", "b", "c"}));
  REQUIRE(run_cli(dir, "check --manifest m.json --shard 2/2 --json s2.json -q").code == 0);
  CHECK(ids(read_json(dir / "s2.json")) == std::vector<std::string>{"b"});
  CHECK(run_cli(dir, "merge s1.json s2.json -q").code == 0);
}

TEST_CASE("progress: a line per frame, a bar on a terminal, nothing with --quiet", "[sequence]") {
  TempDir dir;
  write_frames(dir, 3);
  const CliResult lines = run_cli(dir, "run 'in.####.exr' -o 'a.####.exr'");  // not a terminal
  REQUIRE(lines.code == 0);
  CHECK_THAT(lines.out, Catch::Contains("[1/3] 0001: done") && Catch::Contains("[3/3] 0003: done"));
  CHECK_THAT(lines.out, Catch::Contains("3 frames: 3 done"));
  const CliResult quiet = run_cli(dir, "run 'in.####.exr' -o 'b.####.exr' -q");
  REQUIRE(quiet.code == 0);
  CHECK(quiet.out.empty());
  CHECK(quiet.err.empty());
  // A terminal through script(1), when there is one.
  if (std::system("command -v script >/dev/null 2>&1") != 0) {
    WARN("script(1) not found: the terminal bar is not checked");
    return;
  }
  const std::string cmd = "cd '" + dir.path().string() +
                          "' && COLUMNS=100 script -qec \"'" BLOOMREF_EXE
                          "' run 'in.####.exr' -o 'c.####.exr'\" /dev/null >tty.txt 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  const std::string tty = bloomref::test::read_bytes(dir / "tty.txt");
  CHECK_THAT(tty, Catch::Contains("\r[") && Catch::Contains("3/3 frames") && Catch::Contains("/s"));
  CHECK_THAT(tty, !Catch::Contains("[1/3] 0001"));
}

TEST_CASE("bad patterns, frame lists, shards and results files are exit 2, named", "[sequence]") {
  TempDir dir;
  write_frames(dir, 2);
  const std::pair<std::string, std::string> cases[] = {
      {"run 'in.####.exr' -o out.exr", "-o 'out.exr' names one file for every frame"},
      {"run in.0001.exr --frames 1-2 -o 'o.####.exr'",
       "IN 'in.0001.exr' names one file for every frame"},
      {"run 'in.####.exr' -o 'o.#@.exr'", "'#@' mixes '#' and '@'"},
      {"run 'in.####.exr' -o 'o.%4d.exr'", "write '%04d'"},
      {"run 'in.####.exr' -o 'o.####.####.exr'", "has two frame wildcards"},
      {"run 'in.####.exr' --frames 1-2x0 -o 'o.####.exr'", "must be 1 or more"},
      {"run 'in.####.exr' --frames '1,,2' -o 'o.####.exr'", "an empty part between commas"},
      {"run 'in.####.exr' --frames 2-1,2 -o 'o.####.exr'", "frame 2 is listed twice"},
      {"run 'in.####.exr' --frames 1-b -o 'o.####.exr'", "'1-b' is not a frame"},
      {"run 'nope.####.exr' -o 'o.####.exr'", "no file matches IN 'nope.####.exr'"},
      {"run 'in.####.exr' -o 'in.####.exr'", "is the input file"},
      {"run 'in.####.exr' -o 'no/o.####.exr'",
       "no/o.0001.exr: cannot be written: the folder no does not exist"},
      {"run 'in.####.exr' -o 'o.####.exr' --json 'r.####.json'", "writes one results file"},
      {"run --scene demo -o 'o.####.exr'", "needs --frames"},
      {"run 'in.####.exr' -o 'o.####.exr' --shard 0/2", "K of --shard 0/2 is '0'"},
      {"run 'in.####.exr' -o 'o.####.exr' --shard 2", "is not K/N"},
      {"run 'in.####.exr' -o 'o.####.exr' --shard-count 3", "--shard-count goes with --shard auto"},
      {"run 'in.####.exr' -o 'o.####.exr' --jobs 0", "--jobs: Value 0 not in range"},
      {"run 'in.####.exr' -o 'o.####.exr' --progress loud", "--progress 'loud' is not one of"},
      {"run 'in.####.exr' -o 'o.####.exr' --repeat 3", "--repeat times one image"},
      {"check 'in.####.exr' --stages st", "--stages 'st' names one folder for every frame"},
      {"check 'in.####.exr' --manifest m.json", "give no SCENE"},
      {"check --manifest missing.json --shard 1/2", "missing.json: cannot be opened"},
      {"merge in.0001.exr", "in.0001.exr: is not valid JSON"},
      {"merge in.huge.json", "in.huge.json: is not valid JSON"},  // 1e999: out of a double's range
  };
  bloomref::test::write_bytes(dir / "in.huge.json", R"({"version": 1e999})");
  for (const auto& [args, message] : cases) {
    const CliResult r = run_cli(dir, args, kNoShardVars);
    INFO(args << "\n" << r.err);
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains(message));
  }
  for (const std::string& n : dir.listing()) CHECK(n.rfind("in.", 0) == 0);  // nothing written
}
