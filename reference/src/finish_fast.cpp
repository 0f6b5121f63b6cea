// Stages composite, tonemap and output in f32, the fast way (stages.h: tonemap_fast,
// encode_output_fast, finish_fast): rows handed to the instruction set's kernel
// (finish_kernels.inc), which computes what stages.cpp computes, value by value.
#include <string>
#include <vector>

#include "blur_internal.h"
#include "finish_internal.h"
#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "bloomref/stages.h"

namespace bloomref {
namespace {

void run_rows(BasicView<const float> scene, BasicView<const float> bloom, BasicView<float> dst,
              const detail::FinishRow& job, int threads, BlurIsa isa,
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
  detail::FinishKernel kernel = detail::finish_row_generic;
#ifdef BLOOMREF_HAVE_AVX2_KERNEL
  if (detail::resolves_to_avx2(isa)) kernel = detail::finish_row_avx2;
#else
  detail::resolves_to_avx2(isa);  // throws for avx2
#endif
  const bool with_bloom = !bloom.empty();
  parallel_rows(scene.height, threads, [&](int y0, int y1) {
    std::vector<float> line(detail::finish_line_floats(scene.width) + detail::kFinishLineSlack);
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
      kernel(job, scene.row(y), b, dst.row(y), scene.width, line.data());
    }
  });
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

void finish_fast(BasicView<const float> scene, BasicView<const float> bloom,
                 BasicView<float> dst, float strength, float exposure, float gamma, int threads,
                 BlurIsa isa, const RowSpans* bloom_support) {
  detail::FinishRow job;
  job.strength = strength;
  job.tonemap = job.encode = true;
  job.exposure = exposure;
  job.inv_gamma = 1.0f / gamma;
  run_rows(scene, bloom, dst, job, threads, isa, bloom_support);
}

}  // namespace bloomref
