#include "batch/shard.h"

#include <algorithm>

#include "bloomref/error.h"

namespace bloomref::batch {
namespace {

// A whole number in [lo, hi] from a variable or option, or ParamError naming it.
long long whole(const std::string& what, const std::string& value, long long lo, long long hi) {
  const bool digits = !value.empty() && value.size() <= 10 &&
                      std::all_of(value.begin() + (value[0] == '-'), value.end(),
                                  [](char c) { return c >= '0' && c <= '9'; }) &&
                      value != "-";
  const long long v = digits ? std::stoll(value) : 0;
  if (!digits || v < lo || v > hi)
    throw ParamError(what + " is '" + value + "'; it must be a whole number from " +
                     std::to_string(lo) + " to " + std::to_string(hi));
  return v;
}

constexpr long long kMaxShards = 1000000;

const std::string* get(const Environment& env, const std::string& name) {
  const auto it = env.find(name);
  return it == env.end() ? nullptr : &it->second;
}

const std::string& require(const Environment& env, const std::string& name,
                           const std::string& with) {
  const std::string* v = get(env, name);
  if (!v) throw ParamError("--shard auto: " + with + " is set but " + name + " is not");
  return *v;
}

std::string var(const std::string& name, const std::string& value) {
  return name + "=" + value;
}

Shard make(long long index, long long count, const std::string& source) {
  if (index < 0 || index >= count)
    throw ParamError("--shard auto: " + source + " gives shard " + std::to_string(index + 1) +
                     " of " + std::to_string(count) + ", which does not exist");
  return Shard{static_cast<int>(index), static_cast<int>(count), source, ""};
}

// An engine that sets an index (0- or 1-based) and a total.
std::optional<Shard> index_total(const Environment& env, const std::string& engine,
                                 const std::string& index_var, const std::string& total_var,
                                 int base) {
  const std::string* index = get(env, index_var);
  if (!index) return std::nullopt;
  const std::string& total = require(env, total_var, index_var);
  const long long n = whole(total_var, total, 1, kMaxShards);
  const long long i = whole(index_var, *index, base, kMaxShards) - base;
  return make(i, n, engine + " (" + var(index_var, *index) + ", " + var(total_var, total) + ")");
}

std::optional<Shard> slurm(const Environment& env) {
  const std::string id_var = "SLURM_ARRAY_TASK_ID";
  const std::string* id = get(env, id_var);
  if (!id) return std::nullopt;
  const std::string& min_s = require(env, "SLURM_ARRAY_TASK_MIN", id_var);
  const std::string& count_s = require(env, "SLURM_ARRAY_TASK_COUNT", id_var);
  const std::string* step_s = get(env, "SLURM_ARRAY_TASK_STEP");
  const long long task = whole(id_var, *id, 0, 4000000000LL);
  const long long min = whole("SLURM_ARRAY_TASK_MIN", min_s, 0, 4000000000LL);
  const long long count = whole("SLURM_ARRAY_TASK_COUNT", count_s, 1, kMaxShards);
  const long long step = step_s ? whole("SLURM_ARRAY_TASK_STEP", *step_s, 1, 4000000000LL) : 1;
  std::string source = "Slurm array (" + var(id_var, *id) + ", MIN " + min_s + ", STEP " +
                       (step_s ? *step_s : "1") + ", COUNT " + count_s + ")";
  // Measured with Slurm 22.05: --array=1,2,5 sets MIN 1, MAX 5, STEP 1, COUNT 3. Ids that are
  // not evenly spaced leave a task's position unknowable from the environment.
  if (const std::string* max_s = get(env, "SLURM_ARRAY_TASK_MAX")) {
    const long long max = whole("SLURM_ARRAY_TASK_MAX", *max_s, 0, 4000000000LL);
    if (min + step * (count - 1) != max)
      throw ParamError("--shard auto: the Slurm array's ids are not evenly spaced (MIN " + min_s +
                       ", MAX " + *max_s + ", STEP " + std::to_string(step) + ", COUNT " + count_s +
                       "), so a task's position is unknown; submit --array=A-B or A-B:S, or "
                       "pass --shard K/N");
  }
  if (task < min || (task - min) % step != 0)
    throw ParamError("--shard auto: " + source +
                     ": the task id is not MIN plus a multiple of STEP");
  return make((task - min) / step, count, source);
}

std::optional<Shard> kubernetes(const Environment& env, int count) {
  const std::string* index = get(env, "JOB_COMPLETION_INDEX");
  if (!index) return std::nullopt;
  if (count == 0)
    throw ParamError(
        "--shard auto: JOB_COMPLETION_INDEX is set (a Kubernetes Indexed Job) but "
        "Kubernetes does not say how many completions there are: pass "
        "--shard-count with the Job's spec.completions");
  const long long i = whole("JOB_COMPLETION_INDEX", *index, 0, kMaxShards);
  return make(i, count,
              "Kubernetes Indexed Job (" + var("JOB_COMPLETION_INDEX", *index) +
                  ", --shard-count " + std::to_string(count) + ")");
}

}  // namespace

std::optional<Shard> resolve_shard(const std::string& arg, int count, const Environment& env) {
  if (count != 0 && (count < 1 || count > kMaxShards))
    throw ParamError("--shard-count is " + std::to_string(count) + "; it must be from 1 to " +
                     std::to_string(kMaxShards));
  if (arg.empty()) {
    if (count != 0) throw ParamError("--shard-count goes with --shard auto");
    return std::nullopt;
  }
  if (arg != "auto") {
    if (count != 0) throw ParamError("--shard-count goes with --shard auto, not --shard K/N");
    const std::size_t slash = arg.find('/');
    if (slash == std::string::npos)
      throw ParamError("--shard '" + arg + "' is not K/N (e.g. 2/4, 1-based) or auto");
    const long long n = whole("N of --shard " + arg, arg.substr(slash + 1), 1, kMaxShards);
    const long long k = whole("K of --shard " + arg, arg.substr(0, slash), 1, kMaxShards);
    if (k > n)
      throw ParamError("--shard " + arg + ": shard " + std::to_string(k) + " of " +
                       std::to_string(n) + " does not exist (K is 1-based, from 1 to N)");
    return Shard{static_cast<int>(k - 1), static_cast<int>(n), "--shard " + arg, ""};
  }
  std::optional<Shard> s = slurm(env);
  if (!s) s = kubernetes(env, count);
  if (!s) s = index_total(env, "GitLab", "CI_NODE_INDEX", "CI_NODE_TOTAL", 1);
  if (!s) {
    s = index_total(env, "Bazel", "TEST_SHARD_INDEX", "TEST_TOTAL_SHARDS", 0);
    if (s) {
      if (const std::string* f = get(env, "TEST_SHARD_STATUS_FILE")) s->status_file = *f;
    }
  }
  if (!s) s = index_total(env, "GoogleTest", "GTEST_SHARD_INDEX", "GTEST_TOTAL_SHARDS", 0);
  if (!s)
    s = index_total(env, "Buildkite", "BUILDKITE_PARALLEL_JOB", "BUILDKITE_PARALLEL_JOB_COUNT", 0);
  if (!s) s = index_total(env, "CircleCI", "CIRCLE_NODE_INDEX", "CIRCLE_NODE_TOTAL", 0);
  if (!s)
    throw ParamError(
        "--shard auto: no shard variables are set (SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX, "
        "CI_NODE_INDEX, TEST_SHARD_INDEX, GTEST_SHARD_INDEX, BUILDKITE_PARALLEL_JOB, "
        "CIRCLE_NODE_INDEX); running every item in every shard would prove nothing. Pass "
        "--shard K/N, or leave --shard out to run everything");
  if (count != 0 && count != s->count)
    throw ParamError("--shard-count " + std::to_string(count) + " contradicts " + s->source);
  return s;
}

std::vector<std::size_t> shard_positions(std::size_t items, const Shard& shard) {
  std::vector<std::size_t> out;
  for (std::size_t i = static_cast<std::size_t>(shard.index); i < items;
       i += static_cast<std::size_t>(shard.count))
    out.push_back(i);
  return out;
}

}  // namespace bloomref::batch
