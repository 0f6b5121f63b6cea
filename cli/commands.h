#pragma once

#include <CLI/CLI.hpp>

namespace bloomref::cli {

// Each adds its subcommand; the returned callable runs it and returns the exit code.
std::function<int()> add_run(CLI::App& app);
std::function<int()> add_scenes(CLI::App& app);
std::function<int()> add_gl_info(CLI::App& app);
std::function<int()> add_vulkan_info(CLI::App& app);
std::function<int()> add_compare(CLI::App& app);
std::function<int()> add_check(CLI::App& app);
std::function<int()> add_describe(CLI::App& app);
std::function<int()> add_stability(CLI::App& app);
std::function<int()> add_bench(CLI::App& app);
std::function<int()> add_tradeoff(CLI::App& app);
std::function<int()> add_merge(CLI::App& app);

}  // namespace bloomref::cli
