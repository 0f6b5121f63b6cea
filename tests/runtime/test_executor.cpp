// The executor (executor.h): a run into a buffer handed over, and where the output then is.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/plan.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "test_util.h"

using namespace bloomref;

TEST_CASE("a run into a buffer of its own gives the bits of a run in the scene's buffer",
          "[stages]") {
  // Out of place the finishing stages stream their stores (finish_kernels.inc); in place they
  // store as usual. Odd widths leave every other row 16- but not 32-byte aligned; the second
  // run writes into the first's output buffer, as the Python module hands it back.
  for (const char* name : {"demo", "constant", "noise"})
    for (const int w : {257, 320}) {
      const Image scene = make_scene(name, w, 75);
      for (PlanMode mode : {PlanMode::full, PlanMode::adaptive}) {
        BloomParams p;
        p.plan = mode;
        const Plan plan = make_plan(p, scene.cview());
        const StageTrace own = execute(plan, Image(scene));
        StageTrace apart = execute(plan, scene.cview(), Image());
        INFO(name << " " << w << " " << to_string(mode));
        CHECK(test::bit_identical(own.final_image().cview(), apart.final_image().cview()));
        Image reused = std::move(apart.stages.back().image);
        const float* buffer = reused.data();
        const StageTrace again = execute(plan, scene.cview(), std::move(reused));
        CHECK(again.final_image().data() == buffer);
        CHECK(test::bit_identical(own.final_image().cview(), again.final_image().cview()));
      }
    }
}

TEST_CASE("output_in_given_buffer: the output is in the buffer handed over, wherever it says so",
          "[stages]") {
  // Every plan, blur, storage and method, a sparse and a dense scene, one with NaN (sanitised
  // in place first): where output_in_given_buffer is true, the output's buffer is the scene's
  // (taken over) or the output buffer's (given), and its bits are those of a run on a copy;
  // where it is false (mip, f64, kept stages) the run still gives those bits.
  Image nan_scene = make_scene("demo", 96, 64);
  nan_scene.data()[4 * (10 * 96 + 7)] = std::numeric_limits<float>::quiet_NaN();
  const std::vector<std::pair<const char*, Image>> scenes = {
      {"demo", make_scene("demo", 96, 64)}, {"constant", make_scene("constant", 96, 64)},
      {"nan", nan_scene}};
  int handed = 0;
  for (const auto& [name, scene] : scenes)
    for (Method method : {Method::gaussian, Method::mip})
      for (Precision precision : {Precision::f32, Precision::f64})
        for (PlanMode mode : {PlanMode::full, PlanMode::adaptive})
          for (BlurImpl blur : {BlurImpl::fast, BlurImpl::reference, BlurImpl::approx})
            for (Storage storage : {Storage::f32, Storage::f16})
              for (bool keep : {false, true}) {
                BloomParams p;
                p.method = method;
                p.precision = precision;
                p.plan = mode;
                p.blur = blur;
                p.storage = storage;
                ExecuteOptions eo;
                eo.keep_all = keep;
                const Plan plan = make_plan(p, scene.cview());
                const StageTrace copy = execute(plan, scene.cview(), eo);
                Image owned = scene;
                const float* scene_buffer = owned.data();
                const StageTrace in_place = execute(plan, std::move(owned), eo);
                Image out = Image::uninitialised(96, 64);
                const float* out_buffer = out.data();
                const StageTrace apart = execute(plan, scene.cview(), std::move(out), eo);
                INFO(name << " " << to_string(method) << " " << to_string(precision) << " "
                          << to_string(mode) << " " << to_string(blur) << " "
                          << to_string(storage) << " keep " << keep);
                CHECK(test::bit_identical(copy.final_image().cview(),
                                          in_place.final_image().cview()));
                CHECK(test::bit_identical(copy.final_image().cview(),
                                          apart.final_image().cview()));
                if (output_in_given_buffer(p, eo)) {
                  ++handed;
                  CHECK(in_place.final_image().data() == scene_buffer);
                  CHECK(apart.final_image().data() == out_buffer);
                }
              }
  CHECK(handed == 3 * 2 * 3 * 2);  // f32, gaussian, not kept: every scene, plan, blur, storage
}
