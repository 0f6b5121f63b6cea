#include "bloomref/machine_ceiling.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <vector>

#include "bloomref/parallel.h"

namespace bloomref {

namespace {

// One unit of register-only work: 8 independent chains of x = x * a + b (no memory traffic).
// Not inlined: inlined into the one-thread loop, GCC vectorises across units and the ratio lies.
__attribute__((noinline)) float register_work(float seed) {
  float x[8];
  for (int i = 0; i < 8; ++i) x[i] = seed + float(i);
  for (int it = 0; it < 2000000; ++it)
    for (int i = 0; i < 8; ++i) x[i] = x[i] * 0.99999994f + 1e-7f;
  float s = 0;
  for (int i = 0; i < 8; ++i) s += x[i];
  return s;
}

// One unit of throughput-bound work: 14 independent chains of 4-float vectors (SSE registers
// in this baseline build: 14 and the two constants fill its 16 without spilling), x = x * a + b:
// more multiplies and adds in flight than a core's vector units take (on this project's AMD
// EPYC, Zen 5: ~3 cycles each, two units for each; Intel's recent cores: 4 cycles, two ports),
// so one thread keeps them busy. register_work's 8 floats (two 4-float chains once GCC
// vectorises them) leave the units mostly idle, so two hardware threads of one core double it
// as two cores would; they cannot double this (the blur's kernels are of this kind).
__attribute__((noinline)) float throughput_work(float seed) {
  typedef float V __attribute__((vector_size(16)));
  constexpr int kChains = 14;
  V x[kChains];
  for (int i = 0; i < kChains; ++i) x[i] = V{} + (seed + float(i));
  const V a = V{} + 0.99999994f, b = V{} + 1e-7f;
  for (int it = 0; it < 500000; ++it)
    for (int i = 0; i < kChains; ++i) x[i] = x[i] * a + b;
  float s = 0;
  for (int i = 0; i < kChains; ++i)
    for (int l = 0; l < 4; ++l) s += x[i][l];
  return s;
}

double seconds_for(int threads, int units_per_thread, float (*work)(float)) {
  std::vector<float> sink(std::size_t(threads) * units_per_thread);
  const auto t0 = std::chrono::steady_clock::now();
  parallel_rows(threads * units_per_thread, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) sink[y] = work(float(y));
  });
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  volatile float keep = sink[0];  // the work is observable
  (void)keep;
  return s;
}

constexpr std::size_t kCopyFloats = std::size_t(8) << 20;  // 32 MiB per thread and buffer

double copy_seconds(int threads, const std::vector<float>& from, std::vector<float>& to) {
  const auto t0 = std::chrono::steady_clock::now();
  parallel_rows(threads * 4, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {  // 4 copies of region y % threads
      const std::size_t at = std::size_t(y % threads) * kCopyFloats;
      std::memcpy(to.data() + at, from.data() + at, kCopyFloats * sizeof(float));
    }
  });
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

ParallelCeiling parallel_ceiling(int threads, int repeats) {
  ParallelCeiling c;
  c.threads = resolve_threads(threads);
  constexpr int kUnits = 16;  // per thread
  std::vector<float> from(kCopyFloats * c.threads, 1.0f), to(kCopyFloats * c.threads, 0.0f);
  std::vector<double> compute, throughput, memory, one_gbs, all_gbs;
  for (int r = 0; r < std::max(1, repeats); ++r) {
    const double one = seconds_for(1, kUnits, register_work),
                 many = seconds_for(c.threads, kUnits, register_work);
    compute.push_back(c.threads * one / many);
    const double busy_one = seconds_for(1, kUnits, throughput_work),
                 busy_many = seconds_for(c.threads, kUnits, throughput_work);
    throughput.push_back(c.threads * busy_one / busy_many);
    const double copy_one = copy_seconds(1, from, to), copy_all = copy_seconds(c.threads, from, to);
    memory.push_back(c.threads * copy_one / copy_all);
    const double bytes = 2.0 * 4 * kCopyFloats * sizeof(float);  // 4 copies, read + write
    one_gbs.push_back(bytes / copy_one / 1e9);
    all_gbs.push_back(c.threads * bytes / copy_all / 1e9);
  }
  c.compute = median(compute);
  c.throughput = median(throughput);
  c.memory = median(memory);
  c.copy_gb_per_s_one = median(one_gbs);
  c.copy_gb_per_s_all = median(all_gbs);
  return c;
}

std::string describe(const ParallelCeiling& c) {
  char line[200];
  std::snprintf(line, sizeof line,
                "machine ceiling, %d threads: register-only work %.2fx (latency-bound), %.2fx "
                "(throughput-bound), memory copy %.2fx (%.1f -> %.1f GB/s)",
                c.threads, c.compute, c.throughput, c.memory, c.copy_gb_per_s_one,
                c.copy_gb_per_s_all);
  return line;
}

}  // namespace bloomref
