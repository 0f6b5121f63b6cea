// Outputs reach the disk whole or not at all, and nothing is left behind (output_files.h): a
// process killed while it writes, by any signal, leaves the folder as it was; a command's
// outputs are published together; destinations are checked before the work.
//
// The command runs as a separate process (BLOOMREF_EXE) in a temporary folder; "what was there"
// is the folder's listing and the bytes of the file the output would replace.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <algorithm>
#include <chrono>
#include <thread>

#include "bloomref/image.h"
#include "bloomref/io.h"
#include "bloomref/output_files.h"
#include "io_test_util.h"

using bloomref::test::TempDir;
namespace fs = std::filesystem;

namespace {

// Starts `args` in `dir`, waits until it has a file open there (it is writing an output: the
// computation before it is short at this size), lets it write for `delay_ms`, then sends `sig`
// and returns its exit status. Fails the test if it never writes or ends first.
int kill_while_writing(const TempDir& dir, const std::vector<std::string>& args, int sig,
                       const std::vector<std::string>& env = {}, int delay_ms = 30) {
  const int pid = bloomref::test::spawn_cli(args, dir.path(), env);
  const auto t0 = std::chrono::steady_clock::now();
  bool writing = false;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
    if ((writing = bloomref::test::has_open_file_in(pid, dir.path()))) break;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  if (writing) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
  ::kill(pid, sig);
  const int status = bloomref::test::wait_cli(pid);
  REQUIRE(writing);
  REQUIRE(status == 128 + sig);  // the signal ended it, not the end of its work
  return status;
}

std::vector<std::string> demo_run(const std::string& out) {
  // 2048 x 2048: ~0.2 s of computation, then a 67 MB EXR that takes ~1 s to write or more.
  return {"run", "--scene", "demo", "--size", "2048x2048", "--threads", "1", "-o", out};
}

}  // namespace

TEST_CASE("a run killed while it writes its output leaves the folder as it was", "[outputs]") {
  TempDir dir;
  bloomref::test::write_bytes(dir / "keep.exr", "what was there");
  const auto listing = dir.listing();
  const int sig = GENERATE(SIGKILL, SIGTERM, SIGINT);
  INFO("signal " << sig);
  kill_while_writing(dir, demo_run("keep.exr"), sig);
  CHECK(dir.listing() == listing);  // no temporary, no partial file
  CHECK(bloomref::test::read_bytes(dir / "keep.exr") == "what was there");
}

TEST_CASE("without unnamed files, SIGTERM and SIGINT remove the named temporary", "[outputs]") {
  TempDir dir;
  const int sig = GENERATE(SIGTERM, SIGINT);
  INFO("signal " << sig);
  kill_while_writing(dir, demo_run("out.exr"), sig, {"BLOOMREF_NO_TMPFILE=1"});
  CHECK(dir.listing().empty());
}

TEST_CASE("a named temporary left by SIGKILL is removed by the next run in its folder",
          "[outputs]") {
  TempDir dir;
  kill_while_writing(dir, demo_run("out.exr"), SIGKILL, {"BLOOMREF_NO_TMPFILE=1"});
  const auto left = dir.listing();
  REQUIRE(left.size() == 1);  // SIGKILL cannot be caught: the temporary stays
  CHECK(left[0].rfind(".out.tmp-", 0) == 0);
  const auto r = bloomref::test::run_cli("run --scene demo --size 16x16 -o other.png -q", "",
                                         dir.path());
  REQUIRE(r.code == 0);
  CHECK(dir.listing() == std::vector<std::string>{"other.png"});
}

TEST_CASE("a pending file has no name until it is published", "[outputs]") {
  TempDir dir;
  const bloomref::Image img = bloomref::test::constant_image(4, 3, 0.5f);
  {
    bloomref::PendingFile f(dir / "a.txt");
    REQUIRE(::write(f.fd(), "abc", 3) == 3);
    CHECK(dir.listing().empty());
  }  // not published: discarded
  CHECK(dir.listing().empty());
  bloomref::PendingFile f(dir / "a.txt");
  REQUIRE(::write(f.fd(), "abc", 3) == 3);
  f.prepare();  // a hidden name, nothing replaced yet
  CHECK(!fs::exists(dir / "a.txt"));
  f.commit();
  CHECK(dir.listing() == std::vector<std::string>{"a.txt"});
  CHECK(bloomref::test::read_bytes(dir / "a.txt") == "abc");
}

TEST_CASE("a staged folder appears whole, and keeps the other files of a folder in the way",
          "[outputs]") {
  TempDir dir;
  {
    bloomref::StagedFolder s(dir / "rep");
    bloomref::test::write_bytes(s.path() + "/index.html", "x");
    CHECK(!fs::exists(dir / "rep"));
  }  // not published: removed
  CHECK(dir.listing().empty());

  bloomref::StagedFolder s(dir / "rep");
  bloomref::test::write_bytes(s.path() + "/index.html", "new");
  s.publish();
  CHECK(dir.listing() == std::vector<std::string>{"rep"});
  CHECK(bloomref::test::read_bytes(dir / "rep/index.html") == "new");

  bloomref::test::write_bytes(dir / "rep/mine.txt", "the user's");
  bloomref::StagedFolder again(dir / "rep");
  bloomref::test::write_bytes(again.path() + "/index.html", "newer");
  again.publish();
  CHECK(dir.listing() == std::vector<std::string>{"rep"});
  CHECK(bloomref::test::read_bytes(dir / "rep/index.html") == "newer");
  CHECK(bloomref::test::read_bytes(dir / "rep/mine.txt") == "the user's");
}

namespace {

// Runs `args` in `dir`; returns its exit status, or -1 after killing it when it takes longer
// than `seconds`.
int run_within(const TempDir& dir, const std::vector<std::string>& args, int seconds) {
  const int pid = bloomref::test::spawn_cli(args, dir.path());
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(seconds)) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid)
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ::kill(pid, SIGKILL);
  bloomref::test::wait_cli(pid);
  return -1;
}

}  // namespace

TEST_CASE("run replaces no output when another cannot be written", "[outputs]") {
  TempDir dir;
  bloomref::test::write_bytes(dir / "keep.exr", "what was there");
  const auto listing = dir.listing();
  const auto r = bloomref::test::run_cli(
      "run --scene demo --size 64x64 -o keep.exr -o nosuch/y.png --json r.json", "", dir.path());
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find("nosuch") != std::string::npos);
  CHECK(dir.listing() == listing);
  CHECK(bloomref::test::read_bytes(dir / "keep.exr") == "what was there");
}

TEST_CASE("run refuses a missing output folder before the computation", "[outputs]") {
  TempDir dir;
  // 1000 reference passes over 2048 x 2048 take minutes; the refusal must come at once.
  for (const auto& bad : std::vector<std::vector<std::string>>{
           {"-o", "nosuch/y.exr"}, {"--json", "nosuch/r.json"}, {"-o", "ok.exr", "-o", "ok.exr"}}) {
    std::vector<std::string> args{"run",      "--scene", "demo",   "--size", "2048x2048",
                                  "--passes", "1000",    "--blur", "reference"};
    args.insert(args.end(), bad.begin(), bad.end());
    INFO(bad.back());
    CHECK(run_within(dir, args, 20) == 2);
    CHECK(dir.listing().empty());
  }
}

TEST_CASE("run publishes its outputs together, stage dumps included", "[outputs]") {
  TempDir dir;
  const auto r = bloomref::test::run_cli(
      "run --scene demo --size 32x16 --passes 2 -o a.exr -o b.png --json r.json "
      "--dump-stages st -q", "", dir.path());
  REQUIRE(r.code == 0);
  CHECK(dir.listing() == std::vector<std::string>{"a.exr", "b.png", "r.json", "st"});
  const TempDir& d = dir;
  std::vector<std::string> stages;
  for (const auto& e : fs::directory_iterator(d / "st")) stages.push_back(e.path().filename());
  std::sort(stages.begin(), stages.end());
  // input, bright, blur.1, blur.2, composite, tonemap, output (docs/design.md, "Specification").
  CHECK(stages == std::vector<std::string>{"blur.1.exr", "blur.2.exr", "bright.exr",
                                           "composite.exr", "input.exr", "output.exr",
                                           "tonemap.exr"});
}
