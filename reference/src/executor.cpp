#include "bloomref/executor.h"

#include <algorithm>
#include <chrono>
#include <type_traits>

#include "bloomref/error.h"

namespace bloomref {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

Image to_float_image(const Image& img) { return img; }
Image to_float_image(const ImageF64& img) { return convert_image<float>(img.cview()); }

// Runs the plan in precision T. The scene, bright image and the latest blur result are the only
// full-size images alive at once (plus the kept intermediates when asked).
template <class T>
StageTrace run(const Plan& plan, ConstImageView scene_in, const ExecuteOptions& opt) {
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
  BasicImage<T> bright(w, h);
  BasicImage<T> ping(w, h), pong;

  for (const StageSpec& stage : plan.stages) {
    const auto t0 = Clock::now();
    switch (stage.kind) {
      case StageKind::input: {
        BasicImage<T> raw;
        if constexpr (std::is_same_v<T, float>) {
          raw = BasicImage<T>(w, h);
          for (int y = 0; y < h; ++y)
            std::copy(scene_in.row(y), scene_in.row(y) + std::size_t(w) * kChannels,
                      raw.view().row(y));
        } else {
          raw = convert_image<T>(scene_in);
        }
        if (plan.sanitize) {
          scene = BasicImage<T>(w, h);
          trace.nonfinite = sanitize(raw.cview(), scene.view(), p.nonfinite, p.storage, threads);
        } else {
          scene = std::move(raw);
        }
        // The seeds' MRT pass writes the scene and the bright colour in one draw: bright is
        // decided on the sanitised value before either is stored (rounded to f16).
        extract_bright(scene.cview(), bright.view(), static_cast<T>(p.threshold), threads);
        store(scene.view(), p.storage, rounding, threads);
        record(stage.name, scene, ms_since(t0), false);
        break;
      }
      case StageKind::bright: {
        const auto t1 = Clock::now();
        store(bright.view(), p.storage, rounding, threads);
        record(stage.name, bright, ms_since(t1), false);
        break;
      }
      case StageKind::blur: {
        const BasicImage<T>& src = stage.pass == 1 ? bright : ping;
        if (stage.skipped) {
          // Blur of an all-zero image is exactly zero: the bloom is `bright` itself.
          if (opt.keep_all) record(stage.name, bright, 0.0, true);
          break;
        }
        if (pong.empty()) pong = BasicImage<T>(w, h);
        BlurPassOptions o{stage.axis, &kernel_for(p.kernel), p.subtexel_bits};
        blur_pass(src.cview(), pong.view(), o, threads);
        store(pong.view(), p.storage, rounding, threads);
        std::swap(ping, pong);
        record(stage.name, ping, ms_since(t0), false);
        break;
      }
      case StageKind::composite: {
        const bool blurred = p.passes > 0 && !plan.stages[1 + p.passes].skipped;
        const BasicImage<T>& bloom = blurred ? ping : bright;
        BasicImage<T>& out = blurred ? pong : ping;  // a free full-size buffer
        if (out.empty()) out = BasicImage<T>(w, h);
        composite(scene.cview(), bloom.cview(), out.view(), static_cast<T>(p.strength), threads);
        store(out.view(), p.storage, rounding, threads);
        scene = std::move(out);  // the scene is not needed again; keep three buffers at most
        out = BasicImage<T>();
        bright = BasicImage<T>();
        record(stage.name, scene, ms_since(t0), false);
        break;
      }
      case StageKind::tonemap:
        tonemap(scene.cview(), scene.view(), static_cast<T>(p.exposure), threads);
        store(scene.view(), p.storage, rounding, threads);
        record(stage.name, scene, ms_since(t0), false);
        break;
      case StageKind::output:
        encode_output(scene.cview(), scene.view(), static_cast<T>(p.gamma), threads);
        store(scene.view(), p.storage, rounding, threads);
        trace.total_ms = ms_since(t_total);
        record(stage.name, scene, ms_since(t0), false);
        if constexpr (std::is_same_v<T, double>) trace.output_f64 = scene;
        break;
    }
  }
  return trace;
}

}  // namespace

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
  return plan.params.precision == Precision::f64 ? run<double>(plan, scene, opt)
                                                 : run<float>(plan, scene, opt);
}

}  // namespace bloomref
