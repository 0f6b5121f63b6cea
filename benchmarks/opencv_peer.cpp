// The peer benchmark: OpenCV's separable filter (sepFilter2D, BORDER_REPLICATE = clamp-to-edge,
// the discrete9 weights, 5 H+V applications = 10 passes) against bloomref's exact f32 blur, a
// naive loop, and the whole pipeline, on the same RGBA float image (the demo scene's bright
// pixels; 3840x2160, or `--size WxH`), 1 and 2 threads (OpenCV also split over both cores by
// hand: its own threading barely uses the second), medians of 5 after a warm-up (21 below
// 1 Mpx); the ratios are to OpenCV's best run.
// Every timed result is checked against the f64 truth in the same run (Halide's blur test does
// the same), exit 1 on a miss.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/kernel.h"
#include "bloomref/parallel.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/machine_ceiling.h"

using namespace bloomref;
using Clock = std::chrono::steady_clock;

namespace {

double median(std::vector<double> t) {
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// The median of `runs` values of f() after one warm-up call.
double median_of(int runs, const std::function<double()>& f) {
  f();  // warm-up
  std::vector<double> t;
  for (int i = 0; i < runs; ++i) t.push_back(f());
  return median(t);
}

double median_ms(int runs, const std::function<void()>& f) {
  return median_of(runs, [&] {
    const auto t0 = Clock::now();
    f();
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  });
}

// Largest |a - truth| over RGB, relative to the truth's largest value.
double rel_error(const float* a, const ImageF64& truth) {
  double peak = 0, diff = 0;
  for (std::size_t i = 0; i < truth.values().size(); ++i) {
    if (i % 4 == 3) continue;
    peak = std::max(peak, std::fabs(truth.values()[i]));
    diff = std::max(diff, std::fabs(a[i] - truth.values()[i]));
  }
  return diff / peak;
}

// The naive loop: integer taps, clamp-to-edge, one pass per call.
void naive_pass(const Image& src, Image& dst, bool horizontal, int threads) {
  const std::vector<float>& w = kernel_discrete9().weights_f32;
  parallel_rows(src.height(), threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < src.width(); ++x) {
        float r[3] = {0, 0, 0};
        for (int k = -4; k <= 4; ++k) {
          const int xx = horizontal ? std::clamp(x + k, 0, src.width() - 1) : x;
          const int yy = horizontal ? y : std::clamp(y + k, 0, src.height() - 1);
          const float* p = src.pixel(xx, yy);
          for (int c = 0; c < 3; ++c) r[c] += p[c] * w[std::abs(k)];
        }
        float* d = dst.pixel(x, y);
        d[0] = r[0]; d[1] = r[1]; d[2] = r[2]; d[3] = 1;
      }
  });
}

struct PeerArgs {
  std::string out_dir;
  int w = 3840, h = 2160;
};

// Parses the command line into `a`; returns 0, or the exit code 2 after printing why.
int parse_args(int argc, char** argv, PeerArgs& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--out" && i + 1 < argc) {
      a.out_dir = argv[++i];
    } else if (arg == "--size" && i + 1 < argc) {
      char x = 0, extra = 0;
      if (std::sscanf(argv[++i], "%d%c%d%c", &a.w, &x, &a.h, &extra) != 3 || x != 'x' ||
          a.w < 16 || a.h < 16 || a.w > 16384 || a.h > 16384) {
        std::fprintf(stderr, "opencv_peer: --size wants WxH (16 to 16384 each), got '%s'\n",
                     argv[i]);
        return 2;
      }
    } else {
      std::fprintf(stderr, "usage: opencv_peer [--size WxH] [--out DIR]   (default 3840x2160)\n");
      return 2;
    }
  }
  return 0;
}

bool same_bits(const Image& x, const Image& y) {
  return std::memcmp(x.data(), y.data(), x.values().size() * sizeof(float)) == 0;
}

// One benchmark run: the scene, its bright image and the f64 truth of its ten passes, the
// lines reported so far and whether every check held. One method per group of timings.
class Peer {
 public:
  static constexpr int kPasses = 10;

  Peer(int w, int h)
      : w_(w), h_(h),
        // Medians of 5 runs from 1 Mpx on; smaller images, whose runs take a few ms, of 21.
        runs_(std::size_t(w) * h >= (std::size_t(1) << 20) ? 5 : 21),
        scene_(make_scene("demo", w, h)), bright_(w, h), ping_(w, h), pong_(w, h) {
    std::printf("%dx%d RGBA float, %d passes, medians of %d runs after a warm-up\n", w, h,
                kPasses, runs_);
    extract_bright(scene_.cview(), bright_.view(), 1.0f, 0);
    // The truth: exact taps in double.
    truth_ = convert_image<double>(bright_.cview());
    ImageF64 tmp64(w, h);
    for (int p = 0; p < kPasses; ++p) {
      blur_pass(truth_.cview(), tmp64.view(), {axis(p), &kernel_discrete9(), 0}, 0);
      std::swap(truth_, tmp64);
    }
    for (int p = 0; p < kPasses; ++p) axes_.push_back(axis(p));
  }

  void opencv();
  void bloomref_blurs();
  void hardware_weights();
  void head_to_head();
  void pipeline();
  void summary();
  void write(const std::string& out_dir) const;
  bool ok() const { return ok_; }

 private:
  enum class Impl { reference, fast, approx };
  static Axis axis(int p) { return p % 2 == 0 ? Axis::horizontal : Axis::vertical; }

  void line(const std::string& l) {
    lines_.push_back(l);
    std::puts(l.c_str());
  }
  void report(const std::string& what, int threads, double ms, double err, double allowed) {
    const bool pass = err <= allowed;
    ok_ &= pass;
    char l[256];
    std::snprintf(l, sizeof l, "%-42s %dt %9.1f ms   error vs f64 %.2e (allowed %.0e) %s",
                  what.c_str(), threads, ms, err, allowed, pass ? "" : "FAIL");
    line(l);
  }
  bool check(bool same) {
    ok_ &= same;
    return same;
  }
  void cv_split();
  void ten_passes(Impl impl, int threads, int bits = 0);
  double time_fused(int bits, int threads, const std::string& name);

  int w_, h_, runs_;
  Image scene_, bright_, ping_, pong_, reference_out_;
  ImageF64 truth_;
  std::vector<Axis> axes_;  // H, V, H, ... as ten_passes
  cv::Mat src_, a_, b_, k_;
  std::vector<std::string> lines_;
  bool ok_ = true;
  double cv_best_ = 1e30, ours_best_ = 1e30, approx_best_ = 1e30, hw_best_ = 1e30;
  double pair_ratio_ = 0, pipe_[2] = {0, 0};
};

// OpenCV split over both cores by hand: each application, each thread filters one half of the
// rows as a ROI of the whole image.
void Peer::cv_split() {
  cv::setNumThreads(1);
  const int halves[3] = {0, h_ / 2, h_};
  src_.copyTo(a_);
  b_.create(h_, w_, CV_32FC4);
  for (int i = 0; i < kPasses / 2; ++i) {
    parallel_rows(2, 2, [&](int first, int last) {
      for (int part = first; part < last; ++part) {
        const cv::Rect rows(0, halves[part], w_, halves[part + 1] - halves[part]);
        cv::Mat out = b_(rows);
        cv::sepFilter2D(a_(rows), out, -1, k_, k_, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
      }
    });
    std::swap(a_, b_);
  }
}

// OpenCV: 5 x sepFilter2D (H and V in one call), on one and two threads, then split by hand.
void Peer::opencv() {
  src_ = cv::Mat(h_, w_, CV_32FC4, bright_.data());
  const std::vector<float>& wf = kernel_discrete9().weights_f32;
  k_ = cv::Mat(9, 1, CV_32F);
  for (int i = -4; i <= 4; ++i) k_.at<float>(i + 4) = wf[std::abs(i)];
  for (int threads : {1, 2}) {
    cv::setNumThreads(threads);
    const double ms = median_ms(runs_, [&] {
      src_.copyTo(a_);
      for (int i = 0; i < kPasses / 2; ++i) {
        cv::sepFilter2D(a_, b_, -1, k_, k_, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
        std::swap(a_, b_);
      }
    });
    cv_best_ = std::min(cv_best_, ms);
    report("OpenCV sepFilter2D x5", threads, ms, rel_error(a_.ptr<float>(), truth_), 1e-5);
  }
  // Split by hand (its own threading barely uses the second core here). Without
  // BORDER_ISOLATED, OpenCV reads the texels across the cut from the parent image and replicates
  // only at the image's own edges: the same arithmetic per texel, so the same bits as the single
  // call (checked).
  const cv::Mat whole = a_.clone();
  const double ms = median_ms(runs_, [&] { cv_split(); });
  const bool same = check(std::memcmp(whole.ptr<float>(), a_.ptr<float>(),
                                      std::size_t(w_) * h_ * 4 * sizeof(float)) == 0);
  cv_best_ = std::min(cv_best_, ms);
  report(same ? "OpenCV sepFilter2D x5, split by hand"
              : "OpenCV sepFilter2D x5, split by hand, DIFFERS from one call",
         2, ms, rel_error(a_.ptr<float>(), truth_), 1e-5);
}

void Peer::ten_passes(Impl impl, int threads, int bits) {
  const Image* s = &bright_;
  for (int p = 0; p < kPasses; ++p) {
    Image& d = p % 2 == 0 ? ping_ : pong_;
    const BlurPassOptions o{axis(p), &kernel_discrete9(), bits};
    if (impl == Impl::fast) blur_pass_fast(s->cview(), d.view(), o, threads);
    else if (impl == Impl::approx) blur_pass_approx(s->cview(), d.view(), o, threads);
    else blur_pass(s->cview(), d.view(), o, threads);
    s = &d;
  }
}

// All ten passes fused (blur_passes_fused: column strips through ring buffers) with `bits`
// subtexel weights, checked bit for bit against reference_out_; returns the median ms.
double Peer::time_fused(int bits, int threads, const std::string& name) {
  const double ms = median_ms(runs_, [&] {
    blur_passes_fused(bright_.cview(), ping_.view(), axes_, kernel_discrete9(), bits, threads);
  });
  const bool same = check(same_bits(reference_out_, ping_));
  report(same ? name : name + " DIFFERS from the reference", threads, ms,
         rel_error(ping_.data(), truth_), 1e-4);
  return ms;
}

// bloomref's exact f32 blur (GL sampling semantics): the fast path, checked bit for bit against
// the reference loop in this run; the approximate blur, pass by pass and fused (the two checked
// bit for bit against each other); and the naive loop.
void Peer::bloomref_blurs() {
  for (int threads : {1, 2}) {
    const double ref_ms = median_ms(runs_, [&] { ten_passes(Impl::reference, threads); });
    report("bloomref reference loop, 10 passes", threads, ref_ms, rel_error(pong_.data(), truth_),
           1e-4);
    reference_out_ = pong_;
    const double ms = median_ms(runs_, [&] { ten_passes(Impl::fast, threads); });
    ours_best_ = std::min(ours_best_, ms);
    const bool same = check(same_bits(reference_out_, pong_));
    report(same ? "bloomref exact f32 blur (fast), 10 passes"
                : "bloomref fast blur DIFFERS from the reference",
           threads, ms, rel_error(pong_.data(), truth_), 1e-4);
    ours_best_ =
        std::min(ours_best_, time_fused(0, threads, "bloomref exact f32 blur (fused), 10 passes"));
    const double approx_ms = median_ms(runs_, [&] { ten_passes(Impl::approx, threads); });
    report("bloomref approx blur (passes), 10 passes", threads, approx_ms,
           rel_error(pong_.data(), truth_), 1e-5);
    // The same passes fused (what `--blur approx` runs), checked bit for bit against them.
    const double approx_fused_ms = median_ms(runs_, [&] {
      blur_passes_fused(bright_.cview(), ping_.view(), axes_, kernel_discrete9(), 0, threads,
                        BlurIsa::best, BlurImpl::approx);
    });
    approx_best_ = std::min(approx_best_, approx_fused_ms);
    const bool approx_same = check(same_bits(pong_, ping_));
    report(approx_same ? "bloomref approx blur (fused), 10 passes"
                       : "bloomref approx blur (fused) DIFFERS from its passes",
           threads, approx_fused_ms, rel_error(ping_.data(), truth_), 1e-5);
    const double naive = median_ms(runs_, [&] {
      const Image* s = &bright_;
      for (int p = 0; p < kPasses; ++p) {
        Image& d = p % 2 == 0 ? ping_ : pong_;
        naive_pass(*s, d, p % 2 == 0, threads);
        s = &d;
      }
    });
    report("naive loop, 10 passes", threads, naive, rel_error(pong_.data(), truth_), 1e-5);
  }
}

// The same exact blur with 8-bit subtexel weights, as hardware filtering units round them
// (sampler.h; the default, float weights, is llvmpipe's). Every tap then sits on one texel, so
// no line needs the 2-D bilinear mix: checked bit for bit against the reference loop with the
// same weights in this run.
void Peer::hardware_weights() {
  ten_passes(Impl::reference, 2, 8);
  reference_out_ = pong_;
  for (int threads : {1, 2})
    hw_best_ = std::min(hw_best_,
                        time_fused(8, threads, "bloomref exact f32 blur, 8-bit weights (fused)"));
}

// Head to head: OpenCV's split run and the fused exact blur on two threads alternated, pair by
// pair, so that both see the same moments of a noisy machine (medians taken seconds apart can
// differ by a third there). The ratio quoted is the median of the pairs' ratios; the fused
// output is checked again.
void Peer::head_to_head() {
  ten_passes(Impl::reference, 2);
  reference_out_ = pong_;
  const int pairs = 2 * runs_ + 1;
  std::vector<double> cv_ms, ours_ms, ratio;
  for (int i = 0; i <= pairs; ++i) {  // the first pair is a warm-up
    const auto t0 = Clock::now();
    cv_split();
    const auto t1 = Clock::now();
    blur_passes_fused(bright_.cview(), ping_.view(), axes_, kernel_discrete9(), 0, 2);
    const auto t2 = Clock::now();
    if (i == 0) continue;
    cv_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    ours_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
    ratio.push_back(ours_ms.back() / cv_ms.back());
  }
  const bool same_out = check(same_bits(reference_out_, ping_));
  pair_ratio_ = median(ratio);
  char l[240];
  std::snprintf(l, sizeof l,
                "head to head, %d alternated pairs, 2t: OpenCV split %.1f ms, fused exact %.1f "
                "ms (medians); fused / OpenCV per pair: median %.2f, range %.2f-%.2f%s",
                pairs, median(cv_ms), median(ours_ms), pair_ratio_,
                *std::min_element(ratio.begin(), ratio.end()),
                *std::max_element(ratio.begin(), ratio.end()),
                same_out ? "" : " (fused DIFFERS from the reference)");
  line(l);
}

// The whole pipeline, full and adaptive plans, 2 threads; outputs must be identical.
void Peer::pipeline() {
  Image full_out, adaptive_out;
  for (PlanMode mode : {PlanMode::full, PlanMode::adaptive}) {
    BloomParams p;
    p.threads = 2;
    p.plan = mode;
    StageTrace t;
    // Each run gets its own copy of the scene, made outside the timer (as `bloomref run` hands
    // over the image it read); the time is the executor's own total, with its plan's scan of
    // the scene.
    const double ms = median_of(runs_, [&] {
      Image copy(scene_);
      t = execute(make_plan(p, scene_.cview()), std::move(copy));
      return t.total_ms;
    });
    (mode == PlanMode::full ? full_out : adaptive_out) = t.final_image();
    pipe_[mode == PlanMode::full ? 0 : 1] = ms;
    char l[200];
    std::snprintf(l, sizeof l, "%-42s 2t %9.1f ms",
                  (std::string("whole pipeline, ") + to_string(mode) + " plan").c_str(), ms);
    line(l);
  }
  const bool same = check(same_bits(full_out, adaptive_out));
  char l[420];
  std::snprintf(l, sizeof l,
                "ratios (same run): exact blur / OpenCV best = %.2f (target <= 0.7; head to "
                "head %.2f; with 8-bit weights %.2f), approximate blur (fused) / OpenCV best = %.2f; "
                "pipeline full / "
                "OpenCV blur = %.2f, adaptive / OpenCV blur = %.2f (target <= 1); adaptive plan %s",
                ours_best_ / cv_best_, pair_ratio_, hw_best_ / cv_best_, approx_best_ / cv_best_,
                pipe_[0] / cv_best_, pipe_[1] / cv_best_,
                same ? "bit-identical to full" : "DIFFERS from full");
  line(l);
}

// What two threads can give on this machine right now (machine_ceiling.h), beside the runs.
void Peer::summary() { line(describe(parallel_ceiling(2))); }

void Peer::write(const std::string& out_dir) const {
  if (out_dir.empty()) return;
  std::filesystem::create_directories(out_dir);
  const std::string size = std::to_string(w_) + "x" + std::to_string(h_);
  const std::string name = size == "3840x2160" ? "opencv_peer.txt" : "opencv_peer_" + size + ".txt";
  std::ofstream f(std::filesystem::path(out_dir) / name);
  for (const auto& l : lines_) f << l << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  PeerArgs args;
  if (const int rc = parse_args(argc, argv, args)) return rc;
  Peer peer(args.w, args.h);
  peer.opencv();
  peer.bloomref_blurs();
  peer.hardware_weights();
  peer.head_to_head();
  peer.pipeline();
  peer.summary();
  peer.write(args.out_dir);
  return peer.ok() ? 0 : 1;
}
