// bloomref check called as a library (cli/check/check.h): stage images in memory judged without
// a file, a planted error failing where it was planted, the request's sources refused when there
// are none or two, options the caller set winning over a manifest's, a known deviation's reason
// kept in the result, and the result's JSON the same as the command's for the same stages.
#include <catch2/catch.hpp>
#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "check/check.h"
#include "check/output.h"
#include "test_util.h"

namespace fs = std::filesystem;
using bloomref::test::TempDir;
using namespace bloomref;

namespace {

// bloomref's own CPU stages of the demo scene at 48x40 (the command, a separate process), and
// the scene as a file.
void dump(const TempDir& dir) {
  REQUIRE(test::run_cli("scenes demo --size 48x40 -o scene.exr", "", dir.path()).code == 0);
  REQUIRE(test::run_cli("run scene.exr --plan full --dump-stages stages -q", "", dir.path()).code == 0);
}

// The dumped stages read into memory (the I/O library, not the code under test).
struct Loaded {
  std::deque<Image> images;
  std::deque<ConstImageView> views;  // the files' images point here
  std::vector<cli::StageFile> files;
};

Loaded load_stages(const std::string& folder) {
  Loaded l;
  std::vector<fs::path> paths;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().extension() == ".exr") paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  for (const fs::path& p : paths) {
    l.images.push_back(load_image(p.string()).image);
    cli::StageFile f;
    f.stage = p.stem().string();
    f.path = f.stage + " (memory)";
    l.files.push_back(f);
  }
  for (std::size_t i = 0; i < l.files.size(); ++i) {
    l.views.push_back(l.images[i].cview());
    l.files[i].image = &l.views.back();
  }
  return l;
}

cli::CheckRequest quiet_request() {
  cli::CheckRequest r;
  r.require_sensitivity = 0;  // what the verdict could see is not asked here
  return r;
}

const nlohmann::ordered_json& stage_of(const nlohmann::ordered_json& item, const std::string& name) {
  for (const auto& s : item["stages"])
    if (s["stage"] == name) return s;
  FAIL("no stage " << name);
  throw;
}

}  // namespace

TEST_CASE("check as a library judges stages in memory, a planted error where it is planted",
          "[check-library]") {
  TempDir dir;
  dump(dir);
  Loaded stages = load_stages(dir / "stages");
  REQUIRE(stages.files.size() == 15);  // input, bright, 10 passes, composite, tonemap, output
  const Image scene = load_image(dir / "scene.exr").image;
  const ConstImageView scene_view = scene.cview();

  cli::CheckRequest clean = quiet_request();
  clean.scene = "the demo scene";
  clean.scene_image = &scene_view;
  clean.stages = stages.files;
  const cli::CheckRun ok = cli::check(clean);
  CHECK(ok.verdict == "PASS");
  CHECK(ok.exit_code == 0);
  REQUIRE(ok.items.size() == 1);
  CHECK(ok.items[0].source == "the demo scene");
  CHECK(ok.items[0].parity.isolated.size() == 15);
  CHECK(ok.items[0].file_of.at("blur.3") == "blur.3 (memory)");

  // A ping-pong bug: pass 3 leaves its input unchanged.
  std::size_t blur2 = 0, blur3 = 0;
  for (std::size_t i = 0; i < stages.files.size(); ++i) {
    if (stages.files[i].stage == "blur.2") blur2 = i;
    if (stages.files[i].stage == "blur.3") blur3 = i;
  }
  cli::CheckRequest broken = clean;
  (*broken.stages)[blur3].image = stages.files[blur2].image;
  const cli::CheckRun bad = cli::check(broken);
  CHECK(bad.verdict == "FAIL");
  CHECK(bad.exit_code == 1);
  REQUIRE(bad.items[0].parity.first_divergent_stage);
  CHECK(*bad.items[0].parity.first_divergent_stage == "blur.3");
  CHECK(dir.listing() == std::vector<std::string>{"scene.exr", "stages"});  // nothing written
}

TEST_CASE("check as a library refuses a request with no source of stages or two",
          "[check-library]") {
  TempDir dir;
  cli::CheckRequest none = quiet_request();
  CHECK_THROWS_AS(cli::check(none), ParamError);
  cli::CheckRequest two = quiet_request();
  two.stages_dir = dir.path().string();
  two.stages.emplace();
  CHECK_THROWS_AS(cli::check(two), ParamError);
  cli::CheckRequest manifest_and_folder = quiet_request();
  manifest_and_folder.stages_dir = dir.path().string();
  manifest_and_folder.manifest = dir / "m.json";
  CHECK_THROWS_AS(cli::check(manifest_and_folder), ParamError);
  const Image scene = Image::uninitialised(8, 8);
  const ConstImageView view = scene.cview();
  cli::CheckRequest memory_scene_with_manifest = quiet_request();
  memory_scene_with_manifest.scene_image = &view;
  memory_scene_with_manifest.manifest = dir / "m.json";
  CHECK_THROWS_WITH(cli::check(memory_scene_with_manifest),
                    Catch::Contains("a scene in memory is judged with its stages"));
}

TEST_CASE("check as a library: options the caller set win over a manifest's params",
          "[check-library]") {
  TempDir dir;
  dump(dir);
  // The stages were dumped at the default threshold (1); the manifest says 5.
  std::ofstream(dir / "m.json") << R"({"version": 1, "params": {"threshold": 5},
    "items": [{"id": "demo", "scene": "scene.exr", "stages": "stages"}]})";
  cli::CheckRequest manifest_wins = quiet_request();
  manifest_wins.manifest = dir / "m.json";
  const cli::CheckRun at5 = cli::check(manifest_wins);
  CHECK(at5.verdict == "FAIL");
  CHECK(at5.params.threshold == 5.0f);

  cli::CheckRequest caller_wins = manifest_wins;
  caller_wins.pipeline.params.threshold = 1;
  caller_wins.given = {"--threshold"};
  const cli::CheckRun at1 = cli::check(caller_wins);
  CHECK(at1.verdict == "PASS");
  CHECK(at1.params.threshold == 1.0f);
}

TEST_CASE("check as a library: a known deviation's reason outlives the request, and the JSON "
          "is the command's", "[check-library]") {
  TempDir dir;
  dump(dir);
  // blur.3 made a copy of blur.2 on disk: a known deviation of this device.
  fs::copy_file(dir / "stages/blur.2.exr", dir / "stages/blur.3.exr",
                fs::copy_options::overwrite_existing);
  std::ofstream(dir / "known.json") << R"({"version": 1, "expectations": [
    {"item": "*", "stage": "blur.3", "reason": "pass 3 is skipped on this device"},
    {"item": "*", "stage": "up.1", "reason": "no such stage in this pipeline"}]})";
  nlohmann::ordered_json ours;
  {
    cli::CheckRequest r = quiet_request();
    r.scene = dir / "scene.exr";
    r.stages_dir = dir / "stages";
    r.expectations = dir / "known.json";
    ours = cli::check_json(cli::check(r));
  }
  const auto& blur3 = stage_of(ours["items"][0], "blur.3");
  CHECK(blur3["status"] == "expected-fail");
  CHECK(blur3["expectation"]["reason"] == "pass 3 is skipped on this device");
  REQUIRE(ours["unused_expectations"].size() == 1);
  CHECK(ours["unused_expectations"][0]["stage"] == "up.1");

  const test::CliResult cmd = test::run_cli(
      "check scene.exr --stages stages --expectations known.json --require-sensitivity 0 "
      "--json r.json", "", dir.path());
  CHECK_THAT(cmd.out, Catch::Contains("note: expectation (item *, stage up.1) matched no stage"));
  // The later passes, judged from the copied capture, fail: the verdict is FAIL either way.
  CHECK(cmd.code == 1);
  CHECK(ours["exit_code"] == 1);
  std::ifstream in(dir / "r.json");
  const nlohmann::ordered_json theirs = nlohmann::ordered_json::parse(in);
  CHECK(ours["verdict"] == theirs["verdict"]);
  CHECK(ours["summary"] == theirs["summary"]);
  REQUIRE(ours["items"][0]["stages"].size() == theirs["items"][0]["stages"].size());
  for (std::size_t i = 0; i < ours["items"][0]["stages"].size(); ++i) {
    const auto& a = ours["items"][0]["stages"][i];
    const auto& b = theirs["items"][0]["stages"][i];
    CHECK(a["stage"] == b["stage"]);
    CHECK(a["status"] == b["status"]);
    CHECK(a["isolated"]["max_error_over_bound"] == b["isolated"]["max_error_over_bound"]);
    CHECK(a["expectation"] == b["expectation"]);
  }
}
