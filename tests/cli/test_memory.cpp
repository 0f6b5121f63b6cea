// Memory: a run's peak is bounded by the image's size, not its pass count, and a command refuses
// an image whose run would exceed --max-memory (exit 2) instead of running out of memory part
// way. Peaks are the child process's own, as its --json reports them (peak_rss_bytes: the
// kernel's VmHWM). getrusage's ru_maxrss through wait4 would count this test process as it was
// when it forked the child (Linux keeps the larger of the two across exec), which after the
// corpus tests is larger than any run here.
#include <catch2/catch.hpp>
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bloomref/memory_budget.h"
#include "bloomref/params.h"
#include "io_test_util.h"

using bloomref::test::TempDir;

namespace {

// Under AddressSanitizer a process's memory is its shadow and quarantine as much as its own:
// peaks say nothing about bloomref there (scripts/sanitize).
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kMeasured = false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kMeasured = false;
#else
constexpr bool kMeasured = true;
#endif
#else
constexpr bool kMeasured = true;
#endif

// Peak resident memory (KiB) of `bloomref ARGS --json peak.json` run in `dir`; REQUIREs exit 0.
long peak_rss_kb(const TempDir& dir, std::vector<std::string> args) {
  args.insert(args.end(), {"--json", "peak.json"});
  const int code = bloomref::test::wait_cli(bloomref::test::spawn_cli(args, dir.path()));
  INFO("bloomref " << Catch::Detail::stringify(args));
  REQUIRE(code == 0);
  const auto j = nlohmann::json::parse(bloomref::test::read_bytes(dir / "peak.json"));
  return static_cast<long>(j.at("peak_rss_bytes").get<long long>() / 1024);
}

}  // namespace

TEST_CASE("a run's peak memory does not grow with its pass count", "[memory]") {
  // The fused blur kept a ring of rows per pass per worker: 1000 passes over 4096x64 peaked at
  // 4.2 GB against 29 MB for 10 (27 MB with the per-pass reference blur).
  if (!kMeasured) {
    WARN("AddressSanitizer build: peak memory not measured");
    return;
  }
  TempDir dir;
  const auto run = [&](const std::string& passes, const std::string& blur) {
    return peak_rss_kb(dir, {"run", "--scene", "demo", "--size", "1024x64", "--threads", "2",
                             "--passes", passes, "--blur", blur, "-o", "out.exr"});
  };
  // From 100 passes on, the bloom covers the whole image, so every working buffer is touched;
  // at 10 the adaptive plan touches a part of them (approx, MALLOC_ARENA_MAX=1: 19 MB at 10
  // passes, 31 MB at 100, 300 and 1000; with a malloc arena per thread, 32-38 MB at both 100 and
  // 1000). So 1000 passes are compared with 100: a peak that grew with the passes would be
  // about ten times as large.
  for (const std::string blur : {"fast", "approx"}) {
    const long hundred = run("100", blur), thousand = run("1000", blur);
    INFO(blur << ": peak " << hundred << " KiB for 100 passes, " << thousand << " KiB for 1000");
    CHECK(thousand < hundred + hundred / 2);
  }
}

TEST_CASE("the working-set bound lies above the measured peaks", "[memory]") {
  if (!kMeasured) {
    WARN("AddressSanitizer build: peak memory not measured");
    return;
  }
  TempDir dir;
  // Outputs: a PNG (its 8-bit buffer is part of the bound); stage dumps (EXR, slower to
  // write) at a quarter of the size.
  struct Case {
    std::vector<std::string> args;
    int kept_traces;
    int w, h;
  };
  const std::vector<Case> cases = {
      {{}, 0, 1024, 768},
      {{"--plan", "full"}, 0, 1024, 768},
      {{"--storage", "f16"}, 0, 1024, 768},
      {{"--precision", "f64"}, 0, 1024, 768},
      {{"--method", "mip"}, 0, 1024, 768},
      {{"--blur", "reference"}, 0, 1024, 768},
      {{"--passes", "40"}, 0, 1024, 768},
      {{"--passes", "40", "--storage", "f16"}, 0, 1024, 768},
      {{"--dump-stages", "stages", "--passes", "2"}, 1, 512, 384},
      {{"--dump-stages", "stages", "--precision", "f64", "--passes", "2"}, 1, 512, 384},
  };
  for (const Case& c : cases) {
    const int w = c.w, h = c.h;
    std::vector<std::string> args = {"run", "--scene", "demo", "--size",
                                     std::to_string(w) + "x" + std::to_string(h), "-o", "out.png"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    bloomref::BloomParams p;
    for (std::size_t i = 0; i + 1 < c.args.size(); ++i) {
      const std::string& o = c.args[i];
      const std::string& v = c.args[i + 1];
      if (o == "--precision") p.precision = bloomref::parse_precision(v);
      if (o == "--method") p.method = bloomref::parse_method(v);
      if (o == "--passes") p.passes = std::stoi(v);
      if (o == "--storage") p.storage = bloomref::parse_storage(v);
    }
    const std::uint64_t bound = bloomref::working_set(p, w, h, c.kept_traces).bytes;
    const long kb = peak_rss_kb(dir, args);
    INFO(Catch::Detail::stringify(c.args) << ": peak " << kb << " KiB, bound " << bound / 1024
                                          << " KiB");
    CHECK(std::uint64_t(kb) * 1024 <= bound);
  }
}

TEST_CASE("max memory: an image whose run would not fit is refused before any work",
          "[memory][cli]") {
  TempDir dir;
  SECTION("a built-in scene") {
    // 16384 x 16384 in f64 would need ~40 GiB: refused at once, whatever this machine has.
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = bloomref::test::run_cli(
        "run --scene demo --size 16384x16384 --precision f64 --max-memory 2G -o out.exr", "",
        dir.path());
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find("--max-memory 2 GiB") != std::string::npos);
    CHECK(r.err.find("16384x16384") != std::string::npos);
    CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10));
    CHECK(dir.listing().empty());
  }
  SECTION("an input file, named in the message") {
    bloomref::test::write_test_exr(dir / "in.exr", 256, 256, {"R", "G", "B"},
                                   std::vector<float>(256 * 256, 2.0f));
    // Above the program's own 64 MiB, below that plus four 1 MiB images.
    const auto r = bloomref::test::run_cli("run in.exr --max-memory 66M -o out.exr", "", dir.path());
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find("in.exr") != std::string::npos);
    CHECK(r.err.find("needs up to") != std::string::npos);
    CHECK(dir.listing() == std::vector<std::string>{"in.exr"});
    const auto ok = bloomref::test::run_cli("run in.exr --max-memory 1G -o out.exr", "", dir.path());
    CHECK(ok.code == 0);
  }
  SECTION("a size that is not one") {
    const auto r = bloomref::test::run_cli("run --max-memory 8Q -o out.exr", "", dir.path());
    CHECK(r.code == 2);
    CHECK(r.err.find("--max-memory '8Q'") != std::string::npos);
  }
}
