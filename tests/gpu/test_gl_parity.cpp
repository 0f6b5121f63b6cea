// The GL path against the CPU oracle on llvmpipe (or whatever device EGL gives): every built-in
// scene and every corpus image, both kernels, both storages, fragment and compute shaders, must
// PASS at every stage, isolated and end to end.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "bloomref/gpu/gl_executor.h"
#include "bloomref/io.h"
#include "bloomref/parity/compare.h"
#include "bloomref/scenes.h"
#include "test_util.h"
#include "gl_fixture.h"

using namespace bloomref;

namespace {

parity::DeviceProfile device_profile(const gpu::GlContext& ctx) {
  return ctx.info().software ? parity::profile_llvmpipe() : parity::profile_nvidia_like();
}

void check_matrix_entry(gpu::ShaderKind shaders, Storage storage, KernelName kernel,
                        Method method = Method::gaussian, bool karis = false,
                        CompositeOrder order = CompositeOrder::before_tonemap) {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const parity::DeviceProfile profile = device_profile(*ctx);
  const auto inputs = test::scenes_and_corpus();
  if (test::corpus_files().empty()) WARN("BLOOMREF_CORPUS is not set: scenes only");
  for (const auto& [name, image] : inputs) {
    BloomParams p;
    p.storage = storage;
    p.kernel = kernel;
    p.method = method;
    p.karis = karis;
    p.composite = order;
    const Plan plan = parity::plan_for_device(p, image.cview(), profile, name);
    gpu::GlOptions go;
    go.shaders = shaders;
    go.keep_all = true;
    const StageTrace gl = gpu::execute_gl(*ctx, plan, image.cview(), go);
    const parity::ParityResult r = parity::compare_with_oracle(plan, image.cview(), gl, profile);
    double worst_iso = 0, worst_e2e = 0, worst_gain = 0;
    std::string worst_stage;
    for (std::size_t i = 0; i < r.isolated.size(); ++i) {
      const auto& s = r.isolated[i];
      const auto& e = r.end_to_end[i];
      INFO(name << " " << gpu::to_string(shaders) << " " << to_string(storage) << " "
                << to_string(kernel) << " stage " << s.stage << ": " << s.reason << " / "
                << e.reason);
      CHECK(s.verdict == parity::Verdict::pass);
      CHECK(e.verdict == parity::Verdict::pass);
      if (s.max_ratio > worst_iso) {
        worst_iso = s.max_ratio;
        worst_stage = s.stage;
      }
      worst_e2e = std::max(worst_e2e, e.max_ratio);
      worst_gain = std::max({worst_gain, s.gain_ratio, s.tile_gain_ratio, e.gain_ratio});
    }
    CHECK(!r.first_divergent_stage);
    std::printf("%-22s %-8s %-3s %-9s largest error/bound: isolated %.3f (%s), end-to-end %.3f; "
                "largest gain gate %.3g\n",
                name.c_str(), gpu::to_string(shaders).c_str(), to_string(storage).c_str(),
                method == Method::mip ? (karis ? "mip+karis" : "mip") : to_string(kernel).c_str(),
                worst_iso, worst_stage.c_str(), worst_e2e, worst_gain);
  }
}

}  // namespace

#define BLOOMREF_MATRIX(SH, ST, K)                                                          \
  TEST_CASE("GL parity: " #SH " " #ST " " #K " on scenes and corpus", "[gl][matrix]") {      \
    check_matrix_entry(gpu::ShaderKind::SH, Storage::ST, KernelName::K);                     \
  }
BLOOMREF_MATRIX(fragment, f32, discrete9)
BLOOMREF_MATRIX(fragment, f32, linear5)
BLOOMREF_MATRIX(fragment, f16, discrete9)
BLOOMREF_MATRIX(fragment, f16, linear5)
BLOOMREF_MATRIX(compute, f32, discrete9)
BLOOMREF_MATRIX(compute, f32, linear5)
BLOOMREF_MATRIX(compute, f16, discrete9)
BLOOMREF_MATRIX(compute, f16, linear5)

// Method mip (seed 003): both shader kinds, both storages, Karis on and off, both composite
// orders (seed 003's own: after the tone map, strength 0.02, exposure 0.5 is exercised by the
// composite order; strength does not change what is compared).
TEST_CASE("GL parity: mip fragment f32 on scenes and corpus", "[gl][matrix][mip]") {
  check_matrix_entry(gpu::ShaderKind::fragment, Storage::f32, KernelName::discrete9, Method::mip);
}
TEST_CASE("GL parity: mip compute f16 Karis after-tonemap on scenes and corpus",
          "[gl][matrix][mip]") {
  check_matrix_entry(gpu::ShaderKind::compute, Storage::f16, KernelName::discrete9, Method::mip,
                     true, CompositeOrder::after_tonemap);
}
TEST_CASE("GL parity: mip fragment f16 Karis on scenes and corpus", "[gl][matrix][mip]") {
  check_matrix_entry(gpu::ShaderKind::fragment, Storage::f16, KernelName::discrete9, Method::mip,
                     true);
}
TEST_CASE("GL parity: mip compute f32 after-tonemap on scenes and corpus", "[gl][matrix][mip]") {
  check_matrix_entry(gpu::ShaderKind::compute, Storage::f32, KernelName::discrete9, Method::mip,
                     false, CompositeOrder::after_tonemap);
}

TEST_CASE("GL: the adaptive plan's scissored draws and per-rectangle dispatches give the full "
          "plan's bits",
          "[gl][adaptive]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const auto inputs =
      test::scenes_and_corpus({{"demo 1920x1080", make_scene("demo", 1920, 1080)}});
  for (gpu::ShaderKind shaders : {gpu::ShaderKind::fragment, gpu::ShaderKind::compute}) {
    int scissored = 0;
    gpu::GlOptions go;
    go.shaders = shaders;
    go.keep_all = true;  // every pass compared, alpha included (the output takes the scene's)
    for (const auto& [name, image] : inputs) {
      for (Storage storage : {Storage::f32, Storage::f16}) {
        BloomParams p;
        p.storage = storage;
        p.nonfinite = NonFinite::propagate;
        p.plan = PlanMode::full;
        const StageTrace full = gpu::execute_gl(*ctx, make_plan(p, image.cview()), image.cview(), go);
        p.plan = PlanMode::adaptive;
        Plan plan = make_plan(p, image.cview());
        // A dense scene is drawn whole; scissored anyway (as before Plan::dense_scene), its
        // support goes dense part way through: the same bits both ways.
        for (bool dense : plan.dense_scene ? std::vector<bool>{true, false} : std::vector<bool>{false}) {
          plan.dense_scene = dense;
          const StageTrace t = gpu::execute_gl(*ctx, plan, image.cview(), go);
          int left_out = 0;
          for (const auto& [stage, frac] : t.skipped_fraction) left_out += frac > 0.0;
          scissored += left_out;
          INFO(name << " " << gpu::to_string(shaders) << " " << to_string(storage) << " dense "
                    << dense);
          if (dense) CHECK(left_out == 0);
          REQUIRE(full.stages.size() == t.stages.size());
          for (std::size_t i = 0; i < t.stages.size(); ++i) {
            INFO("stage " << t.stages[i].name);
            CHECK(test::same_bits_nan_agnostic(full.stages[i].image.cview(), t.stages[i].image.cview()));
          }
        }
      }
    }
    INFO(gpu::to_string(shaders));
    CHECK(scissored > 0);  // some passes were really left out
  }
}

TEST_CASE("GL mip: with nothing that can reach the threshold, the chain is cleared, not drawn, "
          "and the output keeps the full plan's bits",
          "[gl][adaptive][mip]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const Image demo = make_scene("demo", 320, 180);
  for (gpu::ShaderKind shaders : {gpu::ShaderKind::fragment, gpu::ShaderKind::compute}) {
    for (Storage storage : {Storage::f32, Storage::f16}) {
      for (float threshold : {1e30f, 1.0f}) {
        BloomParams p;
        p.method = Method::mip;
        p.storage = storage;
        p.threshold = threshold;
        gpu::GlOptions go;
        go.shaders = shaders;
        go.keep_all = true;
        p.plan = PlanMode::full;
        const StageTrace full = gpu::execute_gl(*ctx, make_plan(p, demo.cview()), demo.cview(), go);
        p.plan = PlanMode::adaptive;
        const Plan plan = make_plan(p, demo.cview());
        const StageTrace t = gpu::execute_gl(*ctx, plan, demo.cview(), go);
        INFO(gpu::to_string(shaders) << " " << to_string(storage) << " threshold " << threshold);
        CHECK(test::same_bits_nan_agnostic(full.final_image().cview(), t.final_image().cview()));
        const int chain = 2 * static_cast<int>(plan.levels.size());  // down.k, up.k, bloom
        if (threshold > 1e29f) {
          // The demo's brightest texels are far below 1e30: every chain stage left out, and
          // each stage image is exactly (0, 0, 0, 1) as the full plan's draw gives.
          CHECK(static_cast<int>(t.skipped_fraction.size()) == chain);
          for (const auto& [stage, frac] : t.skipped_fraction) CHECK(frac == 1.0);
          for (const StageResult& s : t.stages) {
            if (s.name.rfind("down.", 0) != 0 && s.name.rfind("up.", 0) != 0 && s.name != "bloom")
              continue;
            const StageResult* f = full.find(s.name);
            REQUIRE(f);
            CHECK(test::same_bits_nan_agnostic(f->image.cview(), s.image.cview()));
            for (std::size_t i = 0; i < s.image.values().size(); ++i)
              if (s.image.values()[i] != (i % 4 == 3 ? 1.0f : 0.0f)) {
                FAIL_CHECK(s.name << " value " << i << " is " << s.image.values()[i]);
                break;
              }
          }
        } else {
          CHECK(t.skipped_fraction.empty());  // the demo has texels above 1: the chain is drawn
        }
      }
    }
  }
}
