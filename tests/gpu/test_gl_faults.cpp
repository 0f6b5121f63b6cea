// Parity is not vacuous: every injected GL fault FAILs and is charged to the stage it was
// injected in (the first divergent stage), on the demo scene and on three corpus images.
#include <Imath/half.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "bloomref/gpu/device_facts.h"
#include "bloomref/gpu/gl_executor.h"
#include "bloomref/io.h"
#include "bloomref/parity/compare.h"
#include "bloomref/scenes.h"
#include "test_util.h"
#include "gl_fixture.h"

using namespace bloomref;

namespace {

// True when every value is exactly a binary16 value (Imath's conversion).
bool half_exact(const Image& img) {
  for (float v : img.values())
    if (std::isfinite(v) && static_cast<float>(Imath::half(v)) != v) return false;
  return true;
}

// Where f16 storage first changes anything: the first stage of the f32 run whose values are not
// all binary16 values (storing them as half then changes them).
std::string first_not_half_exact(const Plan& plan, const Image& image) {
  const StageTrace t = execute(plan, image.cview(), {true});
  for (const StageResult& s : t.stages)
    if (!half_exact(s.image)) return s.name;
  return "none";
}

// The largest luminance in the image, as the shaders compute it: a threshold there makes a tie.
float max_luminance(const Image& img) {
  float m = -INFINITY;
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    const float* p = img.data() + i * 4;
    const float l = luminance(p[0], p[1], p[2]);
    if (std::isfinite(l)) m = std::max(m, l);
  }
  return m;
}


// Position of a stage in the plan (for "at or after").
int stage_index(const Plan& plan, const std::string& name) {
  for (std::size_t i = 0; i < plan.stages.size(); ++i)
    if (plan.stages[i].name == name) return static_cast<int>(i);
  return -1;
}

// Injects every fault of `method` on the demo and three corpus images (`corpus_names`) and checks
// each FAILs, charged to the stage it was injected in.
void check_fault_matrix(Method method, const std::vector<std::string>& corpus_names) {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  const parity::DeviceProfile profile =
      ctx->info().software ? parity::profile_llvmpipe() : parity::profile_nvidia_like();
  std::vector<std::pair<std::string, Image>> inputs = {{"demo", make_scene("demo")}};
  for (const std::string& f : test::corpus_files()) {
    const std::string n = std::filesystem::path(f).filename().string();
    if (std::find(corpus_names.begin(), corpus_names.end(), n) != corpus_names.end())
      inputs.emplace_back(n, load_image(f).image);
  }
  if (inputs.size() < 4) WARN("BLOOMREF_CORPUS is not set: faults checked on the demo only");
  for (const auto& [name, image] : inputs) {
    for (const gpu::FaultInfo& fault : gpu::fault_list()) {
      if (!gpu::fault_applies(fault.fault, method)) continue;
      BloomParams p;
      p.method = method;
      p.karis = method == Method::mip;  // karis-unnormalised needs it; the others do not mind
      p.exposure = 0.5f;                 // exposure-ignored must make a difference
      // threshold-ge needs a tie: the demo has a label at luminance exactly 1; elsewhere put the
      // threshold at the brightest pixel's luminance.
      if (fault.fault == gpu::Fault::threshold_ge && name != "demo") p.threshold = max_luminance(image);
      const Plan plan = parity::plan_for_device(p, image.cview(), profile, name);
      gpu::GlOptions go;
      go.keep_all = true;
      go.fault = fault.fault;
      const StageTrace gl = gpu::execute_gl(*ctx, plan, image.cview(), go);
      // As `compare` judges bloomref's own shaders: the specification's tone map, reads by
      // texelFetch (CompareOptions; cli/cmd_compare.cpp).
      parity::CompareOptions co;
      co.direct_exp_tonemap = false;
      co.interpolated_reads = false;
      const parity::ParityResult r = parity::compare_with_oracle(plan, image.cview(), gl, profile, co);
      std::string expected = fault.stage;
      if (fault.fault == gpu::Fault::f16_storage) expected = first_not_half_exact(plan, image);
      const std::string charged = r.first_divergent_stage.value_or("none");
      std::printf("%s fault %-19s on %-22s -> %s at %s\n", to_string(method).c_str(),
                  fault.name.c_str(), name.c_str(), parity::to_string(r.verdict).c_str(),
                  charged.c_str());
      INFO(fault.name << " on " << name);
      if (fault.fault == gpu::Fault::weight_0_01pct) {
        // Reported, not required: 0.01% is near the blur's derived bound (see the closing note).
        CHECK((charged == "none" || charged == expected));
        continue;
      }
      CHECK(r.verdict == parity::Verdict::fail);
      if (fault.fault == gpu::Fault::f16_storage) {
        // Injected at every stage: charged where a half rounding first exceeds its bound, at
        // or after the first stage whose values are not all halves (a loose coordinate bound
        // can cover one half ULP: GoldenGate's mip chain is charged at down.3).
        CHECK(stage_index(plan, charged) >= stage_index(plan, expected));
      } else {
        CHECK(charged == expected);
      }
      if (fault.fault == gpu::Fault::level_offset) {
        // A host-code bug no shader edit makes: named, with the levels it read.
        co.causes = true;
        const parity::ParityResult named = parity::compare_with_oracle(plan, image.cview(), gl, profile, co);
        for (const parity::StageComparison& s : named.isolated)
          if (s.stage == expected) {
            REQUIRE_FALSE(s.causes.empty());
            CHECK(s.causes.front().id == "mip-level-offset");
            CHECK(s.causes.front().likely());
            CHECK(s.causes.front().detail == "up.2 reads up.4 where up.3 is specified");
          }
      }
    }
  }
}

}  // namespace

TEST_CASE("every injected fault is caught and charged to its stage", "[gl][faults]") {
  check_fault_matrix(Method::gaussian,
                     {"hdr-rgb-riverwalk.hdr", "reference-crop.exr", "StageEnvLatLong.exr"});
}

TEST_CASE("every injected mip fault is caught and charged to its stage", "[gl][faults][mip]") {
  check_fault_matrix(Method::mip, {"hdr-rgb-riverwalk.hdr", "GoldenGate.exr", "StageEnvLatLong.exr"});
}

TEST_CASE("the measured llvmpipe facts are the llvmpipe profile's", "[gl][facts]") {
  gpu::GlContext* ctx = test::gl_context();
  if (!ctx) return;
  if (ctx->info().renderer.find("llvmpipe") == std::string::npos) {
    WARN("not llvmpipe (" << ctx->info().renderer << "): facts printed, profile not checked");
    return;
  }
  const gpu::DeviceFacts f = gpu::measure_device_facts(*ctx);
  const parity::DeviceProfile p = parity::profile_llvmpipe();
  CHECK(f.subtexel_bits == p.subtexel_bits);
  CHECK(f.bilinear_distinct == 1024);
  CHECK(f.half_rounding == (p.half_nearest_even ? "nearest-even" : "toward-zero"));
  CHECK((f.half_of_65520 == 65504.0f) == p.half_overflow_saturate);
  CHECK(f.shader_denormals_kept == !p.flush_denormals);
  // llvmpipe filters in float (its bilinear weights are floats): half denormals are read as
  // they are, and results between two halves stay between them.
  CHECK(f.half_denormal_texels == "kept");
  CHECK(f.half_filter_denormals == "float");
  CHECK(f.half_filter_normals == "float");
}

TEST_CASE("device facts: a sweep's samples classified", "[gl][facts]") {
  const float d = std::ldexp(1.0f, -24);
  CHECK(gpu::classify_equal({0x1p-20f, 0x1p-20f}, 0x1p-20f) == "kept");
  CHECK(gpu::classify_equal({0.0f, 0.0f}, 0x1p-20f) == "flushed");
  CHECK(gpu::classify_equal({0x1p-20f, 0.0f}, 0x1p-20f) == "other");
  CHECK(gpu::classify_between({0.0f, d / 2, d}, 0.0f, d) == "float");
  CHECK(gpu::classify_between({0.0f, 0.0f, d, d}, 0.0f, d) == "half");
  CHECK(gpu::classify_between({0.0f, 2 * d}, 0.0f, d) == "other");
}

TEST_CASE("bloomref compare exit codes: 0 pass, 1 fail, 2 bad usage, 3 no GL", "[gl][cli]") {
  const test::CliResult none =
      test::run_cli("compare -q --scene impulse", "BLOOMREF_EGL_DEVICE=no-such-device");
  CHECK(none.code == 3);
  CHECK_THAT(none.err, Catch::Contains("GL path unavailable"));
  CHECK(test::run_cli("compare -q --scene impulse --inject-fault bogus").code == 2);
  if (!test::gl_context()) return;
  CHECK(test::run_cli("compare -q --scene hot-edge").code == 0);
  CHECK(test::run_cli("compare -q --scene hot-edge --inject-fault gamma-twice").code == 1);
  CHECK(test::run_cli("compare -q --scene hot-edge --precision f64").code == 2);
}

TEST_CASE("bloomref stability: every hostile case's expectation holds on CPU and GL",
          "[gl][stability]") {
  if (!test::gl_context()) return;
  const test::CliResult r = test::run_cli("stability --json " +
                        (std::filesystem::temp_directory_path() / "bloomref_stability.json").string());
  CHECK(r.code == 0);
}
