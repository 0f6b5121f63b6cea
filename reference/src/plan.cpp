#include "bloomref/plan.h"

#include <mutex>

#include "bloomref/error.h"
#include "bloomref/parallel.h"

namespace bloomref {
namespace {

// Pixels whose sanitised luminance is above the threshold (decided before storage, as the MRT
// pass does): the same per-value functions the input stage applies, in the plan's precision.
template <class T>
std::uint64_t count_bright(ConstImageView scene, const BloomParams& p) {
  std::uint64_t total = 0;
  std::mutex m;
  const T threshold = static_cast<T>(p.threshold);
  parallel_rows(scene.height, p.threads, [&](int y0, int y1) {
    std::uint64_t n = 0;
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < scene.width; ++x) {
        const float* s = scene.pixel(x, y);
        T v[3];
        for (int c = 0; c < 3; ++c)
          v[c] = sanitize_value(static_cast<T>(s[c]), p.nonfinite, p.storage);
        n += luminance(v[0], v[1], v[2]) > threshold;
      }
    }
    std::lock_guard<std::mutex> lock(m);
    total += n;
  });
  return total;
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
  for (std::size_t i = 1; i <= k; ++i) s.push_back({"down." + std::to_string(i), StageKind::down, int(i)});
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
    for (const StageSpec& s : mip_stages(p, mip_levels(width, height, p.levels).size()))
      names.push_back(s.name);
    return names;
  }
  names = {"input", "bright"};
  for (int k = 1; k <= p.passes; ++k) names.push_back("blur." + std::to_string(k));
  names.insert(names.end(), {"composite", "tonemap", "output"});
  return names;
}

Plan make_plan(const BloomParams& params, ConstImageView scene, const std::string& source) {
  validate(params);
  if (scene.empty()) throw InputError(source, "the image has no pixels");
  Plan plan;
  plan.params = params;
  plan.facts.width = scene.width;
  plan.facts.height = scene.height;
  plan.facts.nonfinite = count_nonfinite(scene, params.threads);
  if (params.nonfinite == NonFinite::error && plan.facts.nonfinite.total() > 0)
    throw InputError(source, "holds " + describe(plan.facts.nonfinite) +
                                 " and --nonfinite error refuses them (use zero, clamp or "
                                 "propagate)");
  plan.facts.bright_pixels = params.precision == Precision::f64
                                 ? count_bright<double>(scene, params)
                                 : count_bright<float>(scene, params);

  const bool adaptive = params.plan == PlanMode::adaptive;
  if (params.method == Method::mip) {
    plan.sanitize = !adaptive || plan.facts.nonfinite.any();
    plan.levels = mip_levels(scene.width, scene.height, params.levels);
    plan.stages = mip_stages(params, plan.levels.size());
    return plan;
  }
  plan.sanitize = !adaptive || plan.facts.nonfinite.any();
  const bool skip_blur = adaptive && plan.facts.bright_pixels == 0;

  plan.stages.push_back({"input", StageKind::input});
  plan.stages.push_back({"bright", StageKind::bright});
  for (int k = 1; k <= params.passes; ++k) {
    StageSpec s{"blur." + std::to_string(k), StageKind::blur, k,
                k % 2 == 1 ? Axis::horizontal : Axis::vertical, skip_blur};
    plan.stages.push_back(s);
  }
  plan.stages.push_back({"composite", StageKind::composite});
  plan.stages.push_back({"tonemap", StageKind::tonemap});
  plan.stages.push_back({"output", StageKind::output});
  return plan;
}

}  // namespace bloomref
