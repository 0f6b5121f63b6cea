#include "bloomref/executor.h"
#include "bloomref/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <type_traits>
#include <utility>

#include "bloomref/error.h"
#include "bloomref/mip.h"
#include "bloomref/engine/boxes.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "bloomref/engine/page_ledger.h"

namespace bloomref {
namespace {

// Faults in a buffer about to be written whole, the threads taking equal parts (prefault):
// the dense plan's bright image and blur target. In parts because first-touch faults are taken
// by every writing thread, a single call by one: one unsplit call made a run on two threads
// slower (docs/design.md, "Nothing is written where nothing is"). Buffers under 8 MiB are left
// to fault as they are written.
template <class T>
void prefault_image(BasicImage<T>& img, int threads) {
  const std::size_t bytes = img.values().size() * sizeof(T);
  if (bytes < (std::size_t(8) << 20)) return;
  char* base = reinterpret_cast<char*>(img.values().data());
  const int parts = 64;
  parallel_rows(parts, threads, [&](int i0, int i1) {
    const std::size_t a = bytes * i0 / parts, b = bytes * i1 / parts;
    prefault(base + a, b - a);
  });
}

// The adaptive plan's zeroed scratch images, kept between runs. A fresh zeroed image costs a
// memset of its resident pages or a fault for every page a run touches; the blur of a sparse
// support writes only its support (and its tiles), so a kept image is zeroed again over that
// support alone, and the runs after the first are faster (docs/design.md, "Nothing is written
// where nothing is"). At most kKeep images are kept (the oldest go first);
// release_scratch_images() frees them.
// A kept image is +0 in R, G and B everywhere; its alpha may be 1 where a tile was computed
// around the support (nothing reads the bright image's or the bloom's alpha).
// Each image is kept with the ledger of the pages the blur has faulted in (PageLedger,
// bloomref/engine/page_ledger.h).
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

// ---- How to schedule it --------------------------------------------------------------------
// The stages below are the specification's (plan.h); the schedule says which code computes
// them. Every schedule gives the same bits (tests/runtime/test_determinism.cpp).

// How the gaussian method's blur passes run.
enum class BlurPath {
  // Pass by pass, each pass stored (and kept when asked): f64, f16 storage, the reference
  // blur, or every stage kept.
  staged,
  // Pass by pass over the bright pixels' support (adaptive plan) while it is sparse; from the
  // first dense pass, the rest at once (blur_passes_fused: the image read and written once),
  // the finishing stages in its sink.
  fused_once_dense,
  // Stage bright and every pass at once from pass 1 (blur_bright_fused), the finishing stages
  // in its sink: no bright image is made.
  fused_from_bright,
  // Adaptive plan, a sparse support in a few clusters: stage bright, every pass and the
  // finishing stages box by box (engine/boxes.h), no whole-image buffer made.
  boxed,
};

// How the finishing stages (composite, tonemap, output) run.
enum class FinishPath {
  reference,  // stage by stage, the scalar kernels
  fast,       // stage by stage, the vectorised f32 tone map and output
  fused,      // all three in one sweep (finish_fast), or in the fused blur's sink
};

struct Schedule {
  BlurPath blur = BlurPath::staged;
  FinishPath finish = FinishPath::reference;
  // Adaptive plan: the blur passes and the mip chain compute only the texels that can be
  // nonzero (the bright pixels' support, dilated stage by stage).
  bool track_support = false;
  // The input stage writes only the bright pixels, into a zeroed image from the pool.
  bool sparse_bright = false;
  // Blur pass 1 writes into a zeroed image from the pool, only the tiles its support reaches.
  bool zeroed_blur_target = false;
};

// Whether blur pass 1 runs (the plan skips every pass of a scene with nothing bright).
bool blurs_from_pass_1(const Plan& plan) {
  return std::any_of(plan.stages.begin(), plan.stages.end(), [](const StageSpec& s) {
    return s.kind == StageKind::blur && s.pass == 1 && !s.skipped;
  });
}

// Whether the adaptive plan may blur this scene in boxes (engine/boxes.h): the fused f32 path
// (the fast blur, nothing kept, no value to sanitise first), something to blur, and at most 1%
// of the pixels bright (as sparse_bright below; the boxes then decide).
bool may_box(const Plan& plan, const ExecuteOptions& opt) {
  const BloomParams& p = plan.params;
  const std::uint64_t pixels = std::uint64_t(plan.facts.width) * std::uint64_t(plan.facts.height);
  return p.plan == PlanMode::adaptive && p.method == Method::gaussian &&
         p.composite_mode == CompositeMode::add && p.precision == Precision::f32 && p.storage == Storage::f32 &&
         p.blur == BlurImpl::fast && !opt.keep_all && !plan.sanitize && !plan.dense_scene &&
         !plan.small_scene && p.seed_luma() &&  // the boxes' bright test is the seeds' luminance
         p.passes > 0 && blurs_from_pass_1(plan) && plan.facts.bright_pixels * 100 <= pixels;
}

// The boxes' share of the image beyond which the scene is blurred whole-image pass by pass
// instead (the adaptive plan's support tracking stops at half the image too).
constexpr double kMaxBoxedFraction = 0.5;

// The adaptive plan's boxes for this scene (an empty layout where it blurs otherwise), and the
// finishing stages' table of binary16 values (finish_fast_table), built beside them: the
// boxes cover at most kMaxBoxedFraction of the image, so at least the rest lies outside the
// support.
struct Boxes {
  BoxedBlur layout;
  std::shared_ptr<const std::vector<float>> table;
};

Boxes boxes_for(const Plan& plan, const ExecuteOptions& opt, ConstImageView scene) {
  const BloomParams& p = plan.params;
  Boxes b;
  if (!may_box(plan, opt)) return b;
  const std::uint8_t* rows = plan.facts.bright_rows.size() == std::size_t(scene.height)
                                 ? plan.facts.bright_rows.data()
                                 : nullptr;
  RowSpans bright;
  bright_support_spans(scene, static_cast<float>(p.threshold), rows, bright, p.threads);
  std::vector<Axis> axes;
  for (const StageSpec& s : plan.stages)
    if (s.kind == StageKind::blur) axes.push_back(s.axis);
  const auto pixels = std::size_t(scene.width) * std::size_t(scene.height);
  parallel_rows(2, p.threads, [&](int i0, int i1) {
    for (int i = i0; i < i1; ++i) {
      if (i == 0)
        b.layout = BoxedBlur(scene.width, scene.height, std::move(bright), axes,
                             kernel_for(p.kernel), p.subtexel_bits, kMaxBoxedFraction, p.threads);
      else
        b.table = finish_fast_table(scene, pixels - std::size_t(kMaxBoxedFraction * pixels),
                                    static_cast<float>(p.strength), static_cast<float>(p.exposure),
                                    static_cast<float>(p.gamma), p.threads);
    }
  });
  return b;
}

Schedule choose_schedule(const Plan& plan, const ExecuteOptions& opt, bool boxed) {
  const BloomParams& p = plan.params;
  const bool adaptive = p.plan == PlanMode::adaptive;
  // The vectorised f32 kernels, unless the staged reference was asked for (--blur reference)
  // or values are rounded to f16 between stages.
  const bool fast =
      p.precision == Precision::f32 && p.blur != BlurImpl::reference && p.storage == Storage::f32;
  // Fused where no intermediate is kept; the finish only where the composite comes before the
  // tone map.
  const bool fuse = fast && !opt.keep_all && p.composite_mode == CompositeMode::add;
  Schedule s;
  s.finish = !fast ? FinishPath::reference
             : fuse && !(p.method == Method::mip && p.composite == CompositeOrder::after_tonemap)
                 ? FinishPath::fused
                 : FinishPath::fast;
  if (p.method == Method::gaussian && fuse) {
    // The full plan blurs every pixel, and so does the adaptive plan on a dense scene
    // (Plan::dense_scene) and for the approximate blur, which following a support runs pass by
    // pass over whole images (stages.h: blur_pass_approx) and is slower than all of it fused.
    // The bright image is then one more full-size image, faulted in, written and read once.
    const bool dense =
        !adaptive || plan.dense_scene || plan.small_scene || p.blur == BlurImpl::approx;
    // The fused bright pass tests the seeds' luminance; another makes the bright image first.
    s.blur = dense && blurs_from_pass_1(plan) && p.seed_luma() ? BlurPath::fused_from_bright
                                                                : BlurPath::fused_once_dense;
  }
  if (boxed) s.blur = BlurPath::boxed;
  s.track_support = adaptive && s.blur != BlurPath::fused_from_bright && s.blur != BlurPath::boxed;
  // At most 1% of the pixels bright: the corpus's images are either sparse (0.03-0.6%:
  // StarField, GoldenGate, CandleGlass, the demo) or not (10-25%). A blur that reads all of the
  // bright image pays a fault for every page never written.
  const std::uint64_t pixels = std::uint64_t(plan.facts.width) * std::uint64_t(plan.facts.height);
  s.sparse_bright = adaptive && !opt.keep_all && plan.facts.bright_pixels * 100 <= pixels;
  // No stage kept, so the texels left alone (alpha 0, which nothing after the blur reads) are
  // never seen (fast_stages.h: FastPassOptions::dst_zero_outside).
  s.zeroed_blur_target =
      adaptive && p.blur == BlurImpl::fast && p.precision == Precision::f32 && !opt.keep_all;
  return s;
}

// ---- The algorithm: one function per stage -------------------------------------------------

// Runs the plan in precision T. The scene, bright image and the latest blur result are the only
// full-size images alive at once (plus the kept intermediates when asked).
template <class T>
class Executor {
 public:
  Executor(const Plan& plan, ConstImageView scene_in, const ExecuteOptions& opt, Image* owned,
           Image* output = nullptr)
      : plan_(plan),
        p_(plan.params),
        opt_(opt),
        boxed_(boxes_for(plan, opt, scene_in)),
        boxes_ms_(ms_since(t_total_)),
        sched_(choose_schedule(plan, opt, boxed_.layout.ok())),
        scene_in_(scene_in),
        owned_(owned),
        output_(output),
        w_(scene_in.width),
        h_(scene_in.height),
        threads_(plan.params.threads),
        support_(scene_in.width, scene_in.height, 0.5),
        down_(plan.levels.size() + 1),
        up_(plan.levels.size() + 1),
        handed_(owned ? owned->data() : output ? output->data() : nullptr) {}

  // On an exception the buffer the caller handed over goes back to it (its values unspecified):
  // a caller whose array still points at that buffer (the Python module's `out=`) keeps it.
  StageTrace run() {
    try {
      return run_stages();
    } catch (...) {
      if constexpr (kF32) {
        Image* from = owned_ ? owned_ : output_;
        if (from && handed_ && scene_.data() == handed_) *from = std::move(scene_);
      }
      throw;
    }
  }

 private:
  StageTrace run_stages() {
    // Room for with_scan's timing of the plan: no allocation after the output is handed over.
    trace_.timings.reserve(plan_.stages.size() + 4);
    ledgers_.reserve(2);  // the bright image and the first blur target
    make_bright_image();
    for (const StageSpec& stage : plan_.stages) {
      const auto t0 = Clock::now();
      switch (stage.kind) {
        case StageKind::input:
          input(stage, t0);
          break;
        case StageKind::bright:
          bright(stage);
          break;
        case StageKind::blur:
          blur(stage, t0);
          break;
        case StageKind::down:
          down(stage, t0);
          break;
        case StageKind::up:
          up(stage, t0);
          break;
        case StageKind::bloom:
          mip_bloom(stage, t0);
          break;
        case StageKind::composite:
          composite_stage(stage, t0);
          break;
        case StageKind::tonemap:
          tonemap_stage(stage, t0);
          break;
        case StageKind::output:
          output(stage, t0);
          break;
      }
    }
    return std::move(trace_);
  }

  static constexpr bool kF32 = std::is_same_v<T, float>;

  void record(const std::string& name, const BasicImage<T>& img, double ms, bool skipped) {
    if (!skipped) trace_.timings.emplace_back(name, ms);
    if (opt_.keep_all || name == "output")
      trace_.stages.push_back({name, to_float_image(img), ms, skipped});
  }
  void store_image(BasicImage<T>& img) {
    store(img.view(), p_.storage, opt_.half_rounding, threads_);
  }
  // A mip level (down.k, up.k) as the chain stores it.
  void store_level(BasicImage<T>& img) {
    store(img.view(), p_.level_storage(), opt_.half_rounding, threads_);
  }
  // The ledger of a pool image (image.h), found by the buffer it was made for.
  detail::PageLedger* ledger_of(const BasicImage<T>& img) {
    for (detail::PageLedger& l : ledgers_)
      if (!img.empty() && l.of(img.data())) return &l;
    return nullptr;
  }

  // The gaussian method's bright image, unless stage bright runs inside the fused blur.
  bool makes_bright_image() const {
    if (p_.method == Method::mip) return p_.prefilter == Prefilter::bright;
    return sched_.blur != BlurPath::fused_from_bright && sched_.blur != BlurPath::boxed;
  }
  // Written by the input stage (extract_bright): whole, or when sparse only its bright pixels
  // into a zeroed image (its pages exist where written; nothing after it reads its alpha).
  void make_bright_image() {
    const int bw = makes_bright_image() ? w_ : 0, bh = makes_bright_image() ? h_ : 0;
    if (sched_.sparse_bright) {
      bright_ = take_zeroed<T>(bw, bh, ledgers_);
    } else {
      bright_ = BasicImage<T>::uninitialised(bw, bh);
      prefault_image(bright_, threads_);
    }
  }

  // Stage input: the scene after the non-finite policy; for the gaussian method the bright
  // image comes out of the same sweep, as the seeds' MRT pass writes both in one draw (bright
  // is decided on the sanitised value before either is stored).
  void input(const StageSpec& stage, Clock::time_point t0) {
    load_scene();
    // In place: each value is read once and written once at the same index.
    if (plan_.sanitize)
      trace_.nonfinite =
          sanitize(scene_.cview(), scene_.view(), p_.nonfinite, p_.storage, threads_);
    if (makes_bright_image()) extract_bright_image();
    store_image(scene_);
    record(stage.name, scene_, ms_since(t0), false);
  }

  void load_scene() {
    if constexpr (kF32) {
      if (owned_) {
        scene_ = std::move(*owned_);  // the caller handed the image over: no copy
        return;
      }
      // The caller's buffer for the output when it has the scene's size, else a new one.
      if (output_ && !output_->empty() && output_->width() == w_ && output_->height() == h_)
        scene_ = std::exchange(*output_, Image());
      else
        scene_ = BasicImage<T>::uninitialised(w_, h_);
      if (reads_scene_in_place()) return;  // scene_ receives the output only
      // Copied by every thread (the pages are faulted in by whichever thread writes them
      // first), with no zero fill before the copy.
      parallel_rows(h_, threads_, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
          std::copy(scene_in_.row(y), scene_in_.row(y) + std::size_t(w_) * kChannels,
                    scene_.view().row(y));
      });
    } else {
      scene_ = convert_image<T>(scene_in_);
    }
  }

  // Where nothing writes the scene before the finishing stages (no non-finite value to
  // sanitise, f32 storage, gaussian, the finish fused into one sweep) and the caller keeps it,
  // the stages read the caller's view and the finish writes the output into scene_: no copy
  // of the scene (one read and one write of every value fewer).
  bool reads_scene_in_place() const {
    return kF32 && !owned_ && !plan_.sanitize && p_.method == Method::gaussian &&
           sched_.finish == FinishPath::fused;
  }
  // The scene as the stages read it: the caller's view, or scene_.
  BasicView<const T> scene_source() const {
    if constexpr (kF32)
      if (reads_scene_in_place()) return scene_in_;
    return scene_.cview();
  }

  // The adaptive plan's first support comes out of the same sweep (the bright image's nonzero
  // texels): no second read of the bright image, most of whose pages are never written.
  void extract_bright_image() {
    std::vector<std::uint8_t> nonzero;
    const bool blurs =
        std::any_of(plan_.stages.begin(), plan_.stages.end(),
                    [](const StageSpec& s) { return s.kind == StageKind::blur && !s.skipped; });
    if (sched_.track_support && blurs) nonzero.resize(std::size_t(w_) * h_);
    // Into a zeroed image the rows without a bright pixel (the plan's scan found them) have
    // nothing to write and a zero support: not read at all.
    const std::uint8_t* rows =
        sched_.sparse_bright && plan_.facts.bright_rows.size() == std::size_t(h_)
            ? plan_.facts.bright_rows.data()
            : nullptr;
    extract_bright(scene_source(), bright_.view(), static_cast<T>(p_.threshold), threads_,
                   /*dst_zeroed=*/sched_.sparse_bright, nonzero.empty() ? nullptr : nonzero.data(),
                   rows, luma_rule(p_));
    if (!nonzero.empty()) support_.start(std::move(nonzero), threads_, rows);
  }

  // Stage bright: made by the input stage; here only stored.
  void bright(const StageSpec& stage) {
    if (sched_.blur == BlurPath::fused_from_bright || sched_.blur == BlurPath::boxed)
      return;  // in the fused or boxed blur, timed with it
    const auto t1 = Clock::now();
    store_image(bright_);
    record(stage.name, bright_, ms_since(t1), false);
  }

  // Stage blur.k: one pass, or (fused) this pass and the rest with the finishing stages.
  void blur(const StageSpec& stage, Clock::time_point t0) {
    if (finished_in_blur_) return;  // this pass ran inside the fused blur
    if constexpr (kF32)
      if (sched_.blur == BlurPath::boxed) return blur_boxed(t0);
    const BasicImage<T>& src = stage.pass == 1 ? bright_ : ping_;
    if (stage.skipped) {
      // Blur of an all-zero image is exactly zero: the bloom is `bright` itself.
      if (opt_.keep_all) record(stage.name, bright_, 0.0, true);
      return;
    }
    BlurPassOptions o{stage.axis, &kernel_for(p_.kernel), p_.subtexel_bits};
    FastPassOptions fo;
    if (sched_.track_support) follow_support(stage, o, fo);
    // Dense from here on (the full plan, or the adaptive plan once its support covers half the
    // image): the rest of the passes run fused.
    if (sched_.blur != BlurPath::staged && o.active == nullptr) {
      if constexpr (kF32) blur_rest_fused(stage, src, t0);
      return;
    }
    if (pong_.empty()) {
      if (sched_.zeroed_blur_target && stage.pass == 1) {
        pong_ = take_zeroed<T>(w_, h_, ledgers_);
      } else {
        pong_ = BasicImage<T>::uninitialised(w_, h_);
        prefault_image(pong_, threads_);  // written whole by this pass
      }
    }
    if (sched_.track_support) {
      fo.src_pages = ledger_of(src);
      fo.dst_pages = ledger_of(pong_);
      fo.page_threads = threads_;
    }
    blur_one_pass(src, o, fo);
    store_image(pong_);
    std::swap(ping_, pong_);
    // After the first pass the bright image is not read again: its buffer becomes the other
    // half of the ping-pong pair (three full-size images alive: scene, ping, pong).
    if (stage.pass == 1 && pong_.empty()) pong_ = std::move(bright_);
    record(stage.name, ping_, ms_since(t0), false);
  }

  // Blur only the bright pixels' support (started by the input stage), dilated pass by pass by
  // the taps' reach; every pass on all the run's threads.
  void follow_support(const StageSpec& stage, BlurPassOptions& o, FastPassOptions& fo) {
    o.active = support_.advance<T>(o, threads_);
    fo.active_spans = support_.spans();
    // Pass k > 1 writes the buffer pass k - 2 (pass 2: bright) left +0 outside a support
    // contained in this one (fast_stages.h); pass 1 a zeroed one, or a new one it fills.
    fo.dst_zero_outside = stage.pass != 1 || sched_.zeroed_blur_target;
    trace_.skipped_fraction.emplace_back(stage.name,
                                         1.0 - double(support_.count()) / (double(w_) * h_));
  }

  void blur_one_pass(const BasicImage<T>& src, const BlurPassOptions& o,
                     const FastPassOptions& fo) {
    if constexpr (kF32) {
      if (p_.blur == BlurImpl::fast)
        return blur_pass_fast(src.cview(), pong_.view(), o, threads_, BlurIsa::best, fo);
      if (p_.blur == BlurImpl::approx)
        return blur_pass_approx(src.cview(), pong_.view(), o, threads_);
    }
    blur_pass(src.cview(), pong_.view(), o, threads_);
  }

  // This pass and the rest at once, fused (the same bits as pass by pass, tested), with
  // composite, tone map and output on each block of the last pass while it is in cache, in
  // place into the scene (finish_fast_rows: finish_fast's bits, value by value): no bloom image
  // is allocated, written or read back. The adaptive plan stops tracking its support once
  // dense, so the rest are recorded as not skipping anything.
  void blur_rest_fused(const StageSpec& stage, const Image& src, Clock::time_point t0) {
    std::vector<Axis> axes;
    for (const StageSpec& s : plan_.stages)
      if (s.kind == StageKind::blur && s.pass >= stage.pass) {
        axes.push_back(s.axis);
        if (p_.plan == PlanMode::adaptive &&
            (s.pass > stage.pass || sched_.blur == BlurPath::fused_from_bright))
          trace_.skipped_fraction.emplace_back(s.name, 0.0);
      }
    std::string name = "blur." + std::to_string(stage.pass) + "-" +
                       std::to_string(stage.pass + int(axes.size()) - 1);
    BasicView<float> out = scene_.view();
    const BasicView<const float> scene = scene_source();
    const FusedBlurSink sink = [&](int x0, int x1, int y0, int y1, const float* const* rows) {
      std::vector<float*> dst(std::size_t(y1 - y0));
      std::vector<const float*> in(std::size_t(y1 - y0));
      for (int y = y0; y < y1; ++y) {
        dst[std::size_t(y - y0)] = out.row(y) + 4 * x0;
        in[std::size_t(y - y0)] = scene.row(y) + 4 * x0;
      }
      finish_fast_rows(in.data(), rows, dst.data(), y1 - y0, x1 - x0, p_.strength, p_.exposure,
                       p_.gamma);
    };
    if (sched_.blur == BlurPath::fused_from_bright) {
      blur_bright_fused(scene, static_cast<float>(p_.threshold), sink, axes,
                        kernel_for(p_.kernel), p_.subtexel_bits, threads_, BlurIsa::best, p_.blur);
      name = "bright+" + name;
    } else {
      blur_passes_fused(src.cview(), sink, axes, kernel_for(p_.kernel), p_.subtexel_bits, threads_,
                        BlurIsa::best, p_.blur);
    }
    pong_ = BasicImage<T>();
    bright_ = BasicImage<T>();  // not read again
    finished_in_blur_ = true;
    trace_.timings.emplace_back(name + "+composite+tonemap+output", ms_since(t0));
  }

  // Stages bright, blur.1 .. blur.n, composite, tonemap and output, box by box (engine/boxes.h):
  // each box's bloom finished in place as it comes (finish_fast_parts, with the last pass's
  // support), and the pixels outside every box, whose bloom is +0, by the same threads.
  void blur_boxed(Clock::time_point t0) {
    const int n = p_.passes;
    const BasicView<const float> scene = scene_source();
    const BasicView<float> out = scene_.view();
    const RowSpans& last = boxed_.layout.support(n);
    const float* tab = boxed_.table ? boxed_.table->data() : nullptr;
    std::atomic<std::size_t> from_table{0};
    const std::uint8_t* rows = plan_.facts.bright_rows.size() == std::size_t(h_)
                                   ? plan_.facts.bright_rows.data()
                                   : nullptr;
    // The pixels outside every box, in blocks of rows, taken by the threads after the boxes.
    const RowSpans rest = outside_boxes(boxed_.layout.boxes(), w_, h_);
    constexpr int kRestRows = 16;
    const auto finish_rest = [&](int block) {
      std::vector<FinishPart> parts;
      for (int y = block * kRestRows; y < std::min(h_, (block + 1) * kRestRows); ++y)
        for (const Span& s : rest[std::size_t(y)])
          parts.push_back({scene.pixel(s.x0, y), nullptr, nullptr, 0, out.pixel(s.x0, y),
                           s.x1 - s.x0});
      from_table += finish_fast_parts(parts.data(), parts.size(), p_.strength, p_.exposure,
                                      p_.gamma, tab);
    };
    boxed_.layout.run(
        scene, static_cast<float>(p_.threshold), rows,
        [&](const Box& b, const float* const* bloom) {
          const int bh = b.y1 - b.y0;
          std::vector<std::vector<Span>> spans(static_cast<std::size_t>(bh));
          std::vector<FinishPart> parts(static_cast<std::size_t>(bh));
          for (int i = 0; i < bh; ++i) {
            const int y = b.y0 + i;
            for (const Span& s : last[std::size_t(y)]) {
              const int x0 = std::max(s.x0, b.x0), x1 = std::min(s.x1, b.x1);
              if (x0 < x1) spans[std::size_t(i)].push_back({x0 - b.x0, x1 - b.x0});
            }
            parts[std::size_t(i)] = {scene.pixel(b.x0, y), bloom[i], spans[std::size_t(i)].data(),
                                     spans[std::size_t(i)].size(), out.pixel(b.x0, y),
                                     b.x1 - b.x0};
          }
          from_table += finish_fast_parts(parts.data(), parts.size(), p_.strength, p_.exposure,
                                          p_.gamma, tab);
        },
        threads_, BlurIsa::best, finish_rest, (h_ + kRestRows - 1) / kRestRows);
    const double pixels = double(w_) * double(h_);
    for (int k = 1; k <= n; ++k)
      trace_.skipped_fraction.emplace_back("blur." + std::to_string(k),
                                           1.0 - double(boxed_.layout.support_count(k)) / pixels);
    if (from_table)
      trace_.skipped_fraction.emplace_back("composite+tonemap+output", double(from_table) / pixels);
    finished_in_blur_ = true;
    trace_.timings.emplace_back("bright+blur.1-" + std::to_string(n) + "+composite+tonemap+output",
                                boxes_ms_ + ms_since(t0));
  }

  // Method mip. Adaptive plan: the texels of a chain stage that can be nonzero (mip_support),
  // from the nonzero texels of what it reads; null (compute all) under the full plan or once
  // they cover half the target. Records the skipped fraction. Up the chain the support only
  // grows (each level adds the tent's reach to the one below and its own down level's), so once
  // one up stage is dense the rest are computed whole untracked.
  const std::uint8_t* mip_mask(const std::string& name, const BasicImage<T>& src,
                               const BasicImage<T>& dst, int reach, const BasicImage<T>& also) {
    if (!sched_.track_support) return nullptr;
    const bool up_chain = reach == 1;
    if (up_chain && mip_up_dense_) {
      trace_.skipped_fraction.emplace_back(name, 0.0);
      return nullptr;
    }
    mip_src_mask_.resize(src.pixel_count());
    nonzero_support(src.cview(), mip_src_mask_.data(), threads_);
    if (!also.empty()) {
      mip_also_mask_.resize(also.pixel_count());
      nonzero_support(also.cview(), mip_also_mask_.data(), threads_);
    }
    mip_active_.resize(dst.pixel_count());
    const std::size_t n =
        mip_support<T>(mip_src_mask_.data(), src.width(), src.height(),
                       also.empty() ? nullptr : mip_also_mask_.data(), dst.width(), dst.height(),
                       reach, p_.subtexel_bits, mip_active_.data(), threads_);
    const bool dense = 2 * n > dst.pixel_count();
    mip_up_dense_ = up_chain && dense;
    trace_.skipped_fraction.emplace_back(name,
                                         dense ? 0.0 : 1.0 - double(n) / double(dst.pixel_count()));
    return dense ? nullptr : mip_active_.data();
  }

  // Stage down.k: the 13-tap downsample of the scene (k = 1, thresholded) or of down.k-1.
  void down(const StageSpec& stage, Clock::time_point t0) {
    const int k = stage.pass;
    const bool from_bright = p_.prefilter == Prefilter::bright;
    const BasicImage<T>& src = k > 1 ? down_[k - 1] : from_bright ? bright_ : scene_;
    BasicImage<T>& dst = down_[k];
    dst = BasicImage<T>(plan_.levels[k - 1].width, plan_.levels[k - 1].height);
    DownsampleOptions o = downsample_options(k);
    // The first level reads the whole scene; the others only where the level above has
    // anything (adaptive plan; seed 002's chain only: a variant's chain is computed whole).
    const bool tracked = !p_.mip_variant();
    if (tracked && k > 1) {
      o.active = mip_mask(stage.name, src, dst, 2, BasicImage<T>());
    } else if (tracked && sched_.track_support &&
               mip_nothing_bright(src.cview(), double(p_.threshold), threads_, luma_rule(p_))) {
      mip_active_.assign(dst.pixel_count(), 0);  // every tap thresholded to zero
      o.active = mip_active_.data();
      trace_.skipped_fraction.emplace_back(stage.name, 1.0);
    }
    downsample(src.cview(), dst.view(), o, threads_);
    store_level(dst);
    record(stage.name, dst, ms_since(t0), false);
  }

  DownsampleOptions downsample_options(int k) const {
    DownsampleOptions o = bloomref::downsample_options(p_, k, w_, h_, p_.subtexel_bits);
    o.rounding = opt_.half_rounding;
    return o;
  }

  // Stage up.k = down.k + tent3x3(up.k+1) (the smallest level: down.K itself), or as the
  // variant blends them (level_blend).
  void up(const StageSpec& stage, Clock::time_point t0) {
    const int k = stage.pass, top = static_cast<int>(plan_.levels.size());
    if (p_.level_combine == LevelCombine::sum) {
      std::vector<BasicView<const T>> levels;
      for (int i = 2; i <= top; ++i) levels.push_back(down_[i].cview());
      BasicImage<T>& dst = up_[1];
      dst = BasicImage<T>(down_[1].width(), down_[1].height());
      sum_levels(levels, dst.view(), p_.level_factors, p_.level_radius, p_.level_strength,
                 p_.subtexel_bits, threads_);
      store_level(dst);
      record(stage.name, dst, ms_since(t0), false);
      return;
    }
    const BasicImage<T>& small = k + 1 == top ? down_[top] : up_[k + 1];
    BasicImage<T>& dst = up_[k];
    dst = BasicImage<T>(down_[k].width(), down_[k].height());
    upsample_tent(small.cview(), down_[k].cview(), dst.view(), p_.subtexel_bits, threads_,
                  p_.mip_variant() ? nullptr : mip_mask(stage.name, small, dst, 1, down_[k]),
                  p_.upsample_radius, level_blend(p_, k, top),
                  p_.texel_step == TexelStep::target, p_.upsample);
    store_level(dst);
    record(stage.name, dst, ms_since(t0), false);
  }

  // Stage bloom (method mip): tent3x3(up.1) at full resolution.
  void mip_bloom(const StageSpec& stage, Clock::time_point t0) {
    const int top = static_cast<int>(plan_.levels.size());
    const BasicImage<T>& small = top == 1 ? down_[1] : up_[1];
    mip_bloom_ = BasicImage<T>(w_, h_);
    if (p_.bloom_upscale == BloomUpscale::bilinear)
      upscale_bilinear(small.cview(), mip_bloom_.view(), p_.subtexel_bits, threads_);
    else
      upsample_tent(small.cview(), BasicView<const T>{}, mip_bloom_.view(), p_.subtexel_bits,
                    threads_,
                    p_.mip_variant() ? nullptr
                                     : mip_mask(stage.name, small, mip_bloom_, 1, BasicImage<T>()),
                    p_.upsample_radius, LevelBlend{}, p_.texel_step == TexelStep::target);
    store_image(mip_bloom_);
    record(stage.name, mip_bloom_, ms_since(t0), false);
  }

  // What the composite adds: the mip chain's bloom, the last blur pass, or (no pass ran) bright.
  bool blurred() const {
    return p_.method == Method::gaussian && p_.passes > 0 && !plan_.stages[1 + p_.passes].skipped;
  }
  const BasicImage<T>& bloom_image() const {
    return p_.method == Method::mip ? mip_bloom_ : blurred() ? ping_ : bright_;
  }

  // Stage composite (with tonemap and output when fused).
  void composite_stage(const StageSpec& stage, Clock::time_point t0) {
    if (finished_in_blur_) return;  // in the fused blur's sink, timed with it
    const BasicImage<T>& bloom = bloom_image();
    if (sched_.finish == FinishPath::fused) {
      finish_fused(bloom);
    } else if (p_.method == Method::mip) {
      // before-tonemap: scene + strength * bloom; after-tonemap: mapped + strength * bloom.
      BasicImage<T>& base = p_.composite == CompositeOrder::after_tonemap ? mapped_ : scene_;
      BasicImage<T> out(w_, h_);
      composite_as(base, bloom, out);
      store_image(out);
      scene_ = std::move(out);
    } else {
      // In place into the scene (per value, same index).
      composite_as(scene_, bloom, scene_);
      store_image(scene_);
    }
    release_blur_images();
    if (sched_.finish == FinishPath::fused)
      trace_.timings.emplace_back("composite+tonemap+output", ms_since(t0));
    else
      record(stage.name, scene_, ms_since(t0), false);
  }

  void composite_as(const BasicImage<T>& base, const BasicImage<T>& bloom, BasicImage<T>& out) {
    const T s = static_cast<T>(p_.strength);
    if (p_.composite_mode == CompositeMode::mix)
      composite_mix(base.cview(), bloom.cview(), out.view(), s, threads_);
    else
      composite(base.cview(), bloom.cview(), out.view(), s, threads_);
  }

  // Composite, tonemap and output at once, in place into the scene (finish_fast: the three
  // stages' bits, tested). Under the adaptive plan the bloom's R, G and B are +0 outside the
  // last pass's support (or everywhere, when nothing was bright enough to blur): the composite
  // does not read it there (most of its pages were never written).
  void finish_fused(const BasicImage<T>& bloom) {
    const RowSpans* bloom_support = nullptr;
    RowSpans none;  // no spans on any row
    if (sched_.track_support && p_.method == Method::gaussian) {
      if (plan_.facts.bright_pixels == 0) {
        none.resize(std::size_t(h_));
        bloom_support = &none;
      } else if (blurred() && support_.started()) {
        bloom_support = support_.spans();  // null once dense
      }
    }
    if constexpr (kF32) {
      const std::size_t from_table =
          finish_fast(scene_source(), bloom.cview(), scene_.view(), p_.strength, p_.exposure,
                      p_.gamma, threads_, BlurIsa::best, bloom_support);
      if (from_table)  // finished from the table of binary16 values, not computed
        trace_.skipped_fraction.emplace_back("composite+tonemap+output",
                                             double(from_table) / (double(w_) * h_));
    }
    mip_bloom_ = BasicImage<T>();
  }

  // The bloom buffers go (empty under the mip method); those of a sparse adaptive blur back to
  // the pool, zeroed over the last support (which holds every texel a pass or the input stage
  // wrote nonzero: the supports only grow from the bright pixels).
  void release_blur_images() {
    if constexpr (kF32) {
      if (sched_.zeroed_blur_target && support_.started() && support_.spans())
        for (BasicImage<T>* img : {&ping_, &pong_, &bright_}) {
          detail::PageLedger* pages = ledger_of(*img);
          scratch_pool().give(std::move(*img), pages ? std::move(*pages) : detail::PageLedger(),
                              *support_.spans(), threads_);
        }
    }
    ping_ = BasicImage<T>();
    pong_ = BasicImage<T>();
    bright_ = BasicImage<T>();
  }

  void tonemap_as(const BasicImage<T>& src, BasicImage<T>& dst) {
    if constexpr (kF32)
      if (sched_.finish == FinishPath::fast)
        return tonemap_fast(src.cview(), dst.view(), p_.exposure, threads_);
    tonemap(src.cview(), dst.view(), static_cast<T>(p_.exposure), threads_);
  }

  // Stage tonemap: in place, or (mip, after-tonemap) into its own image, the bloom added after.
  void tonemap_stage(const StageSpec& stage, Clock::time_point t0) {
    if (sched_.finish == FinishPath::fused) return;  // done with the composite
    BasicImage<T>* dst = &scene_;
    if (p_.method == Method::mip && p_.composite == CompositeOrder::after_tonemap) {
      mapped_ = BasicImage<T>(w_, h_);
      dst = &mapped_;
    }
    tonemap_as(scene_, *dst);
    store_image(*dst);
    record(stage.name, *dst, ms_since(t0), false);
  }

  void encode_output_as(BasicImage<T>& img) {
    if constexpr (kF32)
      if (sched_.finish == FinishPath::fast)
        return encode_output_fast(img.cview(), img.view(), p_.gamma, threads_);
    encode_output(img.cview(), img.view(), static_cast<T>(p_.gamma), threads_);
  }

  // Stage output: gamma, in place; the buffer handed over to the trace where nothing is kept.
  void output(const StageSpec& stage, Clock::time_point t0) {
    if (sched_.finish == FinishPath::fused) {  // done with the composite
      if constexpr (kF32) {
        trace_.total_ms = ms_since(t_total_);
        trace_.stages.push_back({stage.name, std::move(scene_), 0.0, false});
      }
      return;
    }
    encode_output_as(scene_);
    store_image(scene_);
    // The stage's clock is read before the run's: the stages' times add up to at most the total.
    const double output_ms = ms_since(t0);
    trace_.total_ms = ms_since(t_total_);
    if constexpr (kF32) {
      if (!opt_.keep_all) {  // hand the buffer over instead of copying it
        trace_.timings.emplace_back(stage.name, output_ms);
        trace_.stages.push_back({stage.name, std::move(scene_), output_ms, false});
        return;
      }
    } else {
      trace_.output_f64 = scene_;
    }
    record(stage.name, scene_, output_ms, false);
  }

  const Clock::time_point t_total_ = Clock::now();  // first: the total covers every allocation
  const Plan& plan_;
  const BloomParams& p_;
  const ExecuteOptions& opt_;
  const Boxes boxed_;  // the adaptive plan's boxes (engine/boxes.h), where it blurs in boxes
  const double boxes_ms_;  // laying them out (the supports of every pass), timed with the blur
  const Schedule sched_;
  const ConstImageView scene_in_;
  Image* const owned_;
  Image* const output_;  // the caller's buffer for the output (execute's third overload), or null
  const int w_, h_, threads_;
  StageTrace trace_;
  BasicImage<T> scene_, bright_, ping_, pong_;  // ping_ and pong_ allocated by the first blur pass
  std::vector<detail::PageLedger> ledgers_;     // of the pool's images
  bool finished_in_blur_ = false;  // the remaining blur passes and the finishing stages ran fused
  // Adaptive plan: the blur's nonzero texels; whole passes once they cover half the image.
  BlurSupportTracker support_;
  // Method mip: level k of the down and up chains (index 0 unused), the full-size bloom, and
  // (after-tonemap) the tone-mapped scene.
  std::vector<BasicImage<T>> down_, up_;
  BasicImage<T> mip_bloom_, mapped_;
  std::vector<std::uint8_t> mip_src_mask_, mip_also_mask_, mip_active_;
  bool mip_up_dense_ = false;
  const float* const handed_;  // the buffer the caller handed over (owned_ or output_), or null
};

// The plan's scan of the scene is part of the run it was made for: its first timing, "plan", and
// part of the total.
StageTrace with_scan(const Plan& plan, StageTrace trace) {
  trace.timings.insert(trace.timings.begin(), {"plan", plan.facts.scan_ms});
  trace.total_ms += plan.facts.scan_ms;
  return trace;
}

}  // namespace

void release_scratch_images() { scratch_pool().clear(); }

bool output_in_given_buffer(const BloomParams& params, const ExecuteOptions& opt) {
  return params.precision == Precision::f32 && params.method == Method::gaussian &&
         !opt.keep_all;
}

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
                               ? Executor<double>(plan, scene, opt, nullptr).run()
                               : Executor<float>(plan, scene, opt, nullptr).run());
}

StageTrace execute(const Plan& plan, ConstImageView scene, Image&& output,
                   const ExecuteOptions& opt) {
  if (plan.params.precision == Precision::f64 || scene.width != plan.facts.width ||
      scene.height != plan.facts.height)
    return execute(plan, scene, opt);  // (f64 computes in its own buffers; reports a mismatch)
  return with_scan(plan, Executor<float>(plan, scene, opt, nullptr, &output).run());
}

StageTrace execute(const Plan& plan, Image&& scene, const ExecuteOptions& opt) {
  if (plan.params.precision == Precision::f64) return execute(plan, scene.cview(), opt);
  if (scene.width() != plan.facts.width || scene.height() != plan.facts.height)
    return execute(plan, scene.cview(), opt);  // reports the mismatch
  const ConstImageView view = scene.cview();
  return with_scan(plan, Executor<float>(plan, view, opt, &scene).run());
}

}  // namespace bloomref
