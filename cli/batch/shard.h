// Which part of an item list one process takes: `--shard K/N` (1-based, as jest, Playwright and
// GitLab count), or `--shard auto` read from the variables a job engine sets. Shard K of N takes
// the items at positions K-1, K-1+N, K-1+2N ... of the sorted item list, so shards differ in size
// by one item at most and every item is in exactly one shard.
#pragma once

#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace bloomref::batch {

using Environment = std::map<std::string, std::string>;

struct Shard {
  int index = 0;  ///< 0-based
  int count = 1;
  std::string source;       ///< where it came from: "--shard 2/4", "GitLab (CI_NODE_INDEX=2, ...)"
  std::string status_file;  ///< Bazel's TEST_SHARD_STATUS_FILE, to be touched; "" for others
  /// "K/N" (1-based), as the user writes it.
  std::string label() const { return std::to_string(index + 1) + "/" + std::to_string(count); }
};

/// Resolves `--shard` (`arg`: "" for none, "K/N", or "auto") with `--shard-count` (`count`, 0
/// when not given). `auto` reads, in this order, the first engine whose index variable is set:
///   Slurm array      SLURM_ARRAY_TASK_ID, _MIN, _STEP, _COUNT (position (ID-MIN)/STEP; ids
///                    may be sparse, A-B:S, but must be evenly spaced)
///   Kubernetes       JOB_COMPLETION_INDEX (0-based) with --shard-count (the Job's completions)
///   GitLab           CI_NODE_INDEX (1-based) / CI_NODE_TOTAL
///   Bazel            TEST_SHARD_INDEX (0-based) / TEST_TOTAL_SHARDS; status_file from
///                    TEST_SHARD_STATUS_FILE
///   GoogleTest       GTEST_SHARD_INDEX (0-based) / GTEST_TOTAL_SHARDS
///   Buildkite        BUILDKITE_PARALLEL_JOB (0-based) / BUILDKITE_PARALLEL_JOB_COUNT
///   CircleCI         CIRCLE_NODE_INDEX (0-based) / CIRCLE_NODE_TOTAL
/// ParamError (exit 2) for a malformed value, K outside 1..N, a variable without its partner,
/// a --shard-count that contradicts the engine's total, and `auto` with none of them set
/// (running everything in every shard would pass while proving nothing).
std::optional<Shard> resolve_shard(const std::string& arg, int count, const Environment& env);

/// The positions (0-based, ascending) of the items of a list of `items` that `shard` takes.
std::vector<std::size_t> shard_positions(std::size_t items, const Shard& shard);

}  // namespace bloomref::batch
