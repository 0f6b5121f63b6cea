// compare --report builds its report in a hidden folder and moves it into place when complete:
// interrupted, it leaves no half-written report (output_files.h, StagedFolder).
#include <signal.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <thread>

#include "gl_fixture.h"
#include "test_util.h"

using bloomref::test::TempDir;

TEST_CASE("compare --report interrupted leaves no half-written folder", "[outputs]") {
  if (!bloomref::test::gl_context()) return;
  TempDir dir;
  const int sig = GENERATE(SIGTERM, SIGINT);
  INFO("signal " << sig);
  // Interrupted as soon as anything appears in the folder: the report's first file.
  const int pid = bloomref::test::spawn_cli(
      {"compare", "--scene", "demo", "--size", "256x256", "--report", "rep", "-q"}, dir.path());
  const auto t0 = std::chrono::steady_clock::now();
  bool started = false;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(120)) {
    if ((started = !dir.listing().empty())) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ::kill(pid, sig);
  const int status = bloomref::test::wait_cli(pid);
  REQUIRE(started);
  REQUIRE(status == 128 + sig);
  CHECK(dir.listing().empty());
}
