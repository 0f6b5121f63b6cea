// Stages composite, tonemap and output in f32, the fast way (stages.h: tonemap_fast,
// encode_output_fast, finish_fast): rows handed to the instruction set's kernel
// (finish_kernels.inc), which computes what stages.cpp computes, value by value.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "blur_internal.h"
#include "finish_internal.h"
#include "bloomref/simd/half_bits.h"
#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"

namespace bloomref {
namespace {

// The table of finished values (FinishRow::table) pays where at least this many pixels lie
// outside the bloom's support: it costs the finishing of 65536 values, about 21,850 pixels' worth.
constexpr std::size_t kTableMinPixels = std::size_t(1) << 17;

detail::FinishKernel kernel_for(BlurIsa isa) {
  switch (detail::resolve_isa(isa)) {  // throws for avx2 and avx512 where they are not
#ifdef BLOOMREF_HAVE_AVX2_KERNEL
    case BlurIsa::avx512: return detail::finish_row_avx512;
    case BlurIsa::avx2: return detail::finish_row_avx2;
#endif
    default: return detail::finish_row_generic;
  }
}

// The three finishing stages at once: composite, tone map, output (finish_fast's job, and
// finish_fast_rows').
detail::FinishRow finish_job(float strength, float exposure, float gamma) {
  detail::FinishRow job;
  job.strength = strength;
  job.tonemap = job.encode = true;
  job.exposure = exposure;
  job.inv_gamma = 1.0f / gamma;
  return job;
}

// The pixels outside a support.
std::size_t outside(BasicView<const float> scene, const RowSpans& support) {
  std::size_t n = 0;
  for (const std::vector<Span>& row : support) {
    std::size_t inside = 0;
    for (const Span& s : row) inside += static_cast<std::size_t>(s.x1 - s.x0);
    n += static_cast<std::size_t>(scene.width) - inside;
  }
  return n;
}

// Whether a table of finished values pays for this scene: enough pixels outside the support,
// and of 1024 pixels sampled evenly over the image at least half with three binary16 values
// s + t (a scene read from a half-float file; a float scene has next to none).
bool table_pays(BasicView<const float> scene, std::size_t outside, float t) {
  if (outside < kTableMinPixels) return false;
  const std::size_t pixels = static_cast<std::size_t>(scene.width) * scene.height;
  constexpr std::size_t kSamples = 1024;
  std::size_t halves = 0;
  for (std::size_t i = 0; i < kSamples; ++i) {
    const std::size_t p = i * pixels / kSamples;
    const float* px = scene.row(static_cast<int>(p / scene.width)) + 4 * (p % scene.width);
    std::uint16_t h = 0;
    bool all = true;
    for (int c = 0; c < 3; ++c) all = detail::half_bits_of(px[c] + t, h) && all;
    halves += all;
  }
  return 2 * halves >= kSamples;
}

// The finished value (job's tone map and output, no composite) of every binary16 value, by
// `kernel` itself: the values laid out as the RGB of rows of pixels and finished as any row
// is, so the table holds what the kernel computes for that float.
std::vector<float> finished_half_table(detail::FinishKernel kernel, detail::FinishRow job,
                                       int threads) {
  job.table = nullptr;
  constexpr int kRows = 16, kWidth = 1366;  // 16 * 1366 * 3 = 65568 values >= 65536
  std::vector<float> table(65536);
  parallel_rows(kRows, threads, [&](int r0, int r1) {
    std::vector<float> px(std::size_t(4) * kWidth);
    std::vector<float> line(detail::finish_line_floats(kWidth) + detail::kFinishLineSlack);
    std::vector<detail::PackedRun> runs(kWidth);
    for (int r = r0; r < r1; ++r) {
      const std::size_t first = std::size_t(r) * kWidth * 3;
      for (std::size_t i = 0; i < std::size_t(kWidth) * 3; ++i) {
        const std::size_t j = first + i;
        px[4 * (i / 3) + i % 3] = j < table.size() ? detail::half_value(std::uint16_t(j)) : 0.0f;
      }
      for (int x = 0; x < kWidth; ++x) px[4 * std::size_t(x) + 3] = 0.0f;
      kernel(job, px.data(), detail::BloomRow{}, px.data(), kWidth, line.data(), runs.data());
      for (std::size_t i = 0; i < std::size_t(kWidth) * 3 && first + i < table.size(); ++i)
        table[first + i] = px[4 * (i / 3) + i % 3];
    }
  });
  return table;
}

// The table of a job, kept between runs: it depends only on the kernel, the exposure and 1 /
// gamma (finished_half_table: tone map and output, no composite), which stay the same run
// after run (`run --repeat`, `bench`, a library's frames), and building it is the finishing of
// 65536 values, a large share of a sparse scene's finish (docs/design.md, "A pass's tables are
// built once and kept"). At most kKeptTables, the least recently used dropped first.
constexpr std::size_t kKeptTables = 4;

std::shared_ptr<const std::vector<float>> kept_half_table(detail::FinishKernel kernel,
                                                          const detail::FinishRow& job,
                                                          int threads) {
  struct Entry {
    detail::FinishKernel kernel;
    std::uint32_t exposure, inv_gamma;  // bit patterns: -0 and NaN told apart
    std::shared_ptr<const std::vector<float>> table;
  };
  static std::mutex mutex;
  static std::vector<Entry> kept;  // the most recently used last
  const auto bits = [](float f) {
    std::uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    return u;
  };
  const std::uint32_t e = bits(job.exposure), g = bits(job.inv_gamma);
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (auto it = kept.begin(); it != kept.end(); ++it)
      if (it->kernel == kernel && it->exposure == e && it->inv_gamma == g) {
        Entry found = *it;
        kept.erase(it);
        kept.push_back(found);
        return found.table;
      }
  }
  auto table =
      std::make_shared<const std::vector<float>>(finished_half_table(kernel, job, threads));
  std::lock_guard<std::mutex> lock(mutex);
  kept.push_back({kernel, e, g, table});
  if (kept.size() > kKeptTables) kept.erase(kept.begin());
  return table;
}

std::size_t run_rows(BasicView<const float> scene, BasicView<const float> bloom,
                     BasicView<float> dst, detail::FinishRow job, int threads, BlurIsa isa,
                     const RowSpans* bloom_support = nullptr) {
  if (dst.width != scene.width || dst.height != scene.height ||
      (!bloom.empty() && (bloom.width != scene.width || bloom.height != scene.height)))
    throw ParamError("finishing stages: images of different sizes");
  if (bloom_support && bloom_support->size() != static_cast<std::size_t>(scene.height))
    throw ParamError("finishing stages: the bloom's support has " +
                     std::to_string(bloom_support->size()) + " rows, the image " +
                     std::to_string(scene.height));
  if (bloom_support)
    for (std::size_t y = 0; y < bloom_support->size(); ++y) {
      int end = 0;
      for (const Span& s : (*bloom_support)[y]) {
        if (s.x0 < end || s.x1 <= s.x0 || s.x1 > scene.width)
          throw ParamError("finishing stages: the bloom's support has span [" +
                           std::to_string(s.x0) + ", " + std::to_string(s.x1) + ") on row " +
                           std::to_string(y) + ", not sorted, disjoint and inside [0, " +
                           std::to_string(scene.width) + ")");
        end = s.x1;
      }
    }
  const detail::FinishKernel kernel = kernel_for(isa);
  const bool with_bloom = !bloom.empty();
  std::shared_ptr<const std::vector<float>> table;
  if (with_bloom && bloom_support && job.tonemap && job.encode &&
      table_pays(scene, outside(scene, *bloom_support), job.strength * 0.0f)) {
    table = kept_half_table(kernel, job, threads);
    job.table = table->data();
  }
  std::atomic<std::size_t> looked_up{0};
  parallel_rows(scene.height, threads, [&](int y0, int y1) {
    std::vector<float> line(detail::finish_line_floats(scene.width) + detail::kFinishLineSlack);
    std::vector<detail::PackedRun> runs(static_cast<std::size_t>(scene.width));
    std::size_t n = 0;
    for (int y = y0; y < y1; ++y) {
      detail::BloomRow b;
      if (with_bloom) {
        b.pixels = bloom.row(y);
        if (bloom_support) {
          const std::vector<Span>& spans = (*bloom_support)[std::size_t(y)];
          b.in_spans = true;
          b.spans = spans.data();
          b.span_count = spans.size();
        }
      }
      n += static_cast<std::size_t>(
          kernel(job, scene.row(y), b, dst.row(y), scene.width, line.data(), runs.data()));
    }
    looked_up += n;
  });
  return looked_up;
}

}  // namespace

void tonemap_fast(BasicView<const float> hdr, BasicView<float> dst, float exposure, int threads,
                  BlurIsa isa) {
  detail::FinishRow job;
  job.tonemap = true;
  job.exposure = exposure;
  run_rows(hdr, BasicView<const float>{}, dst, job, threads, isa);
}

void encode_output_fast(BasicView<const float> mapped, BasicView<float> dst, float gamma,
                        int threads, BlurIsa isa) {
  detail::FinishRow job;
  job.encode = true;
  job.inv_gamma = 1.0f / gamma;
  run_rows(mapped, BasicView<const float>{}, dst, job, threads, isa);
}

std::size_t finish_fast(BasicView<const float> scene, BasicView<const float> bloom,
                        BasicView<float> dst, float strength, float exposure, float gamma,
                        int threads, BlurIsa isa, const RowSpans* bloom_support) {
  return run_rows(scene, bloom, dst, finish_job(strength, exposure, gamma), threads, isa,
                  bloom_support);
}

std::shared_ptr<const std::vector<float>> finish_fast_table(BasicView<const float> scene,
                                                            std::size_t outside, float strength,
                                                            float exposure, float gamma,
                                                            int threads, BlurIsa isa) {
  if (!table_pays(scene, outside, strength * 0.0f)) return nullptr;
  return kept_half_table(kernel_for(isa), finish_job(strength, exposure, gamma), threads);
}

std::size_t finish_fast_parts(const FinishPart* parts, std::size_t n, float strength,
                              float exposure, float gamma, const float* table, BlurIsa isa) {
  detail::FinishRow job = finish_job(strength, exposure, gamma);
  job.table = table;
  const detail::FinishKernel kernel = kernel_for(isa);
  int widest = 0;
  for (std::size_t i = 0; i < n; ++i) widest = std::max(widest, parts[i].width);
  std::vector<float> line(detail::finish_line_floats(widest) + detail::kFinishLineSlack);
  std::vector<detail::PackedRun> runs(static_cast<std::size_t>(widest));
  std::size_t looked_up = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const FinishPart& f = parts[i];
    if (f.width <= 0) continue;
    detail::BloomRow b;
    b.pixels = f.bloom ? f.bloom : f.scene;  // not read without spans
    b.in_spans = true;
    b.spans = f.bloom ? f.spans : nullptr;
    b.span_count = f.bloom ? f.span_count : 0;
    looked_up += static_cast<std::size_t>(
        kernel(job, f.scene, b, f.dst, f.width, line.data(), runs.data()));
  }
  return looked_up;
}

void finish_fast_rows(const float* const* scene_rows, const float* const* bloom_rows,
                      float* const* dst_rows, int rows, int width, float strength,
                      float exposure, float gamma, BlurIsa isa) {
  if (rows <= 0 || width <= 0) return;
  const detail::FinishRow job = finish_job(strength, exposure, gamma);
  const detail::FinishKernel kernel = kernel_for(isa);
  std::vector<float> line(detail::finish_line_floats(width) + detail::kFinishLineSlack);
  std::vector<detail::PackedRun> runs(static_cast<std::size_t>(width));
  for (int i = 0; i < rows; ++i) {
    detail::BloomRow b;
    b.pixels = bloom_rows[i];
    kernel(job, scene_rows[i], b, dst_rows[i], width, line.data(), runs.data());
  }
}

}  // namespace bloomref
