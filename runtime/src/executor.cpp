#include "bloomref/executor.h"
#include "bloomref/parallel.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <type_traits>

#include "bloomref/error.h"
#include "bloomref/mip.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "bloomref/engine/page_ledger.h"

namespace bloomref {
namespace {

// Faults in a buffer about to be written whole, the threads taking equal parts (detail::prefault):
// the dense plan's bright image and blur target. In parts because first-touch faults are taken
// by every writing thread, a single call by one (README, stop 17: `bloomref run --size
// 3840x2160 --plan full`, medians 947 / 898 ms against 1048 / 1069 on one thread, 530 / 548
// against 585 / 587 on two; one unsplit call made two threads slower). Buffers under 8 MiB are
// left to fault as they are written.
template <class T>
void prefault_image(BasicImage<T>& img, int threads) {
  const std::size_t bytes = img.values().size() * sizeof(T);
  if (bytes < (std::size_t(8) << 20)) return;
  char* base = reinterpret_cast<char*>(img.values().data());
  const int parts = 64;
  parallel_rows(parts, threads, [&](int i0, int i1) {
    const std::size_t a = bytes * i0 / parts, b = bytes * i1 / parts;
    detail::prefault(base + a, b - a);
  });
}

// The adaptive plan's zeroed scratch images, kept between runs. A fresh zeroed image costs a
// memset of its resident pages or a fault for every page a run touches (about 1.3 us a page on
// this project's machine); the blur of a sparse support writes only its support (and its
// tiles), so a kept image is zeroed again over that support alone: StarField.exr, 2 threads,
// the runs after the first 20.1-22.6 -> 17.0-18.1 ms (README, stop 20). At most kKeep images
// are kept (the oldest go first); release_scratch_images() frees them.
// A kept image is +0 in R, G and B everywhere; its alpha may be 1 where a tile was computed
// around the support (nothing reads the bright image's or the bloom's alpha).
// Each image is kept with the ledger of the pages the blur has faulted in (image.h: PageLedger).
class ScratchPool {
 public:
  Image take(int w, int h, detail::PageLedger& pages) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto it = kept_.begin(); it != kept_.end(); ++it)
        if (it->image.width() == w && it->image.height() == h) {
          Image img = std::move(it->image);
          pages = std::move(it->pages);
          kept_.erase(it);
          return img;
        }
    }
    Image img = Image::zeroed(w, h);
    pages = detail::PageLedger(img.values().data(), img.values().size() * sizeof(float));
    return img;
  }
  // `img` is +0 in R, G and B outside `dirty` (one row of spans per image row): zeroed there,
  // then kept.
  void give(Image&& img, detail::PageLedger&& pages, const RowSpans& dirty, int threads) {
    if (img.empty() || dirty.size() != std::size_t(img.height())) return;
    parallel_rows(img.height(), threads, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y)
        for (const Span& s : dirty[std::size_t(y)])
          std::memset(img.pixel(s.x0, y), 0, std::size_t(s.x1 - s.x0) * kChannels * sizeof(float));
    });
    std::lock_guard<std::mutex> lock(mutex_);
    kept_.push_back({std::move(img), std::move(pages)});
    while (kept_.size() > kKeep) kept_.erase(kept_.begin());
  }
  void clear() {
    std::lock_guard<std::mutex> lock(mutex_);
    kept_.clear();
  }

 private:
  static constexpr std::size_t kKeep = 2;  // a run's two: the bright image and the ping-pong one
  struct Kept {
    Image image;
    detail::PageLedger pages;
  };
  std::mutex mutex_;
  std::vector<Kept> kept_;
};

ScratchPool& scratch_pool() {
  static ScratchPool pool;
  return pool;
}

// A zeroed w x h image; in f32 from the pool, its ledger added to `ledgers`.
template <class T>
BasicImage<T> take_zeroed(int w, int h, std::vector<detail::PageLedger>& ledgers) {
  if constexpr (std::is_same_v<T, float>) return scratch_pool().take(w, h, ledgers.emplace_back());
  else return BasicImage<T>::zeroed(w, h);
}

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

Image to_float_image(const Image& img) { return img; }
Image to_float_image(const ImageF64& img) { return convert_image<float>(img.cview()); }

// Runs the plan in precision T. The scene, bright image and the latest blur result are the only
// full-size images alive at once (plus the kept intermediates when asked).
template <class T>
StageTrace run(const Plan& plan, ConstImageView scene_in, const ExecuteOptions& opt,
               Image* owned) {
  const BloomParams& p = plan.params;
  const int threads = p.threads;
  const HalfRounding rounding = opt.half_rounding;
  const int w = scene_in.width, h = scene_in.height;
  StageTrace trace;

  auto record = [&](const std::string& name, const BasicImage<T>& img, double ms, bool skipped) {
    if (!skipped) trace.timings.emplace_back(name, ms);
    if (opt.keep_all || name == "output") trace.stages.push_back({name, to_float_image(img), ms, skipped});
  };

  const auto t_total = Clock::now();
  BasicImage<T> scene;
  // The finishing stages: the fast f32 ones unless the staged reference was asked for (--blur
  // reference) or values are rounded to f16 between stages; and all three in one sweep
  // (finish_fast) where no intermediate is kept and the composite comes before the tone map.
  const bool fast_finish = std::is_same_v<T, float> && p.blur != BlurImpl::reference &&
                           p.storage == Storage::f32;
  const bool fuse_finish = fast_finish && !opt.keep_all &&
                           !(p.method == Method::mip &&
                             p.composite == CompositeOrder::after_tonemap);
  // Where the gaussian blur's last passes run fused, the finishing stages run inside it, on
  // each block of the last pass (blur_passes_fused's sink): the composite stage then has
  // nothing left to do.
  const bool finish_in_blur = fuse_finish && p.method == Method::gaussian;
  bool finished_in_blur = false;
  // Whether dense blur passes run fused (blur_passes_fused): the fast f32 blur or the
  // approximate one, nothing rounded or kept between passes. The blur stage runs the rest fused
  // from the first dense pass.
  const bool fusable = std::is_same_v<T, float> && p.blur != BlurImpl::reference &&
                       p.storage == Storage::f32 && !opt.keep_all;
  // The full plan then runs every pass fused from pass 1, and stage bright with them
  // (blur_bright_fused): no bright image is made. It was one more full-size image, faulted in
  // by every run (mmap'd anew: 133 MB at 3840x2160), written and read once. So does the
  // adaptive plan on a dense scene (Plan::dense_scene), tracking no support.
  // The approximate blur takes that path under the adaptive plan too, whenever something is
  // bright: following a support, it runs pass by pass over whole images, skipping only rows
  // (stages.h: blur_pass_approx), and measured slower than all of it fused (stop 31, --repeat 5
  // warm medians, 2 threads: StarField 28.6 against 14.9 ms, CandleGlass 23.1 against 10.3).
  const bool bright_in_blur =
      fusable && finish_in_blur &&
      (p.plan == PlanMode::full || plan.dense_scene || p.blur == BlurImpl::approx) &&
      std::any_of(plan.stages.begin(), plan.stages.end(), [](const StageSpec& s) {
        return s.kind == StageKind::blur && s.pass == 1 && !s.skipped;
      });
  // The adaptive plan's blur follows the bright pixels' support pass by pass.
  const bool track_support = p.plan == PlanMode::adaptive && !bright_in_blur;
  // Written by the input stage (extract_bright): whole, or under the adaptive plan when no
  // stage is kept and at most 1% of the pixels are bright, only its bright pixels into a zeroed
  // image (its pages exist where written; no stage after it reads its alpha, left 0 elsewhere).
  // A blur that reads all of it (the adaptive one once dense) pays a fault for every page never
  // written; none where the bright stage runs inside the fused blur. The corpus's images are
  // either sparse (0.03-0.6% bright: StarField, GoldenGate, CandleGlass, the demo) or not
  // (10-25%: WideColorGamut, BrightRingsNanInf, StageEnvLatLong, WideFloatRange, comp_dwab_v2).
  const int bw = p.method == Method::gaussian && !bright_in_blur ? w : 0;
  const int bh = p.method == Method::gaussian && !bright_in_blur ? h : 0;
  const bool sparse_bright = p.plan == PlanMode::adaptive && !opt.keep_all &&
                             plan.facts.bright_pixels * 100 <= std::uint64_t(w) * std::uint64_t(h);
  // The ledgers of the pool's images (image.h), each found by the buffer it was made for.
  std::vector<detail::PageLedger> ledgers;
  ledgers.reserve(2);  // the bright image and the first blur target
  auto ledger_of = [&](const BasicImage<T>& img) -> detail::PageLedger* {
    for (detail::PageLedger& l : ledgers)
      if (!img.empty() && l.of(img.data())) return &l;
    return nullptr;
  };
  BasicImage<T> bright = sparse_bright ? take_zeroed<T>(bw, bh, ledgers)
                                       : BasicImage<T>::uninitialised(bw, bh);
  if (!sparse_bright) prefault_image(bright, threads);
  BasicImage<T> ping, pong;  // allocated by the first blur pass
  // The adaptive fast f32 blur writes only the tiles its support reaches when what it writes
  // into is already +0 around them (stages.h: dst_zero_outside), and no stage image is kept (the
  // texels left alone keep alpha 0, which nothing after the blur reads): its first pass then
  // writes into pages that only exist where written (image.h: zeroed).
  const bool leave_zeros = p.plan == PlanMode::adaptive && p.blur == BlurImpl::fast &&
                           std::is_same_v<T, float> && !opt.keep_all;
  bool blur_fused_done = false;  // the remaining blur passes ran fused (blur_passes_fused)
  auto tonemap_as = [&](const BasicImage<T>& src, BasicImage<T>& dst) {
    if constexpr (std::is_same_v<T, float>)
      if (fast_finish) return tonemap_fast(src.cview(), dst.view(), p.exposure, threads);
    tonemap(src.cview(), dst.view(), static_cast<T>(p.exposure), threads);
  };
  auto encode_output_as = [&](const BasicImage<T>& src, BasicImage<T>& dst) {
    if constexpr (std::is_same_v<T, float>)
      if (fast_finish) return encode_output_fast(src.cview(), dst.view(), p.gamma, threads);
    encode_output(src.cview(), dst.view(), static_cast<T>(p.gamma), threads);
  };
  // Method mip: level k of the down and up chains (index 0 unused), and the full-size bloom.
  std::vector<BasicImage<T>> down(plan.levels.size() + 1), up(plan.levels.size() + 1);
  BasicImage<T> mip_bloom, mapped;
  // Adaptive plan: the blur's nonzero texels; whole passes once they cover half the image.
  BlurSupportTracker support(w, h, 0.5);
  const int top = static_cast<int>(plan.levels.size());
  // Adaptive plan, method mip: the texels of a chain stage that can be nonzero (mip_support),
  // from the nonzero texels of what it reads; null (compute all) under the full plan or once
  // they cover half the target. Records the skipped fraction.
  // Up the chain the support only grows (each level adds the tent's reach to the one below and
  // its own down level's), so once one up stage is dense the rest are computed whole untracked.
  std::vector<std::uint8_t> mip_src_mask, mip_also_mask, mip_active;
  bool mip_up_dense = false;
  auto mip_mask = [&](const std::string& name, const BasicImage<T>& src, const BasicImage<T>& dst,
                      int reach, const BasicImage<T>& also) -> const std::uint8_t* {
    if (p.plan != PlanMode::adaptive) return nullptr;
    const bool up_chain = reach == 1;
    if (up_chain && mip_up_dense) {
      trace.skipped_fraction.emplace_back(name, 0.0);
      return nullptr;
    }
    mip_src_mask.resize(src.pixel_count());
    nonzero_support(src.cview(), mip_src_mask.data(), threads);
    if (!also.empty()) {
      mip_also_mask.resize(also.pixel_count());
      nonzero_support(also.cview(), mip_also_mask.data(), threads);
    }
    mip_active.resize(dst.pixel_count());
    const std::size_t n = mip_support<T>(
        mip_src_mask.data(), src.width(), src.height(), also.empty() ? nullptr : mip_also_mask.data(),
        dst.width(), dst.height(), reach, p.subtexel_bits, mip_active.data(), threads);
    const bool dense = 2 * n > dst.pixel_count();
    mip_up_dense = up_chain && dense;
    trace.skipped_fraction.emplace_back(
        name, dense ? 0.0 : 1.0 - double(n) / double(dst.pixel_count()));
    return dense ? nullptr : mip_active.data();
  };

  for (const StageSpec& stage : plan.stages) {
    const auto t0 = Clock::now();
    switch (stage.kind) {
      case StageKind::input: {
        if constexpr (std::is_same_v<T, float>) {
          if (owned) {
            scene = std::move(*owned);  // the caller handed the image over: no copy
          } else {
            // Copied by every thread (the pages are faulted in by whichever thread writes them
            // first), with no zero fill before the copy.
            scene = BasicImage<T>::uninitialised(w, h);
            parallel_rows(h, threads, [&](int y0, int y1) {
              for (int y = y0; y < y1; ++y)
                std::copy(scene_in.row(y), scene_in.row(y) + std::size_t(w) * kChannels,
                          scene.view().row(y));
            });
          }
        } else {
          scene = convert_image<T>(scene_in);
        }
        // In place: each value is read once and written once at the same index.
        if (plan.sanitize)
          trace.nonfinite = sanitize(scene.cview(), scene.view(), p.nonfinite, p.storage, threads);
        // The seeds' MRT pass writes the scene and the bright colour in one draw: bright is
        // decided on the sanitised value before either is stored (rounded to f16).
        if (p.method == Method::gaussian && !bright_in_blur) {
          // The adaptive plan's first support comes out of the same sweep (the bright image's
          // nonzero texels): no second read of the bright image, most of whose pages are
          // never written (zeroed).
          std::vector<std::uint8_t> nonzero;
          const bool blurs = std::any_of(plan.stages.begin(), plan.stages.end(), [](const StageSpec& s) {
            return s.kind == StageKind::blur && !s.skipped;
          });
          if (p.plan == PlanMode::adaptive && blurs) nonzero.resize(std::size_t(w) * h);
          // Into a zeroed image the rows without a bright pixel (the plan's scan found them)
          // have nothing to write and a zero support: not read at all.
          const std::uint8_t* rows =
              sparse_bright && plan.facts.bright_rows.size() == std::size_t(h)
                  ? plan.facts.bright_rows.data() : nullptr;
          extract_bright(scene.cview(), bright.view(), static_cast<T>(p.threshold), threads,
                         /*dst_zeroed=*/sparse_bright, nonzero.empty() ? nullptr : nonzero.data(),
                         rows);
          if (!nonzero.empty()) support.start(std::move(nonzero), threads, rows);
        }
        store(scene.view(), p.storage, rounding, threads);
        record(stage.name, scene, ms_since(t0), false);
        break;
      }
      case StageKind::bright: {
        if (bright_in_blur) break;  // in the fused blur, timed with it
        const auto t1 = Clock::now();
        store(bright.view(), p.storage, rounding, threads);
        record(stage.name, bright, ms_since(t1), false);
        break;
      }
      case StageKind::blur: {
        const BasicImage<T>& src = stage.pass == 1 ? bright : ping;
        if (blur_fused_done) break;  // this pass ran inside the fused blur
        if (stage.skipped) {
          // Blur of an all-zero image is exactly zero: the bloom is `bright` itself.
          if (opt.keep_all) record(stage.name, bright, 0.0, true);
          break;
        }
        BlurPassOptions o{stage.axis, &kernel_for(p.kernel), p.subtexel_bits};
        const bool first_pass = stage.pass == 1;
        if (track_support) {
          // Blur only the bright pixels' support (started by the input stage), dilated pass by
          // pass by the taps' reach. Every pass on all the run's threads: a small support on
          // one thread (under 2^15 texels, when waking the others cost more than they saved
          // before the kept arenas, parallel.cpp) measured slower since (README, stop 29).
          o.active = support.advance<T>(o, threads);
          o.active_spans = support.spans();
          // Pass k > 1 writes the buffer pass k - 2 (pass 2: bright) left +0 outside a support
          // contained in this one (stages.h); pass 1 a zeroed one, or a new one it fills.
          o.dst_zero_outside = !first_pass || leave_zeros;
          trace.skipped_fraction.emplace_back(
              stage.name, 1.0 - double(support.count()) / (double(w) * h));
        }
        // Dense from here on (the full plan, or the adaptive plan once its support covers half
        // the image): the rest of the passes run fused. (Always with the bright stage inside:
        // bright_in_blur implies fusable and tracks nothing.)
        const bool fused_rest = fusable && o.active == nullptr;
        if (pong.empty() && !(fused_rest && finish_in_blur)) {
          if (leave_zeros && first_pass) {
            pong = take_zeroed<T>(w, h, ledgers);
          } else {
            pong = BasicImage<T>::uninitialised(w, h);
            prefault_image(pong, threads);  // written whole by this pass
          }
        }
        if (track_support) {
          o.src_pages = ledger_of(src);
          o.dst_pages = ledger_of(pong);
          o.page_threads = threads;
        }
        if constexpr (std::is_same_v<T, float>) {
          // This pass and the rest at once, fused (the same bits as pass by pass, tested; the
          // image is read and written once). The adaptive plan stops tracking its support once
          // dense, so the rest are recorded as not skipping anything.
          if (fused_rest) {
            std::vector<Axis> axes;
            for (const StageSpec& s : plan.stages)
              if (s.kind == StageKind::blur && s.pass >= stage.pass) {
                axes.push_back(s.axis);
                if (p.plan == PlanMode::adaptive && (s.pass > stage.pass || bright_in_blur))
                  trace.skipped_fraction.emplace_back(s.name, 0.0);
              }
            std::string name = "blur." + std::to_string(stage.pass) + "-" +
                               std::to_string(stage.pass + int(axes.size()) - 1);
            if (finish_in_blur) {
              // Composite, tone map and output on each block of the last pass while it is in
              // cache, in place into the scene (finish_fast_rows: finish_fast's bits, value by
              // value): no bloom image is allocated, written or read back.
              BasicView<float> out = scene.view();
              const FusedBlurSink sink = [&](int x0, int x1, int y0, int y1,
                                             const float* const* rows) {
                std::vector<float*> dst(std::size_t(y1 - y0));
                for (int y = y0; y < y1; ++y) dst[std::size_t(y - y0)] = out.row(y) + 4 * x0;
                finish_fast_rows(dst.data(), rows, dst.data(), y1 - y0, x1 - x0, p.strength,
                                 p.exposure, p.gamma);
              };
              if (bright_in_blur) {
                blur_bright_fused(scene.cview(), static_cast<float>(p.threshold), sink, axes,
                                  kernel_for(p.kernel), p.subtexel_bits, threads, BlurIsa::best,
                                  p.blur);
                name = "bright+" + name;
              } else {
                blur_passes_fused(src.cview(), sink, axes, kernel_for(p.kernel), p.subtexel_bits,
                                  threads, BlurIsa::best, p.blur);
              }
              finished_in_blur = true;
              name += "+composite+tonemap+output";
            } else {
              blur_passes_fused(src.cview(), pong.view(), axes, kernel_for(p.kernel),
                                p.subtexel_bits, threads, BlurIsa::best, p.blur);
              std::swap(ping, pong);
            }
            pong = BasicImage<T>();
            bright = BasicImage<T>();  // not read again
            blur_fused_done = true;
            trace.timings.emplace_back(name, ms_since(t0));
            break;
          }
          if (p.blur == BlurImpl::fast) blur_pass_fast(src.cview(), pong.view(), o, threads);
          else if (p.blur == BlurImpl::approx) blur_pass_approx(src.cview(), pong.view(), o, threads);
          else blur_pass(src.cview(), pong.view(), o, threads);
        } else {
          blur_pass(src.cview(), pong.view(), o, threads);
        }
        store(pong.view(), p.storage, rounding, threads);
        std::swap(ping, pong);
        // After the first pass the bright image is not read again: its buffer becomes the
        // other half of the ping-pong pair (three full-size images alive: scene, ping, pong).
        if (first_pass && pong.empty()) pong = std::move(bright);
        record(stage.name, ping, ms_since(t0), false);
        break;
      }
      case StageKind::down: {
        const int k = stage.pass;
        const BasicImage<T>& src = k == 1 ? scene : down[k - 1];
        down[k] = BasicImage<T>(plan.levels[k - 1].width, plan.levels[k - 1].height);
        DownsampleOptions o{k == 1, p.threshold, p.karis && k == 1, p.subtexel_bits};
        // The first level reads the whole scene; the others only where the level above has
        // anything (adaptive plan).
        if (k > 1) {
          o.active = mip_mask(stage.name, src, down[k], 2, BasicImage<T>());
        } else if (p.plan == PlanMode::adaptive &&
                   mip_nothing_bright(src.cview(), double(p.threshold), threads)) {
          mip_active.assign(down[k].pixel_count(), 0);  // every tap thresholded to zero
          o.active = mip_active.data();
          trace.skipped_fraction.emplace_back(stage.name, 1.0);
        }
        downsample(src.cview(), down[k].view(), o, threads);
        store(down[k].view(), p.storage, rounding, threads);
        record(stage.name, down[k], ms_since(t0), false);
        break;
      }
      case StageKind::up: {
        const int k = stage.pass;
        const BasicImage<T>& small = k + 1 == top ? down[top] : up[k + 1];
        up[k] = BasicImage<T>(down[k].width(), down[k].height());
        upsample_tent(small.cview(), down[k].cview(), up[k].view(), p.subtexel_bits, threads,
                      mip_mask(stage.name, small, up[k], 1, down[k]));
        store(up[k].view(), p.storage, rounding, threads);
        record(stage.name, up[k], ms_since(t0), false);
        break;
      }
      case StageKind::bloom: {
        const BasicImage<T>& small = top == 1 ? down[1] : up[1];
        mip_bloom = BasicImage<T>(w, h);
        upsample_tent(small.cview(), BasicView<const T>{}, mip_bloom.view(), p.subtexel_bits,
                      threads, mip_mask(stage.name, small, mip_bloom, 1, BasicImage<T>()));
        store(mip_bloom.view(), p.storage, rounding, threads);
        record(stage.name, mip_bloom, ms_since(t0), false);
        break;
      }
      case StageKind::composite: {
        if (finished_in_blur) break;  // in the fused blur's sink, timed with it
        // What is added: the mip chain's bloom, the last blur pass, or (no pass ran) bright.
        const bool blurred = p.method == Method::gaussian && p.passes > 0 &&
                             !plan.stages[1 + p.passes].skipped;
        const BasicImage<T>& bloom =
            p.method == Method::mip ? mip_bloom : blurred ? ping : bright;
        if (fuse_finish) {
          // composite, tonemap and output at once, in place into the scene (finish_fast: the
          // three stages' bits, tested); one timing for the three.
          // Under the adaptive plan the bloom's R, G and B are +0 outside the last pass's
          // support (or everywhere, when nothing was bright enough to blur): the composite
          // does not read it there (most of its pages were never written).
          const RowSpans* bloom_support = nullptr;
          RowSpans none;  // no spans on any row
          if (p.plan == PlanMode::adaptive && p.method == Method::gaussian) {
            if (plan.facts.bright_pixels == 0) {
              none.resize(std::size_t(h));
              bloom_support = &none;
            } else if (blurred && !blur_fused_done && support.started()) {
              bloom_support = support.spans();  // null once dense
            }
          }
          if constexpr (std::is_same_v<T, float>) {
            const std::size_t from_table =
                finish_fast(scene.cview(), bloom.cview(), scene.view(), p.strength, p.exposure,
                            p.gamma, threads, BlurIsa::best, bloom_support);
            if (from_table)  // finished from the table of binary16 values, not computed
              trace.skipped_fraction.emplace_back(
                  "composite+tonemap+output", double(from_table) / (double(w) * h));
          }
          mip_bloom = BasicImage<T>();
        } else if (p.method == Method::mip) {
          // before-tonemap: scene + strength * bloom; after-tonemap: mapped + strength * bloom.
          BasicImage<T>& base = p.composite == CompositeOrder::after_tonemap ? mapped : scene;
          BasicImage<T> out(w, h);
          composite(base.cview(), bloom.cview(), out.view(), static_cast<T>(p.strength),
                    threads);
          store(out.view(), p.storage, rounding, threads);
          scene = std::move(out);
        } else {
          // In place into the scene (per value, same index).
          composite(scene.cview(), bloom.cview(), scene.view(), static_cast<T>(p.strength),
                    threads);
          store(scene.view(), p.storage, rounding, threads);
        }
        // The bloom buffers go (empty under the mip method); those of a sparse adaptive blur
        // back to the pool, zeroed over the last support (which holds every texel a pass or
        // the input stage wrote nonzero: the supports only grow from the bright pixels).
        if constexpr (std::is_same_v<T, float>) {
          if (leave_zeros && support.started() && support.spans())
            for (BasicImage<T>* img : {&ping, &pong, &bright}) {
              detail::PageLedger* pages = ledger_of(*img);
              scratch_pool().give(std::move(*img), pages ? std::move(*pages) : detail::PageLedger(),
                                  *support.spans(), threads);
            }
        }
        ping = BasicImage<T>();
        pong = BasicImage<T>();
        bright = BasicImage<T>();
        if (fuse_finish) trace.timings.emplace_back("composite+tonemap+output", ms_since(t0));
        else record(stage.name, scene, ms_since(t0), false);
        break;
      }
      case StageKind::tonemap:
        if (fuse_finish) break;  // done with the composite
        if (p.method == Method::mip && p.composite == CompositeOrder::after_tonemap) {
          mapped = BasicImage<T>(w, h);  // the scene tone-mapped; the bloom is added after
          tonemap_as(scene, mapped);
          store(mapped.view(), p.storage, rounding, threads);
          record(stage.name, mapped, ms_since(t0), false);
          break;
        }
        tonemap_as(scene, scene);
        store(scene.view(), p.storage, rounding, threads);
        record(stage.name, scene, ms_since(t0), false);
        break;
      case StageKind::output: {
        if constexpr (std::is_same_v<T, float>) {
          if (fuse_finish) {  // done with the composite; the buffer is handed over
            trace.total_ms = ms_since(t_total);
            trace.stages.push_back({stage.name, std::move(scene), 0.0, false});
            break;
          }
        }
        encode_output_as(scene, scene);
        store(scene.view(), p.storage, rounding, threads);
        // The stage's clock is read before the run's: the stages' times add up to at most the
        // total.
        const double output_ms = ms_since(t0);
        trace.total_ms = ms_since(t_total);
        if constexpr (std::is_same_v<T, double>) trace.output_f64 = scene;
        if constexpr (std::is_same_v<T, float>) {
          if (!opt.keep_all) {  // hand the buffer over instead of copying it
            trace.timings.emplace_back(stage.name, output_ms);
            trace.stages.push_back({stage.name, std::move(scene), output_ms, false});
            break;
          }
        }
        record(stage.name, scene, output_ms, false);
        break;
      }
    }
  }
  return trace;
}

// The plan's scan of the scene is part of the run it was made for: its first timing, "plan", and
// part of the total.
StageTrace with_scan(const Plan& plan, StageTrace trace) {
  trace.timings.insert(trace.timings.begin(), {"plan", plan.facts.scan_ms});
  trace.total_ms += plan.facts.scan_ms;
  return trace;
}

}  // namespace

void release_scratch_images() { scratch_pool().clear(); }

const StageResult* StageTrace::find(const std::string& name) const {
  for (const StageResult& s : stages)
    if (s.name == name) return &s;
  return nullptr;
}

StageTrace execute(const Plan& plan, ConstImageView scene, const ExecuteOptions& opt) {
  if (scene.width != plan.facts.width || scene.height != plan.facts.height)
    throw ParamError("the plan was made for a " + std::to_string(plan.facts.width) + "x" +
                     std::to_string(plan.facts.height) + " scene, not " +
                     std::to_string(scene.width) + "x" + std::to_string(scene.height));
  return with_scan(plan, plan.params.precision == Precision::f64
                               ? run<double>(plan, scene, opt, nullptr)
                               : run<float>(plan, scene, opt, nullptr));
}

StageTrace execute(const Plan& plan, Image&& scene, const ExecuteOptions& opt) {
  if (plan.params.precision == Precision::f64) return execute(plan, scene.cview(), opt);
  if (scene.width() != plan.facts.width || scene.height() != plan.facts.height)
    return execute(plan, scene.cview(), opt);  // reports the mismatch
  const ConstImageView view = scene.cview();
  return with_scan(plan, run<float>(plan, view, opt, &scene));
}

}  // namespace bloomref
