// Every corpus image under every non-finite policy: it loads, it runs, and finite input never
// produces NaN in any stage.
#include <catch2/catch.hpp>
#include <filesystem>

#include "bloomref/error.h"
#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "test_util.h"

using namespace bloomref;

TEST_CASE("every corpus image runs under every non-finite policy", "[corpus][nonfinite]") {
  const auto files = test::corpus_files();
  if (files.empty()) WARN("BLOOMREF_CORPUS is not set: corpus policy checks skipped");
  for (const std::string& f : files) {
    const LoadedImage in = load_image(f);
    const std::string name = std::filesystem::path(f).filename().string();
    BloomParams probe;
    const bool finite = make_plan(probe, in.image.cview()).facts.nonfinite.total() == 0;
    for (NonFinite policy :
         {NonFinite::zero, NonFinite::clamp, NonFinite::propagate, NonFinite::error}) {
      BloomParams p;
      p.nonfinite = policy;
      INFO(name << " under " << to_string(policy));
      if (policy == NonFinite::error && !finite) {
        CHECK_THROWS_AS(make_plan(p, in.image.cview(), f), InputError);
        continue;
      }
      const Plan plan = make_plan(p, in.image.cview(), f);
      const StageTrace t = execute(plan, in.image.cview(), {true});
      CHECK(t.stages.size() == 15u);  // input, bright, blur.1..10, composite, tonemap, output
      const bool nan_expected = policy == NonFinite::propagate && !finite;
      std::size_t nans = 0;
      std::string first;
      for (const StageResult& s : t.stages) {
        const std::size_t n = test::count_nan(s.image.cview());
        if (n && first.empty()) first = s.name;
        nans += n;
      }
      INFO("first stage with NaN: " << first);
      if (!nan_expected) CHECK(nans == 0);
      if (nan_expected) CHECK(nans > 0);  // propagate keeps them: the policy is not a no-op
    }
  }
}
