// Every hostile case's written expectation holds on the CPU runs (f64, f32, f16); the GL runs
// are checked by `bloomref stability` in the GL tests.
#include <catch2/catch.hpp>

#include "bloomref/error.h"
#include "bloomref/stability.h"

using namespace bloomref;

TEST_CASE("hostile cases meet their expectations on the CPU", "[stability]") {
  for (Method method : {Method::gaussian, Method::mip}) {
    for (const StabilityCase& c : stability_cases(method)) {
      const Image input = c.make();
      INFO(to_string(method) << " " << c.name << ": " << c.expectation);
      if (c.expects_refusal) {
        CHECK_THROWS_AS(make_plan(stability_params(c, method), input.cview(), c.name), InputError);
        continue;
      }
      std::vector<StabilityRun> runs;
      runs.push_back(run_stability_cpu(c, method, input, Precision::f64, Storage::f32));
      runs.push_back(run_stability_cpu(c, method, input, Precision::f32, Storage::f32));
      runs.push_back(run_stability_cpu(c, method, input, Precision::f32, Storage::f16));
      for (const Finding& f : c.check(input, runs)) {
        INFO(f.backend << ": " << f.detail);
        CHECK(f.ok);
      }
    }
  }
}
