#include "chain.h"

namespace bloomref::parity::detail {

std::vector<std::string> stage_inputs(const Plan& plan, const StageSpec& spec) {
  const BloomParams& p = plan.params;
  const bool after = p.method == Method::mip && p.composite == CompositeOrder::after_tonemap;
  const int top = static_cast<int>(plan.levels.size());
  auto level = [](const char* kind, int k) { return std::string(kind) + "." + std::to_string(k); };
  switch (spec.kind) {
    case StageKind::input:
    case StageKind::bright:
      return {};
    case StageKind::blur:
      return {spec.pass == 1 ? "bright" : level("blur", spec.pass - 1)};
    case StageKind::down:
      if (spec.pass > 1) return {level("down", spec.pass - 1)};
      return {p.prefilter == Prefilter::bright ? "bright" : "input"};
    case StageKind::up: {
      if (p.level_combine == LevelCombine::sum) {  // the blurred levels, in order
        std::vector<std::string> in;
        for (int k = 2; k <= top; ++k) in.push_back(level("down", k));
        return in;
      }
      return {spec.pass + 1 == top ? level("down", top) : level("up", spec.pass + 1),
              level("down", spec.pass)};
    }
    case StageKind::bloom:
      return {top == 1 ? level("down", 1) : "up.1"};
    case StageKind::composite:
      return {after ? "tonemap" : "input", bloom_stage_name(plan)};
    case StageKind::tonemap:
      return {after ? "input" : "composite"};
    case StageKind::output:
      return {after ? "composite" : "tonemap"};
  }
  return {};
}

const StageSpec* find_stage(const Plan& plan, const std::string& name) {
  for (const StageSpec& s : plan.stages)
    if (s.name == name) return &s;
  return nullptr;
}

}  // namespace bloomref::parity::detail
