// Fault injection edits the shipped shader sources from outside (gpu/src/faults.cpp): every
// fault's anchors must be in the embedded sources exactly once, and a missing anchor must throw.
// Needs no GL context: only the embedded text is read.
#include <catch2/catch.hpp>
#include <set>
#include <stdexcept>

#include "bloomref/gpu/gl_executor.h"
#include "fault_patches.h"
#include "shader_sources.h"

using namespace bloomref;
using gpu::Fault;

namespace {
std::size_t occurrences(const std::string& text, const std::string& s) {
  std::size_t n = 0;
  for (std::size_t at = text.find(s); at != std::string::npos; at = text.find(s, at + 1)) ++n;
  return n;
}
}  // namespace

TEST_CASE("every fault's anchor is in the shipped shader sources exactly once", "[faults]") {
  const auto& sources = gpu::shader_sources();
  for (const gpu::FaultInfo& f : gpu::fault_list()) {
    for (const gpu::SourcePatch& p : gpu::fault_patches(f.fault)) {
      INFO(f.name << ": " << p.file << ": " << p.anchor);
      REQUIRE(sources.count(p.file) == 1);
      const std::string& text = sources.at(p.file);
      CHECK(occurrences(text, p.anchor) == 1);
      CHECK(p.replacement != p.anchor);
      // The patched file holds the replacement in place of the anchor.
      const std::string patched = gpu::apply_fault(f.fault, p.file, text);
      CHECK(occurrences(patched, p.replacement) == 1);
      CHECK(patched != text);
    }
  }
}

TEST_CASE("only the host-injected faults have no shader edit", "[faults]") {
  // GL state and allocation, not shader text: wrap mode, a pass not drawn, the texture format,
  // a level's size, the level an upsample binds.
  const std::set<Fault> host = {Fault::repeat_wrap, Fault::skip_pass, Fault::f16_storage,
                                Fault::level_size, Fault::level_offset};
  for (const gpu::FaultInfo& f : gpu::fault_list()) {
    INFO(f.name);
    CHECK(gpu::fault_patches(f.fault).empty() == (host.count(f.fault) == 1));
  }
  CHECK(gpu::fault_patches(Fault::none).empty());
}

TEST_CASE("the shipped shaders read as the effect only", "[faults]") {
  for (const auto& [file, text] : gpu::shader_sources()) {
    INFO(file);
    CHECK(text.find("FAULT") == std::string::npos);
  }
}

TEST_CASE("a fault's edit that finds no anchor throws, naming the fault and the anchor",
          "[faults]") {
  const std::string edited = "void run_stage(vec2 frag_coord) { emit0(vec4(0.0)); }\n";
  try {
    gpu::apply_fault(Fault::gamma_twice, "encode_output.glsl", edited);
    FAIL("no exception");
  } catch (const std::logic_error& e) {
    const std::string what = e.what();
    CHECK_THAT(what, Catch::Contains("gamma-twice"));
    CHECK_THAT(what, Catch::Contains("vec3 c = pow(max(m.rgb, vec3(0.0)), vec3(1.0 / gamma));"));
    CHECK_THAT(what, Catch::Contains("encode_output.glsl"));
  }
  // An anchor found twice is as ambiguous as one not found.
  const std::string twice = "vec3 x = -h.rgb * exposure;\nvec3 x = -h.rgb * exposure;\n";
  CHECK_THROWS_AS(gpu::apply_fault(Fault::exposure_ignored, "tonemap.glsl", twice),
                  std::logic_error);
  // Another file's text is left alone.
  CHECK(gpu::apply_fault(Fault::gamma_twice, "tonemap.glsl", edited) == edited);
}

TEST_CASE("the weight faults scale weight[1] of both blur kernels", "[faults]") {
  const std::string& blur = gpu::shader_sources().at("blur_pass.glsl");
  const std::string p = gpu::apply_fault(Fault::weight_0_1pct, "blur_pass.glsl", blur);
  CHECK(occurrences(p, "0.1945945946 * 1.001,") == 1);  // discrete9
  CHECK(occurrences(p, "0.3162162162 * 1.001,") == 1);  // linear5
}
