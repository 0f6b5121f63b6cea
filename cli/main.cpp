// The bloomref command. Exit codes (DESIGN.md): 0 success, 1 parity FAIL, 2 bad usage or bad
// input, 3 GL path unavailable, 4 internal error (a bug: please report it), 5 nothing compared.
#include <CLI/CLI.hpp>
#include <iostream>

#include "bloomref/error.h"
#include "bloomref/gpu/context.h"
#include "commands.h"

int main(int argc, char** argv) {
  CLI::App app{"bloomref: the reference HDR bloom (the CPU oracle and its GL parity)"};
  app.require_subcommand(1);
  auto run = bloomref::cli::add_run(app);
  auto scenes = bloomref::cli::add_scenes(app);
  auto gl_info = bloomref::cli::add_gl_info(app);
  auto compare = bloomref::cli::add_compare(app);
  auto check = bloomref::cli::add_check(app);
  auto stability = bloomref::cli::add_stability(app);
  auto bench = bloomref::cli::add_bench(app);
  auto tradeoff = bloomref::cli::add_tradeoff(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "bloomref: " << e.what() << "\n(run bloomref --help)\n";
    return 2;
  }
  try {
    for (auto* cmd : {&run, &scenes, &gl_info, &compare, &check, &stability, &bench, &tradeoff}) {
      const int rc = (*cmd)();
      if (rc >= 0) return rc;
    }
    return 2;
  } catch (const bloomref::gpu::GlUnavailable& e) {
    std::cerr << "bloomref: GL path unavailable: " << e.what() << "\n";
    return 3;
  } catch (const bloomref::Error& e) {
    std::cerr << "bloomref: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "bloomref: out of memory\n";
    return 4;
  } catch (const std::exception& e) {
    std::cerr << "bloomref: internal error: " << e.what() << "\n";
    return 4;
  }
}
