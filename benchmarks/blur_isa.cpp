// The exact fast blur compiled for each instruction set this CPU runs (BlurIsa: generic, whose
// vectors are 16 bytes, avx2, avx512), one source (engine/src/blur_tiles.inc) each: ten passes
// of the 9-tap kernel over the bright stage of the demo scene, alternated, medians; every set's
// output checked bit for bit against the generic one's. Beside them a memory copy on the same
// threads (machine_ceiling.h), as bytes moved per second. docs/design.md, "The kernels' vector
// code is written once in the compiler's vector extensions", quotes a run of it.
//   blur_isa [--size WxH] [--threads N] [--repeat N]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "bloomref/engine/fast_stages.h"
#include "bloomref/kernel.h"
#include "bloomref/machine_ceiling.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"

using namespace bloomref;

int main(int argc, char** argv) {
  int w = 3840, h = 2160, threads = 2, repeat = 7;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--size") std::sscanf(argv[i + 1], "%dx%d", &w, &h);
    else if (a == "--threads") threads = std::atoi(argv[i + 1]);
    else if (a == "--repeat") repeat = std::atoi(argv[i + 1]);
    else {
      std::fprintf(stderr, "blur_isa: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  constexpr int kPasses = 10;
  const Image scene = make_scene("demo", w, h);
  Image bright(w, h), ping(w, h), pong(w, h);
  extract_bright(scene.cview(), bright.view(), 1.0f, threads);
  auto ten_passes = [&](BlurIsa isa) {
    const Image* s = &bright;
    for (int p = 0; p < kPasses; ++p) {
      Image& d = p % 2 == 0 ? ping : pong;
      const BlurPassOptions o{p % 2 == 0 ? Axis::horizontal : Axis::vertical, &kernel_discrete9(), 0};
      blur_pass_fast(s->cview(), d.view(), o, threads, isa);
      s = &d;
    }
    return s;
  };
  std::vector<BlurIsa> isas{BlurIsa::generic};
  for (BlurIsa i : {BlurIsa::avx2, BlurIsa::avx512})
    if (blur_isa_available(i)) isas.push_back(i);
  std::vector<std::vector<double>> ms(isas.size());
  std::vector<float> first;
  bool same = true;
  for (int r = 0; r < repeat; ++r)
    for (std::size_t k = 0; k < isas.size(); ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      const Image* out = ten_passes(isas[k]);
      ms[k].push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      const float* p = out->data();
      const std::size_t n = std::size_t(w) * h * kChannels;
      if (first.empty()) first.assign(p, p + n);
      else same &= std::memcmp(first.data(), p, n * sizeof(float)) == 0;
    }
  const ParallelCeiling c = parallel_ceiling(threads);
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  const double bytes = 2.0 * kPasses * double(w) * h * kChannels * sizeof(float);  // read + write
  const double base = median(ms[0]);
  std::printf("exact blur, %d passes at %dx%d, %d threads, medians of %d alternated runs\n",
              kPasses, w, h, threads, repeat);
  std::printf("| instruction set | ms | against generic | bytes a pass reads and writes, per second |\n");
  std::printf("|---|---|---|---|\n");
  for (std::size_t k = 0; k < isas.size(); ++k) {
    const double m = median(ms[k]);
    std::printf("| %s | %.1f | %.2fx | %.1f GB/s |\n", blur_isa_name(isas[k]).c_str(), m, base / m,
                bytes / (m * 1e6));
  }
  std::printf("memory copy, %d threads: %.1f GB/s (read + written)\n", threads, c.copy_gb_per_s_all);
  std::printf("every set's output the generic one's, bit for bit: %s\n", same ? "yes" : "NO");
  return same ? 0 : 1;
}
