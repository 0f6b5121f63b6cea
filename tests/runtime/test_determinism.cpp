// Bit-identical results for any thread count, and for the adaptive and full plans.
#include <catch2/catch.hpp>
#include <filesystem>
#include <tuple>

#include "bloomref/executor.h"
#include "bloomref/plan.h"
#include "bloomref/io.h"
#include "bloomref/scenes.h"
#include "test_util.h"

using namespace bloomref;

using test::run_output;

TEST_CASE("1, 2 and 8 threads give identical bits", "[determinism]") {
  std::vector<std::pair<std::string, Image>> scenes = {{"demo", make_scene("demo", 640, 360)}};
  for (const std::string& f : test::corpus_files())
    if (f.find("CandleGlass") != std::string::npos ||
        f.find("BrightRingsNanInf") != std::string::npos)
      scenes.emplace_back(f, load_image(f).image);
  for (const auto& [name, scene] : scenes) {
    for (auto [storage, precision] : {std::pair{Storage::f32, Precision::f32},
                                      {Storage::f16, Precision::f32},
                                      {Storage::f32, Precision::f64}}) {
      BloomParams p;
      p.storage = storage;
      p.precision = precision;
      p.nonfinite = NonFinite::propagate;  // NaN placement must not depend on threads either
      p.threads = 1;
      const Image one = run_output(scene, p);
      for (int t : {2, 8}) {
        p.threads = t;
        INFO(name << " storage " << to_string(storage) << " precision " << to_string(precision)
                  << " threads " << t);
        CHECK(test::bit_identical(one.cview(), run_output(scene, p).cview()));
      }
    }
  }
}

TEST_CASE("the adaptive plan gives the full plan's bits on scenes and corpus", "[determinism]") {
  const auto scenes = test::scenes_and_corpus();
  int skipped_something = 0, small_tracked = 0;
  for (const auto& [name, scene] : scenes) {
    BloomParams p;
    p.plan = PlanMode::full;
    const Image full = run_output(scene, p);
    p.plan = PlanMode::adaptive;
    Plan plan = make_plan(p, scene.cview());
    skipped_something += !plan.skipped_names().empty();
    INFO(name);
    CHECK(test::bit_identical(full.cview(), execute(plan, scene.cview()).final_image().cview()));
    // A small scene (Plan::small_scene) is blurred whole; its support tracked anyway, the same
    // bits.
    if (plan.small_scene) {
      plan.small_scene = false;
      ++small_tracked;
      CHECK(test::bit_identical(full.cview(), execute(plan, scene.cview()).final_image().cview()));
    }
  }
  CHECK(skipped_something > 0);  // the comparison is not vacuous
  CHECK(small_tracked > 0);       // nor is the small scenes' tracked one

  // A dense scene (Plan::dense_scene) is blurred as the full plan blurs it; tracked anyway, its
  // support goes dense part way through (the switch to whole fused passes): the same bits. The
  // scene: a bright band over the left 190 of 400 columns (47.5%, every row): the tracked
  // support covers 48.5% at pass 1 and passes half the image at pass 5.
  Image band(400, 240);
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 190; ++x) {
      float* px = band.view().pixel(x, y);
      px[0] = px[1] = px[2] = 2.0f + 0.01f * float((x * 7 + y * 3) % 13);
      px[3] = 1.0f;
    }
  {
    BloomParams p;
    p.plan = PlanMode::full;
    const Image full = run_output(band, p);
    p.plan = PlanMode::adaptive;
    Plan plan = make_plan(p, band.cview());
    CHECK(plan.dense_scene);
    CHECK(test::bit_identical(full.cview(), execute(plan, band.cview()).final_image().cview()));
    plan.dense_scene = false;
    const StageTrace tracked = execute(plan, band.cview());
    CHECK(test::bit_identical(full.cview(), tracked.final_image().cview()));
    REQUIRE(tracked.skipped_fraction.size() == 10u);
    CHECK(tracked.skipped_fraction.front().second > 0.0);  // pass 1 tracked
    CHECK(tracked.skipped_fraction.back().second == 0.0);  // the last ones whole
  }

  // NaN/Inf kept (propagate), f16 storage and f64: the texel-level skipping stays exact.
  for (const std::string& f : test::corpus_files()) {
    if (f.find("BrightRingsNanInf") == std::string::npos && f.find("AllHalfValues") == std::string::npos &&
        f.find("StarField") == std::string::npos)
      continue;
    const Image img = load_image(f).image;
    for (auto [policy, storage, precision] :
         {std::tuple{NonFinite::propagate, Storage::f32, Precision::f32},
          {NonFinite::zero, Storage::f16, Precision::f32},
          {NonFinite::zero, Storage::f32, Precision::f64}}) {
      BloomParams p;
      p.nonfinite = policy;
      p.storage = storage;
      p.precision = precision;
      p.plan = PlanMode::full;
      const Image full = run_output(img, p);
      p.plan = PlanMode::adaptive;
      INFO(f << " " << to_string(policy) << " " << to_string(storage) << " " << to_string(precision));
      CHECK(test::bit_identical(full.cview(), run_output(img, p).cview()));
    }
  }
}

TEST_CASE("the adaptive blur leaves out most texels of sparse scenes", "[determinism]") {
  // The demo's four lights cover ~0.6% of it; after 10 passes of +-5 texels the support is a
  // few percent, so at least 90% of every pass is left out.
  const Image demo = make_scene("demo", 640, 360);
  BloomParams p;
  const Plan plan = make_plan(p, demo.cview());
  const StageTrace t = execute(plan, demo.cview());
  REQUIRE(t.skipped_fraction.size() == 10u);
  for (const auto& [name, frac] : t.skipped_fraction) {
    INFO(name);
    CHECK(frac > 0.9);
  }
}

TEST_CASE("the adaptive plan's kept scratch images carry nothing from one run into the next",
          "[determinism]") {
  // Scenes of one size whose bright pixels sit in different places (and one with none, one
  // bright enough that the blur turns dense): each run of the adaptive plan, in an order where
  // it takes the scratch images the run before kept, gives the full plan's bits.
  const int w = 160, h = 120;
  auto spots = [&](std::vector<std::pair<int, int>> at, float value) {
    Image img(w, h, 0.1f);
    for (float* p = img.data(); p != img.data() + img.values().size(); p += 4) p[3] = 1.0f;
    for (auto [x, y] : at) {
      float* p = img.pixel(x, y);
      p[0] = value;
      p[1] = value * 0.5f;
      p[2] = -value * 0.01f;  // negative colour: -0 and negative texels in the bloom
    }
    return img;
  };
  std::vector<std::pair<std::string, Image>> scenes = {
      {"left", spots({{3, 4}, {20, 60}, {40, 110}}, 50.0f)},
      {"right", spots({{150, 10}, {130, 70}, {159, 119}}, 80.0f)},
      {"nothing bright", spots({}, 0.0f)},
      {"dense", Image(w, h, 3.0f)},
      {"middle", spots({{80, 60}}, 1e30f)},
  };
  for (int passes : {1, 2, 10}) {
    release_scratch_images();
    BloomParams p;
    p.passes = passes;
    p.threads = 2;
    std::vector<Image> full;
    p.plan = PlanMode::full;
    for (const auto& s : scenes) full.push_back(run_output(s.second, p));
    p.plan = PlanMode::adaptive;
    for (int round = 0; round < 2; ++round)
      for (std::size_t i = 0; i < scenes.size(); ++i) {
        // Second round backwards: each scene after a different one than in the first.
        const std::size_t k = round == 0 ? i : scenes.size() - 1 - i;
        INFO("passes " << passes << ", round " << round << ", " << scenes[k].first);
        CHECK(test::bit_identical(full[k].cview(), run_output(scenes[k].second, p).cview()));
      }
  }
  release_scratch_images();
}

// make_plan: a scene of at most 128 x 128 pixels whose thread count is left to bloomref runs on
// one thread; an explicit count is kept, and a larger scene keeps the default (0: all).
TEST_CASE("a small scene is planned on one thread unless the user chose a count", "[determinism]") {
  BloomParams p;
  p.threads = 0;
  const Image at_limit(128, 128, 0.5f), wide(16385, 1, 0.5f), tiny(256, 8, 0.5f);
  CHECK(make_plan(p, at_limit.cview()).params.threads == 1);
  CHECK(make_plan(p, tiny.cview()).params.threads == 1);
  CHECK(make_plan(p, wide.cview()).params.threads == 0);
  const Image over(129, 128, 0.5f);
  CHECK(make_plan(p, over.cview()).params.threads == 0);
  p.threads = 2;
  CHECK(make_plan(p, tiny.cview()).params.threads == 2);
  // The output is the same either way (every stage's bits are independent of the thread count).
  p.threads = 0;
  Image scene(64, 64, 0.0f);
  for (int y = 20; y < 30; ++y)
    for (int x = 10; x < 40; ++x) scene.pixel(x, y)[0] = 4.0f;
  BloomParams two = p;
  two.threads = 2;
  CHECK(test::same_bits_nan_agnostic(
      execute(make_plan(p, scene.cview()), scene.cview()).final_image().cview(),
      execute(make_plan(two, scene.cview()), scene.cview()).final_image().cview()));
}
