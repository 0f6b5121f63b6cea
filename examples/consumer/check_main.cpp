// Judges a bloom's stage images in memory with the installed check library (bloomref::check,
// "check/check.h"): the stages a run of the pipeline kept pass; the same stages with the
// composite 10% too bright fail, first at the composite. Nothing is written to disk.
//
// The scene is the one examples/consumer/main.cpp blooms: 64x32 at 0.25 with one pixel of 8.
#include <cstdio>
#include <deque>
#include <exception>
#include <string>
#include <vector>

#include "bloomref/error.h"
#include "bloomref/executor.h"
#include "check/check.h"

namespace {

// Judges `trace`'s stages against the pipeline's defaults: the run's verdict and the first
// stage that diverged ("" when none did).
bloomref::cli::CheckRun judge(const bloomref::ConstImageView& scene,
                              const bloomref::StageTrace& trace) {
  std::deque<bloomref::ConstImageView> views;  // the request points at these
  std::vector<bloomref::cli::StageFile> files;
  for (const bloomref::StageResult& s : trace.stages) {
    views.push_back(s.image.cview());
    bloomref::cli::StageFile f;
    f.stage = s.name;
    f.path = s.name + " (memory)";
    f.image = &views.back();
    files.push_back(f);
  }
  bloomref::cli::CheckRequest request;
  request.scene = "consumer scene";
  request.scene_image = &scene;
  request.stages = files;
  return bloomref::cli::check(request);
}

std::string first_divergent(const bloomref::cli::CheckRun& run) {
  if (run.items.empty() || !run.items[0].parity.first_divergent_stage) return "";
  return *run.items[0].parity.first_divergent_stage;
}

}  // namespace

int main() {
  try {
    bloomref::Image scene(64, 32, 0.25f);
    for (int c = 0; c < 3; ++c) scene.pixel(48, 24)[c] = 8.0f;
    for (int y = 0; y < scene.height(); ++y)
      for (int x = 0; x < scene.width(); ++x) scene.pixel(x, y)[3] = 1.0f;

    bloomref::BloomParams params;  // the seeds' defaults, every stage computed
    params.plan = bloomref::PlanMode::full;
    const bloomref::Plan plan = bloomref::make_plan(params, scene.cview(), "consumer scene");
    bloomref::ExecuteOptions keep;
    keep.keep_all = true;
    bloomref::StageTrace trace = bloomref::execute(plan, scene.cview(), keep);

    int failures = 0;
    const bloomref::cli::CheckRun clean = judge(scene.cview(), trace);
    if (clean.verdict != "PASS") {
      std::fprintf(stderr, "the pipeline's own stages: %s, expected PASS\n", clean.verdict.c_str());
      ++failures;
    }
    for (bloomref::StageResult& s : trace.stages)
      if (s.name == "composite")
        for (float& v : s.image.values()) v *= 1.1f;
    const bloomref::cli::CheckRun planted = judge(scene.cview(), trace);
    if (planted.verdict != "FAIL" || first_divergent(planted) != "composite") {
      std::fprintf(stderr, "the composite 10%% too bright: %s first at '%s', expected FAIL at composite\n",
                   planted.verdict.c_str(), first_divergent(planted).c_str());
      ++failures;
    }
    std::printf("bloomref check consumer: %zu stages in memory %s; the composite 10%% too bright %s at %s: %s\n",
                trace.stages.size(), clean.verdict.c_str(), planted.verdict.c_str(),
                first_divergent(planted).c_str(), failures ? "FAIL" : "ok");
    return failures ? 1 : 0;
  } catch (const bloomref::Error& e) {
    std::fprintf(stderr, "bloomref check consumer: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bloomref check consumer: internal error: %s\n", e.what());
    return 4;
  }
}
