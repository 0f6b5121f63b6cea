#include "app.h"

#include <CLI/CLI.hpp>
#include <iostream>

#include "bloomref/error.h"
#include "bloomref/gpu/context.h"
#include "bloomref/vulkan/context.h"
#include "commands.h"

namespace bloomref::cli {

int run_command_line(const std::vector<std::string>& args) {
  CLI::App app{"bloomref: the reference HDR bloom (the CPU oracle and its GL parity)"};
  app.name("bloomref");
  app.require_subcommand(1);
  auto run = add_run(app);
  auto scenes = add_scenes(app);
  auto gl_info = add_gl_info(app);
  auto vulkan_info = add_vulkan_info(app);
  auto compare = add_compare(app);
  auto check = add_check(app);
  auto describe = add_describe(app);
  auto stability = add_stability(app);
  auto bench = add_bench(app);
  auto tradeoff = add_tradeoff(app);
  auto merge = add_merge(app);
  try {
    std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11's order
    app.parse(reversed);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "bloomref: " << e.what() << "\n(run bloomref --help)\n";
    return 2;
  }
  try {
    for (auto* cmd : {&run, &scenes, &gl_info, &vulkan_info, &compare, &check, &describe, &stability, &bench,
                      &tradeoff, &merge}) {
      const int rc = (*cmd)();
      if (rc >= 0) return rc;
    }
    return 2;
  } catch (const gpu::GlUnavailable& e) {
    std::cerr << "bloomref: GL path unavailable: " << e.what() << "\n";
    return 3;
  } catch (const vulkan::VulkanUnavailable& e) {
    std::cerr << "bloomref: Vulkan path unavailable: " << e.what() << "\n";
    return 3;
  } catch (const vulkan::VulkanError& e) {
    std::cerr << "bloomref: Vulkan error: " << e.what() << "\n";
    return 4;
  } catch (const Error& e) {
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

}  // namespace bloomref::cli
