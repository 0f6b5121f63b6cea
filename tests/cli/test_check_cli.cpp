// bloomref check as a CI job runs it (a separate process, BLOOMREF_EXE, in a temporary folder):
// bloomref's own dumped stages pass; the same flipped, R/B-swapped, or with a wrong blur weight
// fail at the right stage with the cause named; declared row and channel order are honoured;
// exit codes 5 (nothing compared) and 2 (wrong size, corrupt file, unknown stage, unwritable
// destination, manifest errors) name the file; JSON, JUnit, Markdown, manifest, expectations.
#include <sys/wait.h>

#include <Imath/half.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "bloomref/io.h"
#include "io_test_util.h"
#include "test_util.h"

using bloomref::test::TempDir;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using bloomref::test::CliResult;

CliResult run_cli(const TempDir& cwd, const std::string& args) {
  return bloomref::test::run_cli(args, "", cwd.path());
}

const std::string kSize = "--size 48x40";

// bloomref's own CPU stages of the demo scene at 48x40, dumped into dir/name.
void dump(const TempDir& dir, const std::string& name, const std::string& extra = "",
          const std::string& size = kSize) {
  const CliResult r = run_cli(dir, "run " + size + " --plan full --dump-stages " + name + " " + extra);
  REQUIRE(r.code == 0);
}

// Rewrites every EXR of a folder through `change` (load_image / save_exr: the I/O library, not
// the code under test).
template <class F>
void rewrite_all(const std::string& dir, F change) {
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() != ".exr") continue;
    bloomref::Image img = bloomref::load_image(e.path().string()).image;
    change(img);
    bloomref::save_exr(e.path().string(), img.cview());
  }
}

void flip(bloomref::Image& img) {
  for (int y = 0; y < img.height() / 2; ++y)
    for (int x = 0; x < img.width(); ++x)
      for (int c = 0; c < 4; ++c) std::swap(img.pixel(x, y)[c], img.pixel(x, img.height() - 1 - y)[c]);
}

void swap_rb(bloomref::Image& img) {
  for (std::size_t i = 0; i < img.pixel_count(); ++i) std::swap(img.data()[4 * i], img.data()[4 * i + 2]);
}

// Every stage of the demo at `size` in dir/d, and blur.10 and the output alone in dir/two.
void dump_with_two(const TempDir& dir, const std::string& size) {
  dump(dir, "d", "", size);
  fs::create_directory(dir / "two");
  for (const std::string f : {"blur.10.exr", "output.exr"}) fs::copy_file(dir / ("d/" + f), dir / ("two/" + f));
}

json read_json(const std::string& path) { return json::parse(bloomref::test::read_bytes(path)); }

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto at = s.find(what); at != std::string::npos; at = s.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("bloomref's own dumped stages pass, results are written", "[check-cli]") {
  TempDir dir;
  dump(dir, "d");
  const CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json --junit r.xml "
                                   "--markdown r.md --device-vendor Mesa --device-api 'OpenGL 4.5'");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("verdict PASS") != std::string::npos);
  // The console's table: a line per stage, and nothing more said of a stage that passed.
  CHECK(count(r.out, "PASS") == 2 * 15 + 1);
  CHECK(r.out.find("within its bound") == std::string::npos);
  const json j = read_json(dir / "r.json");
  CHECK(j["version"] == 1);
  CHECK(j["verdict"] == "PASS");
  CHECK(j["exit_code"] == 0);
  CHECK(j["device"]["vendor"] == "Mesa");
  CHECK(j["device"]["api"] == "OpenGL 4.5");
  REQUIRE(j["items"].size() == 1);
  const json& stages = j["items"][0]["stages"];
  CHECK(stages.size() == 15);  // input, bright, blur.1..10, composite, tonemap, output
  for (const json& s : stages) CHECK(s["status"] == "pass");
  CHECK(j["items"][0]["first_divergent_stage"].is_null());
  const std::string xml = bloomref::test::read_bytes(dir / "r.xml");
  CHECK(count(xml, "<testcase ") == 15);
  CHECK(count(xml, "<failure") == 0);
  CHECK(count(xml, "<testsuite ") == 1);
  CHECK(xml.find("name=\"device.vendor\" value=\"Mesa\"") != std::string::npos);
  // Undeclared device keys are left out; each passing stage says its margin.
  CHECK(xml.find("device.driver") == std::string::npos);
  CHECK(count(xml, "largest error / bound: ") == 15);
  CHECK(bloomref::test::read_bytes(dir / "r.md").find("PASS") != std::string::npos);
}

TEST_CASE("a flipped or R/B-swapped dump fails at its first stage, declared, it passes", "[check-cli]") {
  struct Case {
    void (*change)(bloomref::Image&);
    const char* declared;
    const char* cause;
  };
  for (const Case c : {Case{flip, "--origin bottom", "flipped-vertically"},
                       Case{swap_rb, "--channels BGRA", "rb-swapped"}}) {
    TempDir dir;
    dump(dir, "d");
    rewrite_all(dir / "d", c.change);
    CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json --junit r.xml");
    INFO(c.cause << "\n" << r.out << r.err);
    CHECK(r.code == 1);
    const json j = read_json(dir / "r.json");
    CHECK(j["items"][0]["first_divergent_stage"] == "input");
    CHECK(j["items"][0]["first_divergent_cause"]["id"] == c.cause);
    const std::string xml = bloomref::test::read_bytes(dir / "r.xml");
    CHECK(xml.find("likely cause: ") != std::string::npos);
    CHECK(xml.find(c.change == flip ? "flipped vertically" : "R and B swapped") != std::string::npos);
    r = run_cli(dir, "check " + kSize + " --stages d " + c.declared);
    CHECK(r.code == 0);
  }
}

TEST_CASE("a stage judged from an earlier wrong capture says it follows from it", "[check-cli]") {
  // The ping-pong bug of docs/check.md: pass 3 leaves its input unchanged. blur.4 is right, but
  // judged from the wrong blur.3 it fails in isolation; end to end it passes.
  TempDir dir;
  dump(dir, "d");
  fs::copy_file(dir / "d/blur.2.exr", dir / "d/blur.3.exr", fs::copy_options::overwrite_existing);
  const CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json --junit r.xml");
  INFO(r.out << r.err);
  CHECK(r.code == 1);
  CHECK(r.out.find("blur.3: FAIL \u2014 one blur pass too few") != std::string::npos);
  CHECK(r.out.find("blur.4: FAIL \u2014 follows from blur.3") != std::string::npos);
  const json j = json::parse(bloomref::test::read_bytes(dir / "r.json"));
  for (const json& st : j["items"][0]["stages"]) {
    INFO(st["stage"]);
    CHECK(st["follows_from"] == (st["stage"] == "blur.4" ? json("blur.3") : json(nullptr)));
  }
  CHECK(bloomref::test::read_bytes(dir / "r.xml").find("follows from blur.3") != std::string::npos);
}

TEST_CASE("a second, independent bug is listed in the Markdown beside the first", "[check-cli]") {
  // A pass too few (blur.3), and an output gamma of 1.8 where 2.2 is specified: two bugs. blur.4
  // follows from the first and is not listed; the output diverges on its own.
  TempDir dir;
  dump(dir, "d");
  dump(dir, "g", "--gamma 1.8");
  fs::copy_file(dir / "d/blur.2.exr", dir / "d/blur.3.exr", fs::copy_options::overwrite_existing);
  fs::copy_file(dir / "g/output.exr", dir / "d/output.exr", fs::copy_options::overwrite_existing);
  const CliResult r = run_cli(dir, "check " + kSize + " --stages d --markdown r.md -q");
  CHECK(r.code == 1);
  const std::string md = bloomref::test::read_bytes(dir / "r.md");
  INFO(md);
  CHECK(md.find("| d | FAIL | `blur.3` | blur.3: FAIL") != std::string::npos);
  CHECK(md.find("| d | also | `output` | output: FAIL") != std::string::npos);
  CHECK(md.find("`blur.4`") == std::string::npos);
  CHECK(count(md, "| d |") == 2);
}

TEST_CASE("where NaN first enters a capture is named", "[check-cli]") {
  // overte-org/overte#2297: one non-finite texel spreads through every later stage. Planted at
  // blur.3 and (as a pass spreads it) in blur.4 and blur.5 around it.
  TempDir dir;
  dump(dir, "d");
  for (int k = 3; k <= 5; ++k) {
    const std::string f = dir / ("d/blur." + std::to_string(k) + ".exr");
    bloomref::Image img = bloomref::load_image(f).image;
    for (int d = -(k - 3); d <= k - 3; ++d) img.pixel(20 + d, 12)[1] = NAN;
    bloomref::save_exr(f, img.cview());
  }
  const CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json");
  INFO(r.out << r.err);
  CHECK(r.code == 1);
  CHECK(r.out.find("NaN/Inf first stand against finite values at blur.3 (1 values)") != std::string::npos);
  const json j = json::parse(bloomref::test::read_bytes(dir / "r.json"));
  CHECK(j["items"][0]["first_nonfinite_stage"] == "blur.3");
}

TEST_CASE("a blur pass with a wrong weight fails there, and says so", "[check-cli]") {
  TempDir dir;
  dump(dir, "d");
  // blur.3 (horizontal) recomputed from blur.2 with the second weight 0.25 instead of 792/4070:
  // discrete9's taps sit on texel centres, so a plain sum of clamped texels.
  const bloomref::Image b2 = bloomref::load_image(dir / "d/blur.2.exr").image;
  bloomref::Image b3(b2.width(), b2.height());
  const double w[5] = {924.0 / 4070, 0.25, 495.0 / 4070, 220.0 / 4070, 66.0 / 4070};
  for (int y = 0; y < b2.height(); ++y)
    for (int x = 0; x < b2.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        double s = 0;
        for (int i = -4; i <= 4; ++i)
          s += w[std::abs(i)] * b2.pixel(std::clamp(x + i, 0, b2.width() - 1), y)[c];
        b3.pixel(x, y)[c] = static_cast<float>(s);
      }
      b3.pixel(x, y)[3] = 1;
    }
  bloomref::save_exr(dir / "d/blur.3.exr", b3.cview());
  for (const char* later : {"blur.4", "blur.5", "blur.6", "blur.7", "blur.8", "blur.9", "blur.10",
                            "composite", "tonemap", "output"})
    fs::remove(dir / (std::string("d/") + later + ".exr"));
  const CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json --report rep");
  INFO(r.out << r.err);
  CHECK(r.code == 1);
  const json j = read_json(dir / "r.json");
  CHECK(j["items"][0]["first_divergent_stage"] == "blur.3");
  CHECK(j["items"][0]["first_divergent_cause"]["id"] == "wrong-weights");
  CHECK(r.out.find("likely cause: wrong kernel weights") != std::string::npos);
  // The first line under the stage says what to change, and how much it explains.
  CHECK(r.out.find("blur.3: FAIL \u2014 wrong kernel weights, explains ") != std::string::npos);
  // The HTML report names the cause and lists the hypotheses tried; with the default
  // --artifacts fail it holds the failing stage's images only.
  const std::string html = bloomref::test::read_bytes(dir / "rep/d/index.html");
  CHECK(html.find("likely cause: wrong kernel weights") != std::string::npos);
  CHECK(html.find("causes tested") != std::string::npos);
  CHECK(fs::exists(dir / "rep/d/blur.3.diff.exr"));
  CHECK_FALSE(fs::exists(dir / "rep/d/blur.2.diff.exr"));
  CHECK_FALSE(fs::exists(dir / "rep/d/bright.diff.exr"));
  // The stage under test is the user's own file: linked (relative to the page), not copied.
  CHECK_FALSE(fs::exists(dir / "rep/d/blur.3.device.exr"));
  CHECK(html.find("href='../../d/blur.3.exr'") != std::string::npos);
  CHECK(fs::exists(fs::path(dir / "rep/d") / "../../d/blur.3.exr"));
}

TEST_CASE("only the output (composite, tone map and gamma in one pass) is judged", "[check-cli]") {
  TempDir dir;
  dump(dir, "d");
  fs::create_directory(dir / "only");
  fs::copy_file(dir / "d/output.exr", dir / "only/output.exr");
  CliResult r = run_cli(dir, "check " + kSize + " --stages only --json r.json");
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  CHECK(read_json(dir / "r.json")["items"][0]["stages"].size() == 1);
  // The output as an 8-bit PNG (what `run -o out.png` writes): judged with half a code.
  fs::remove(dir / "only/output.exr");
  REQUIRE(run_cli(dir, "run " + kSize + " -o only/output.png").code == 0);
  r = run_cli(dir, "check " + kSize + " --stages only");
  CHECK(r.code == 0);
  // With the gamma left out, it fails and says so.
  fs::remove(dir / "only/output.png");
  fs::copy_file(dir / "d/tonemap.exr", dir / "only/output.exr");
  r = run_cli(dir, "check " + kSize + " --stages only");
  CHECK(r.code == 1);
  CHECK(r.out.find("likely cause: gamma not applied") != std::string::npos);
}

TEST_CASE("a verdict says what it could see, a weak one is WARN, a brighter bloom fails its gain gate",
          "[check-cli][gain]") {
  TempDir dir;
  const std::string size = "--size 160x96";
  dump_with_two(dir, size);
  // Every stage under nvidia: strong.
  CliResult r = run_cli(dir, "check " + size + " --stages d --json all.json");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("could see: a bloom gain of") != std::string::npos);
  json j = read_json(dir / "all.json");
  CHECK(j["verdict"] == "PASS");
  const json& all = j["items"][0]["sensitivity"];
  CHECK(all["weak"] == false);
  CHECK(all["gain"]["smallest_failed"].get<double>() <= 1.05);
  // blur.10 and the output under mediump (coordinates off by up to a texel here): too weak to
  // see 5%, so WARN.
  r = run_cli(dir, "check " + size + " --stages two --profile mediump --json w.json --junit w.xml "
                   "--markdown w.md");
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  CHECK(r.out.find("verdict WARN: weak verdict") != std::string::npos);
  j = read_json(dir / "w.json");
  CHECK(j["verdict"] == "WARN");
  const json& weak = j["items"][0]["sensitivity"];
  CHECK(weak["weak"] == true);
  CHECK(weak["strengthen_with"] == "capture blur.1 ... blur.9");
  for (const json& s : j["items"][0]["stages"]) CHECK(s["isolated"]["verdict"] == "PASS");
  CHECK(bloomref::test::read_bytes(dir / "w.xml").find("name=\"weak-verdict\"") != std::string::npos);
  CHECK(bloomref::test::read_bytes(dir / "w.md").find("weak verdict") != std::string::npos);
  // Each stage says what it was judged through (blur.10: the bright pass and the passes before
  // it; the output: the scene's upload and the finishing stages), in the JSON, the console
  // and JUnit; with every stage captured (above), nothing is.
  const json& carried = j["items"][0]["stages"][0]["carried"];
  CHECK(carried["from"].size() == 10);  // bright (which reads the scene itself), blur.1 ... blur.9
  CHECK(carried["from"][0] == "bright");
  CHECK(carried["from"][9] == "blur.9");
  CHECK(r.out.find("blur.10    ") != std::string::npos);
  CHECK(r.out.find("of its bound is what bright ... blur.9 (10 stages, not captured) may carry") !=
        std::string::npos);
  CHECK(count(bloomref::test::read_bytes(dir / "w.xml"), "judged through stages not captured: ") == 2);
  for (const json& s : read_json(dir / "all.json")["items"][0]["stages"]) CHECK(s["carried"].is_null());
  CHECK(run_cli(dir, "check " + size + " --stages two --profile mediump --warn-as-error -q").code == 1);
  // Under nvidia the same two captures see 10%: a bloom 1.1x too strong (its output made from
  // it here, in double) fails at blur.10.
  r = run_cli(dir, "check " + size + " --stages two --json n.json -q");
  REQUIRE(r.code == 0);
  const double seen = read_json(dir / "n.json")["items"][0]["sensitivity"]["gain"]["smallest_failed"];
  CHECK(seen <= 1.1);
  const bloomref::Image input = bloomref::load_image(dir / "d/input.exr").image;
  bloomref::Image bloom = bloomref::load_image(dir / "two/blur.10.exr").image;
  bloomref::Image out = bloom;
  for (int y = 0; y < bloom.height(); ++y)
    for (int x = 0; x < bloom.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        float& b = bloom.pixel(x, y)[c];
        b = static_cast<float>(b * 1.1);
        const double h = double(input.pixel(x, y)[c]) + b;
        out.pixel(x, y)[c] = static_cast<float>(std::pow(-std::expm1(-h), 1 / 2.2));
      }
  bloomref::save_exr(dir / "two/blur.10.exr", bloom.cview());
  bloomref::save_exr(dir / "two/output.exr", out.cview());
  r = run_cli(dir, "check " + size + " --stages two --json f.json");
  INFO(r.out << r.err);
  CHECK(r.code == 1);
  j = read_json(dir / "f.json");
  CHECK(j["items"][0]["first_divergent_stage"] == "blur.10");
  // Other gates may see it first (the window gate, here); the gain gate sees it too.
  const json& blur10 = j["items"][0]["stages"][0]["isolated"];
  CHECK(blur10["verdict"] == "FAIL");
  CHECK(blur10["gain_gate"].get<double>() > 1);
  CHECK(blur10["gain"][1].get<double>() == Approx(1.1).epsilon(0.01));
  // Under vulkan (4-bit weights) the same two captures see it too: blur.9 is not captured,
  // and 1.1x lies beyond what any 4-bit device could make from the bright pass in nine passes
  // (the envelope gate).
  r = run_cli(dir, "check " + size + " --stages two --profile vulkan --json v.json");
  INFO(r.out << r.err);
  CHECK(r.code == 1);
  j = read_json(dir / "v.json");
  CHECK(j["items"][0]["first_divergent_stage"] == "blur.10");
  const json& v10 = j["items"][0]["stages"][0]["isolated"];
  CHECK(v10["verdict"] == "FAIL");
  CHECK(v10["envelope_gate"].is_number());
  CHECK((v10["envelope_gate"].get<double>() > 1 || v10["envelope_outside_fraction"].get<double>() > 0.01));
  // Its cause is scored within the envelope (every value is within its bound): a gain, fitted.
  const json& v10_stage = j["items"][0]["stages"][0];
  REQUIRE(v10_stage["cause"].is_object());
  CHECK(v10_stage["cause"]["id"] == "weight-sum");
  CHECK(v10_stage["cause"]["likely"] == true);
  // The clean blur.10 and output lie within their envelope.
  fs::create_directory(dir / "clean");
  for (const std::string f : {"blur.10.exr", "output.exr"}) fs::copy_file(dir / ("d/" + f), dir / ("clean/" + f));
  r = run_cli(dir, "check " + size + " --stages clean --profile vulkan --json c.json -q");
  CHECK(r.code == 0);
  const json clean = read_json(dir / "c.json");
  const json& c10 = clean["items"][0]["stages"][0]["isolated"];
  CHECK(c10["envelope_gate"].get<double>() <= 1);
  CHECK(c10["envelope_outside_fraction"].get<double>() == 0);
}

TEST_CASE("each stage's stated sensitivity (--sensitivity stages) holds for errors planted there",
          "[check-cli][gain]") {
  TempDir dir;
  const std::string size = "--size 160x96";
  dump_with_two(dir, size);
  CliResult r = run_cli(dir, "check " + size + " --stages two --profile vulkan --sensitivity stages "
                             "--json s.json --junit s.xml --markdown s.md");
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("could see, of an error entering at:") != std::string::npos);
  const json j = read_json(dir / "s.json");
  std::map<std::string, double> gain;
  for (const json& s : j["items"][0]["stages"]) {
    const json& seen = s["sensitivity"];
    REQUIRE(seen.is_object());
    CHECK(seen["shift_texels"].is_object());
    CHECK(seen["spread"].is_object() == (s["stage"] == "blur.10"));
    if (!seen["gain"]["smallest_failed"].is_null()) gain[s["stage"]] = seen["gain"]["smallest_failed"];
  }
  REQUIRE(gain.count("blur.10"));
  REQUIRE(gain.count("output"));
  const std::string xml = bloomref::test::read_bytes(dir / "s.xml");
  CHECK(xml.find("name=\"sensitivity.blur.10\"") != std::string::npos);
  CHECK(xml.find("name=\"sensitivity.output\"") != std::string::npos);
  CHECK(bloomref::test::read_bytes(dir / "s.md").find("| error entering at |") != std::string::npos);
  // What each stated figure says, planted in the files here: the output times its stated gain
  // fails; blur.10 times its stated gain, with the output made from it in double, fails.
  const bloomref::Image input = bloomref::load_image(dir / "d/input.exr").image;
  const bloomref::Image bloom0 = bloomref::load_image(dir / "d/blur.10.exr").image;
  const bloomref::Image out0 = bloomref::load_image(dir / "d/output.exr").image;
  for (const std::string stage : {"output", "blur.10"}) {
    bloomref::Image bloom = bloom0, out = out0;
    const double g = gain.at(stage);
    for (int y = 0; y < bloom.height(); ++y)
      for (int x = 0; x < bloom.width(); ++x)
        for (int c = 0; c < 3; ++c) {
          if (stage == "output") {
            out.pixel(x, y)[c] = static_cast<float>(out0.pixel(x, y)[c] * g);
            continue;
          }
          float& b = bloom.pixel(x, y)[c];
          b = static_cast<float>(b * g);
          const double h = double(input.pixel(x, y)[c]) + b;
          out.pixel(x, y)[c] = static_cast<float>(std::pow(-std::expm1(-h), 1 / 2.2));
        }
    bloomref::save_exr(dir / "two/blur.10.exr", bloom.cview());
    bloomref::save_exr(dir / "two/output.exr", out.cview());
    r = run_cli(dir, "check " + size + " --stages two --profile vulkan -q");
    INFO(stage << " times " << g);
    CHECK(r.code == 1);
  }
  // The mip method: no blur pass to widen, so no spread; a gain and a shift per stage.
  dump(dir, "m", "--method mip", size);
  r = run_cli(dir, "check " + size + " --method mip --stages m --sensitivity stages --json m.json -q");
  REQUIRE(r.code == 0);
  const json m = read_json(dir / "m.json");
  REQUIRE(m["items"][0]["stages"].size() > 5);
  for (const json& s : m["items"][0]["stages"]) {
    INFO(s["stage"]);
    CHECK(s["sensitivity"]["spread"].is_null());
    CHECK(s["sensitivity"]["gain"]["smallest_failed"].is_number());
  }
}

TEST_CASE("nothing compared is exit 5", "[check-cli]") {
  TempDir dir;
  fs::create_directory(dir / "empty");
  CliResult r = run_cli(dir, "check " + kSize + " --stages empty --json r.json --junit r.xml");
  CHECK(r.code == 5);
  CHECK(r.err.find("nothing compared") != std::string::npos);
  CHECK(read_json(dir / "r.json")["verdict"] == "NOTHING");
  bloomref::test::write_bytes(dir / "empty/notes.txt", "no stages here");
  r = run_cli(dir, "check " + kSize + " --stages empty");
  CHECK(r.code == 5);
  CHECK(r.out.find("notes.txt") != std::string::npos);  // listed as ignored
}

TEST_CASE("bad stage files are exit 2 naming the file, nothing is written", "[check-cli]") {
  struct Case {
    const char* file;
    void (*make)(const TempDir&);
    const char* says;
  };
  const Case cases[] = {
      {"bright.exr", [](const TempDir& d) {
         fs::copy_file(d / "small/bright.exr", d / "d/bright.exr", fs::copy_options::overwrite_existing);
       }, "32x24"},
      {"blur.99.exr", [](const TempDir& d) { fs::copy_file(d / "d/blur.1.exr", d / "d/blur.99.exr"); },
       "blur.99"},
      {"output.exr", [](const TempDir& d) { bloomref::test::write_bytes(d / "d/output.exr", "not an image"); },
       "output.exr"},
      {"down.1.exr", [](const TempDir& d) { fs::copy_file(d / "d/blur.1.exr", d / "d/down.1.exr"); },
       "down.1"}};
  for (const Case& c : cases) {
    TempDir dir;
    dump(dir, "d");
    dump(dir, "small", "", "--size 32x24");
    c.make(dir);
    const auto before = dir.listing();
    const CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json");
    INFO(c.file << ": " << r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find(c.file) != std::string::npos);
    CHECK(r.err.find(c.says) != std::string::npos);
    CHECK(dir.listing() == before);  // no r.json
  }
}

TEST_CASE("destinations are checked before any work", "[check-cli]") {
  TempDir dir;
  dump(dir, "d");
  CliResult r = run_cli(dir, "check " + kSize + " --stages d --json no/such/folder/r.json --junit r.xml");
  CHECK(r.code == 2);
  CHECK(r.err.find("no/such/folder/r.json") != std::string::npos);
  CHECK(!fs::exists(dir / "r.xml"));
  r = run_cli(dir, "check " + kSize + " --stages d --junit d");
  CHECK(r.code == 2);
  r = run_cli(dir, "check " + kSize + " --stages d --json d/output.exr");  // an input
  CHECK(r.code == 2);
}

TEST_CASE("a manifest: raw half, bottom row first, BGRA, aliases, device keys", "[check-cli]") {
  TempDir dir;
  dump(dir, "d", "--storage f16");  // RGBA16F targets: a raw save holds their bits
  REQUIRE(run_cli(dir, "scenes demo " + kSize + " -o scene.exr").code == 0);
  // The output as RenderDoc's raw save of a GL texture might hold it: f16, BGRA, bottom row
  // first, written here byte by byte.
  const bloomref::Image out = bloomref::load_image(dir / "d/output.exr").image;
  std::string bytes;
  for (int y = out.height() - 1; y >= 0; --y)
    for (int x = 0; x < out.width(); ++x)
      for (int c : {2, 1, 0, 3}) {
        const std::uint16_t h = Imath::half(out.pixel(x, y)[c]).bits();
        bytes.append(reinterpret_cast<const char*>(&h), 2);
      }
  fs::create_directory(dir / "cap");
  bloomref::test::write_bytes(dir / "cap/final.raw", bytes);
  fs::copy_file(dir / "d/blur.10.exr", dir / "cap/BloomBlur.exr");
  const std::string manifest = R"({
    "version": 1,
    "params": {"passes": 10, "storage": "f16"},
    "device": {"api": "OpenGL 4.6", "vendor": "ExampleVendor", "renderer": "X", "driver": "1.0"},
    "items": [
      {"id": "frame1", "scene": "scene.exr",
       "stages": {"final": {"path": "cap/final.raw", "encoding": "raw", "format": "f16",
                            "origin": "bottom", "channels": "BGRA", "width": 48, "height": 40},
                  "BloomBlur": "cap/BloomBlur.exr"},
       "aliases": {"final": "output", "BloomBlur": "blur.10"}},
      {"id": "frame1-dir", "scene": "scene.exr", "stages": "d"}
    ]})";
  bloomref::test::write_bytes(dir / "m.json", manifest);
  CliResult r = run_cli(dir, "check --manifest m.json --json r.json --junit r.xml --device-driver 2.0");
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  const json j = read_json(dir / "r.json");
  CHECK(j["items"].size() == 2);
  CHECK(j["items"][0]["stages"].size() == 2);
  CHECK(j["device"]["vendor"] == "ExampleVendor");
  CHECK(j["device"]["driver"] == "2.0");  // the command line wins
  CHECK(count(bloomref::test::read_bytes(dir / "r.xml"), "<testsuite ") == 2);

  // A missing file, an unknown stage name, a bad encoding: exit 2 naming the manifest's field.
  const std::pair<std::string, std::string> broken[] = {
      {R"("cap/BloomBlur.exr")", R"("cap/missing.exr")"},
      {R"("BloomBlur": "blur.10")", R"("BloomBlur": "blurry")"},
      {R"("encoding": "raw")", R"("encoding": "jpeg")"}};
  for (const auto& [from, to] : broken) {
    std::string m = manifest;
    m.replace(m.find(from), from.size(), to);
    bloomref::test::write_bytes(dir / "bad.json", m);
    r = run_cli(dir, "check --manifest bad.json");
    INFO(to << ": " << r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find("bad.json") != std::string::npos);
    CHECK(r.err.find("items[0]") != std::string::npos);
  }
  // A parameter that is no option of check (found by fuzzing: it was an internal error, exit 4).
  std::string m = manifest;
  m.replace(m.find(R"("passes": 10)"), 12, R"("th(eshold": 1)");
  bloomref::test::write_bytes(dir / "bad.json", m);
  r = run_cli(dir, "check --manifest bad.json");
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find("bad.json") != std::string::npos);
  CHECK(r.err.find("params.th(eshold") != std::string::npos);
  // A number beyond a double (found by fuzzing: nlohmann's out_of_range escaped the reader).
  m = manifest;
  m.replace(m.find(R"("passes": 10)"), 12, R"("passes": 1e999)");
  bloomref::test::write_bytes(dir / "bad.json", m);
  r = run_cli(dir, "check --manifest bad.json");
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find("bad.json") != std::string::npos);
}

TEST_CASE("expectations: a known deviation is expected, and reported when fixed", "[check-cli]") {
  TempDir dir;
  dump(dir, "d");
  dump(dir, "ok");
  rewrite_all(dir / "d", flip);
  bloomref::test::write_bytes(dir / "x.json", R"({"version": 1, "expectations": [
      {"item": "d", "stage": "*", "device": "Mesa", "reason": "readback not flipped yet"},
      {"item": "ok", "stage": "output", "reason": "was broken once"}]})");
  CliResult r = run_cli(dir, "check " + kSize + " --stages d --expectations x.json "
                             "--device-vendor Mesa --json r.json --junit r.xml");
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  json j = read_json(dir / "r.json");
  CHECK(j["summary"]["expected_fail"].get<int>() > 0);
  CHECK(j["summary"]["fail"] == 0);
  CHECK(bloomref::test::read_bytes(dir / "r.xml").find("<skipped") != std::string::npos);
  // On another device the expectation does not apply.
  r = run_cli(dir, "check " + kSize + " --stages d --expectations x.json --device-vendor Other");
  CHECK(r.code == 1);
  // A known deviation that now passes is reported as fixed (and does not fail the run).
  r = run_cli(dir, "check " + kSize + " --stages ok --expectations x.json --json r2.json");
  CHECK(r.code == 0);
  j = read_json(dir / "r2.json");
  CHECK(j["summary"]["fixed"] == 1);
  CHECK(r.out.find("FIXED") != std::string::npos);
}

TEST_CASE("a profile file: per-stage overrides, a bad field is exit 2 naming it", "[check-cli]") {
  TempDir dir;
  dump(dir, "d");
  fs::create_directory(dir / "s");
  fs::copy_file(dir / "d/blur.2.exr", dir / "s/blur.2.exr");
  fs::copy_file(dir / "d/blur.2.exr", dir / "s/blur.3.exr");  // pass 3 did nothing
  CHECK(run_cli(dir, "check " + kSize + " --stages s").code == 1);
  bloomref::test::write_bytes(dir / "lenient.json", R"({"version": 1, "base": "vulkan",
      "stages": [{"pattern": "blur.3", "scale": 1e9, "gates": {"mean": 0, "window": 0}}]})");
  CliResult r = run_cli(dir, "check " + kSize + " --stages s --profile lenient.json --json r.json");
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  const json j = read_json(dir / "r.json");
  CHECK(j["profile"]["name"] == "lenient");
  CHECK(j["profile"]["subtexel_bits"] == 8);  // from the base, vulkan
  bloomref::test::write_bytes(dir / "bad.json", R"({"version": 1, "subtexel": 8})");
  r = run_cli(dir, "check " + kSize + " --stages s --profile bad.json");
  CHECK(r.code == 2);
  CHECK(r.err.find("bad.json") != std::string::npos);
  CHECK(r.err.find("subtexel") != std::string::npos);
  r = run_cli(dir, "check " + kSize + " --stages s --profile nosuch");
  CHECK(r.code == 2);
}

TEST_CASE("warn as error: a stage over its bound but within the warning tier fails", "[check-cli]") {
  // One output value is raised step by step (x1.5) until the check reports WARN for it: some
  // step lands its error/bound ratio between 1 and the FAIL tier. That same input then passes
  // with exit 0 and fails with --warn-as-error.
  TempDir dir;
  dump(dir, "d");
  const bloomref::Image original = bloomref::load_image(dir / "d/output.exr").image;
  bool warned = false;
  for (double delta = 1e-7; delta < 0.1 && !warned; delta *= 1.5) {
    bloomref::Image out = original;
    out.pixel(20, 20)[0] += static_cast<float>(delta);
    bloomref::save_exr(dir / "d/output.exr", out.cview());
    const CliResult r = run_cli(dir, "check " + kSize + " --stages d --json r.json");
    REQUIRE((r.code == 0 || r.code == 1));
    const json j = read_json(dir / "r.json");
    if (j["verdict"] == "FAIL") break;
    warned = j["verdict"] == "WARN";
    if (warned) CHECK(r.code == 0);
  }
  REQUIRE(warned);
  const CliResult r = run_cli(dir, "check " + kSize + " --stages d --warn-as-error --json r.json --junit r.xml");
  INFO(r.out << r.err);
  CHECK(r.code == 1);
  CHECK(read_json(dir / "r.json")["exit_code"] == 1);
  CHECK(count(bloomref::test::read_bytes(dir / "r.xml"), "<failure") == 1);
}

TEST_CASE("a bad --layout file is exit 2 naming the file and the field before any GL",
          "[check-cli]") {
  TempDir dir;
  // A shader file is read before the layout; GL is never reached, so this runs without it.
  bloomref::test::write_bytes(dir / "s.frag", "#version 330 core\nvoid main() {}\n");
  const std::string shaders = "check --scene demo --size 48x40 --shaders learnopengl "
                              "--blur-fs s.frag --final-fs s.frag --layout layout.json";
  struct Case {
    const char* text;
    const char* field;  // what the message must name besides the file
  };
  const Case cases[] = {
      {"{\"version\": 1, \"blur\": {\"imag\": \"uSource\"}}", "blur.imag"},
      {"{\"version\": 1, \"blur\": {\"image\": \"9lives\"}}", "blur.image"},
      {"{\"version\": 1, \"final\": {\"scene\": \"gl_Scene\"}}", "final.scene"},
      {"{\"version\": 1, \"attributes\": {\"position\": 3}}", "attributes.position"},
      {"{\"version\": 2}", "version"},
      {"{\"blur\": {}}", "version"},
      {"{\"version\": 1, \"colour\": 1}", "colour"},
      {"{\"version\": 1, \"blur\": {\"horizontal\": \"h\", \"direction\": {\"uniform\": \"d\", "
       "\"horizontal\": [1, 0], \"vertical\": [0, 1]}}}",
       "blur.direction"},
      {"{\"version\": 1, \"blur\": {\"direction\": {\"uniform\": \"d\", \"horizontal\": [1, 0], "
       "\"vertical\": [0, 1, 0]}}}",
       "blur.direction"},
      {"{\"version\": 1, \"blur\": {\"direction\": {\"uniform\": \"d\", \"horizontal\": [1, 0]}}}",
       "blur.direction.vertical"},
      {"{\"version\": 1, \"blur\": {\"set\": {\"uTexel\": \"texel\"}}}", "blur.set.uTexel"},
      {"{\"version\": 1, \"blur\": {\"set\": {\"uTint\": [1, 2, 3, 4, 5]}}}", "blur.set.uTint"},
      {"{\"version\": 1, \"final\": {\"set\": {\"u x\": 1}}}", "final.set.u x"},
      {"{\"version\": 1, ", "not valid JSON"},
  };
  for (const Case& c : cases) {
    bloomref::test::write_bytes(dir / "layout.json", c.text);
    const CliResult r = run_cli(dir, shaders);
    INFO(c.text << "\n" << r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find("layout.json") != std::string::npos);
    CHECK(r.err.find(c.field) != std::string::npos);
    // The layout is an input: left as it was.
    CHECK(bloomref::test::read_bytes(dir / "layout.json") == c.text);
  }
  fs::remove(dir / "layout.json");
  CliResult r = run_cli(dir, shaders);
  CHECK(r.code == 2);
  CHECK(r.err.find("layout.json: cannot be opened") != std::string::npos);
  // A layout names what --shaders binds: alone it is a usage error.
  r = run_cli(dir, "check --scene demo --size 48x40 --stages d --layout layout.json");
  CHECK(r.code == 2);
  CHECK(r.err.find("--layout") != std::string::npos);
}
