#include "bloomref/plan.h"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <type_traits>

#include "bloomref/error.h"
#include "bloomref/parallel.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "bloomref/engine/scan.h"

namespace bloomref {
namespace {

// How many values of a row are non-finite or beyond kRangeGuard (count_nonfinite_values), and
// how many pixels are bright (sanitised luminance > threshold, decided before storage, as the
// MRT pass does), in one scan. In f32 a row without such values is its own sanitised self: the
// instruction set's row kernel (scan_kernels.inc) reads it once, testing the values and
// counting the bright pixels in the same sweep, each luminance and comparison the scalar ones.
// Other rows (and every row in f64) take every value through the per-value functions the input
// stage applies.
template <class T>
void scan_row(const float* s, int width, const BloomParams& p, detail::ScanKernel kernel,
              NonFiniteCounts& c, std::uint64_t& bright) {
  if constexpr (std::is_same_v<T, float>)  // the row kernel tests the seeds' luminance
    if (p.seed_luma() && kernel(s, width, static_cast<float>(p.threshold), bright)) return;
  const T threshold = static_cast<T>(p.threshold);
  const LumaRule rule = luma_rule(p);
  const bool any = count_nonfinite_values(s, width * kChannels, c);
  for (int x = 0; x < width; ++x, s += kChannels) {
    T v[3];
    for (int k = 0; k < 3; ++k)
      v[k] = any ? sanitize_value(static_cast<T>(s[k]), p.nonfinite, p.storage)
                 : static_cast<T>(s[k]);
    bright += threshold_luminance(v[0], v[1], v[2], rule) > threshold;
  }
}

// The scene's facts in one parallel scan (scan_row per row).
template <class T>
void scan_rows(ConstImageView scene, const BloomParams& p, BlurIsa isa, SceneFacts& facts) {
  const detail::ScanKernel kernel = detail::scan_kernel_for(isa);
  std::mutex m;
  facts.bright_rows.assign(std::size_t(scene.height), 0);
  parallel_rows(scene.height, p.threads, [&](int y0, int y1) {
    NonFiniteCounts c;
    std::uint64_t bright = 0;
    for (int y = y0; y < y1; ++y) {
      const std::uint64_t before = bright;
      scan_row<T>(scene.row(y), scene.width, p, kernel, c, bright);
      facts.bright_rows[std::size_t(y)] = bright != before;
    }
    std::lock_guard<std::mutex> lock(m);
    facts.nonfinite += c;
    facts.bright_pixels += bright;
  });
}

std::string describe(const NonFiniteCounts& c) {
  return std::to_string(c.nan) + " NaN, " + std::to_string(c.pos_inf) + " +Inf and " +
         std::to_string(c.neg_inf) + " -Inf values";
}

}  // namespace

std::string bloom_stage_name(const Plan& plan) {
  if (plan.params.method == Method::mip) return "bloom";
  return plan.params.passes > 0 ? "blur." + std::to_string(plan.params.passes) : "bright";
}

std::vector<std::string> Plan::skipped_names() const {
  std::vector<std::string> out;
  if (!sanitize) out.push_back("input.sanitize");
  for (const StageSpec& s : stages)
    if (s.skipped) out.push_back(s.name);
  return out;
}

namespace {

std::vector<StageSpec> mip_stages(const BloomParams& p, std::size_t k) {
  std::vector<StageSpec> s = {{"input", StageKind::input}};
  if (p.prefilter == Prefilter::bright) s.push_back({"bright", StageKind::bright});
  for (std::size_t i = 1; i <= k; ++i) s.push_back({"down." + std::to_string(i), StageKind::down, int(i)});
  // LevelCombine::sum: one stage up.1 adds the blurred levels (down.2 .. down.K) at once.
  if (p.level_combine == LevelCombine::sum) s.push_back({"up.1", StageKind::up, 1});
  else
    for (std::size_t i = k; i-- > 1;) s.push_back({"up." + std::to_string(i), StageKind::up, int(i)});
  s.push_back({"bloom", StageKind::bloom});
  if (p.composite == CompositeOrder::after_tonemap)
    s.insert(s.end(), {{"tonemap", StageKind::tonemap}, {"composite", StageKind::composite}});
  else
    s.insert(s.end(), {{"composite", StageKind::composite}, {"tonemap", StageKind::tonemap}});
  s.push_back({"output", StageKind::output});
  return s;
}

}  // namespace

std::vector<std::string> stage_names(const BloomParams& p, int width, int height) {
  std::vector<std::string> names;
  if (p.method == Method::mip) {
    for (const StageSpec& s : mip_stages(p, chain_levels(p, width, height).size()))
      names.push_back(s.name);
    return names;
  }
  names = {"input", "bright"};
  for (int k = 1; k <= p.passes; ++k) names.push_back("blur." + std::to_string(k));
  names.insert(names.end(), {"composite", "tonemap", "output"});
  return names;
}

SceneFacts scan_scene(ConstImageView scene, const BloomParams& params, BlurIsa isa) {
  SceneFacts facts;
  facts.width = scene.width;
  facts.height = scene.height;
  const auto t0 = std::chrono::steady_clock::now();
  if (params.precision == Precision::f64) scan_rows<double>(scene, params, isa, facts);
  else scan_rows<float>(scene, params, isa, facts);
  facts.scan_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return facts;
}

bool dense_scene(const SceneFacts& facts) {
  const std::uint64_t pixels = std::uint64_t(facts.width) * std::uint64_t(facts.height);
  if (pixels == 0 || facts.bright_rows.size() != std::size_t(facts.height)) return false;
  const auto rows = std::uint64_t(
      std::count(facts.bright_rows.begin(), facts.bright_rows.end(), std::uint8_t(1)));
  return facts.bright_pixels * 10 >= pixels && rows * 2 >= std::uint64_t(facts.height);
}

bool small_scene(const SceneFacts& facts) {
  return std::uint64_t(facts.width) * std::uint64_t(facts.height) <= 256 * 256;
}

// At most this many pixels, a run whose thread count was left to bloomref (threads 0) runs on
// one thread: waking the workers costs more than they save (docs/design.md, "A small scene
// runs on one thread", has the measurements).
constexpr std::uint64_t kOneThreadPixels = 128 * 128;

Plan make_plan(const BloomParams& params, ConstImageView scene, const std::string& source) {
  validate(params);
  if (scene.empty()) throw InputError(source, "the image has no pixels");
  Plan plan;
  plan.params = params;
  const std::uint64_t pixels = std::uint64_t(scene.width) * std::uint64_t(scene.height);
  if (params.threads == 0 && pixels <= kOneThreadPixels) plan.params.threads = 1;
  plan.facts = scan_scene(scene, plan.params);
  if (params.nonfinite == NonFinite::error && plan.facts.nonfinite.total() > 0)
    throw InputError(source, "holds " + describe(plan.facts.nonfinite) +
                                 " and --nonfinite error refuses them (use zero, clamp or "
                                 "propagate)");

  const bool adaptive = params.plan == PlanMode::adaptive;
  if (params.method == Method::mip) {
    plan.sanitize = !adaptive || plan.facts.nonfinite.any();
    plan.levels = chain_levels(params, scene.width, scene.height);
    plan.stages = mip_stages(params, plan.levels.size());
    // GL clamps blend factors to [0, 1] where the target is fixed-point (GL 4.6, 17.3.6): an
    // 8-bit level blended with a constant outside it is not what the constant says.
    if (params.level_storage() == Storage::rgba8 &&
        (params.level_combine == LevelCombine::add || params.level_combine == LevelCombine::mix)) {
      const int top = static_cast<int>(plan.levels.size());
      for (int k = 1; k < top; ++k) {
        const float c = level_blend(params, k, top).weight;
        if (!(c >= 0.0f && c <= 1.0f))
          throw ParamError("--chain-storage rgba8: up." + std::to_string(k) +
                           "'s blend constant is " + std::to_string(c) +
                           ", and GL clamps the blend factors of an 8-bit target to [0, 1]; "
                           "store the levels as f16 or f32, or keep the constants within [0, 1]");
      }
    }
    return plan;
  }
  plan.sanitize = !adaptive || plan.facts.nonfinite.any();
  const bool skip_blur = adaptive && plan.facts.bright_pixels == 0;
  plan.dense_scene = adaptive && dense_scene(plan.facts);
  plan.small_scene = adaptive && small_scene(plan.facts);

  plan.stages.push_back({"input", StageKind::input});
  plan.stages.push_back({"bright", StageKind::bright});
  const bool first_horizontal = params.first_axis == FirstAxis::horizontal;
  for (int k = 1; k <= params.passes; ++k) {
    StageSpec s{"blur." + std::to_string(k), StageKind::blur, k,
                (k % 2 == 1) == first_horizontal ? Axis::horizontal : Axis::vertical, skip_blur};
    plan.stages.push_back(s);
  }
  plan.stages.push_back({"composite", StageKind::composite});
  plan.stages.push_back({"tonemap", StageKind::tonemap});
  plan.stages.push_back({"output", StageKind::output});
  return plan;
}

}  // namespace bloomref
