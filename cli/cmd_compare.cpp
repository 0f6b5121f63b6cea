// bloomref compare [IN] ... : the GL path judged stage by stage against the CPU oracle.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include "bloomref/error.h"
#include "escape.h"
#include "bloomref/executor.h"
#include "bloomref/gpu/gl_executor.h"
#include "bloomref/gpu/user_pipeline.h"
#include "bloomref/io.h"
#include "bloomref/output_files.h"
#include "bloomref/parity/compare.h"
#include "bloomref/scenes.h"
#include "bloomref/vulkan/executor.h"
#include "commands.h"
#include "json_out.h"
#include "options.h"
#include "report.h"

namespace bloomref::cli {
namespace {

struct CompareArgs {
  std::string input, report_dir, json_path, fault = "none", shaders = "fragment",
      profile = "auto", backend = "gl";
  bool quiet = false;
  PipelineOptions pipeline;
};

nlohmann::ordered_json stage_json(const parity::StageComparison& s) {
  nlohmann::ordered_json worst = nlohmann::ordered_json::array();
  for (const parity::WorstValue& w : s.worst) {
    nlohmann::ordered_json terms = nlohmann::ordered_json::object();
    for (const parity::Term& t : w.terms) terms[t.name] = t.value;
    worst.push_back({{"x", w.x}, {"y", w.y}, {"channel", std::string(1, "RGB"[w.channel])},
                     {"oracle", w.oracle}, {"gl", w.gl},
                     {"error", std::isfinite(w.error) ? nlohmann::ordered_json(w.error)
                                                      : nlohmann::ordered_json("non-finite")},
                     {"bound", w.bound}, {"terms", terms}});
  }
  return {{"verdict", parity::to_string(s.verdict)}, {"reason", s.reason},
          {"values", s.values}, {"over_bound", s.over_bound},
          {"nonfinite_mismatch", s.nonfinite_mismatch}, {"max_abs", s.max_abs},
          {"max_rel", s.max_rel}, {"max_f16_ulps", s.max_ulp16},
          {"max_error_over_bound", s.max_ratio}, {"ulp_histogram_minus8_to_plus8", s.ulp_histogram},
          {"worst", worst}};
}

// Prints the table and writes --json: the result of one backend's trace against the oracle.
int finish_compare(const CompareArgs& a, OutputSet& outs, const std::string& source,
                   const std::string& renderer, const Plan& plan, const StageTrace& trace,
                   const parity::DeviceProfile& profile, const parity::ParityResult& r,
                   double device_ms, double cpu_ms, double parity_ms) {
  if (!a.quiet) {
    std::printf("%s: %dx%d, %s, profile %s%s\n", source.c_str(), plan.facts.width,
                plan.facts.height, renderer.c_str(), profile.name.c_str(),
                a.fault == "none" ? "" : (", injected fault " + a.fault).c_str());
    std::printf("  %-10s %-8s %-12s %-12s %-8s %-12s\n", "stage", "isolated", "max |err|",
                "err/bound", "end2end", "err/bound");
    for (std::size_t i = 0; i < r.isolated.size(); ++i) {
      const auto& s = r.isolated[i];
      const auto& e = r.end_to_end[i];
      std::printf("  %-10s %-8s %-12.3g %-12.3g %-8s %-12.3g\n", s.stage.c_str(),
                  parity::to_string(s.verdict).c_str(), s.max_abs, s.max_ratio,
                  parity::to_string(e.verdict).c_str(), e.max_ratio);
    }
    std::printf("verdict %s; first divergent stage: %s\n", parity::to_string(r.verdict).c_str(),
                r.first_divergent_stage ? r.first_divergent_stage->c_str() : "none");
  }
  if (!a.json_path.empty()) {
    nlohmann::ordered_json j = run_json(plan, trace);
    j["renderer"] = renderer;
    j["profile"] = {{"name", profile.name}, {"source", profile.source},
                    {"subtexel_bits", profile.subtexel_bits},
                    {"half_nearest_even", profile.half_nearest_even},
                    {"half_toward_zero", profile.half_toward_zero},
                    {"half_overflow_inf", profile.half_overflow_inf},
                    {"half_overflow_saturate", profile.half_overflow_saturate},
                    {"flush_denormals", profile.flush_denormals}, {"fma", profile.fma},
                    {"division_ulps", profile.division_ulps}};
    j["fault"] = a.fault;
    j["compare_ms"] = {{a.backend + "_with_readbacks", device_ms}, {"cpu", cpu_ms}, {"parity", parity_ms - cpu_ms}};
    j["verdict"] = parity::to_string(r.verdict);
    j["first_divergent_stage"] = r.first_divergent_stage ? nlohmann::ordered_json(*r.first_divergent_stage)
                                                         : nlohmann::ordered_json(nullptr);
    nlohmann::ordered_json stages = nlohmann::ordered_json::array();
    for (std::size_t i = 0; i < r.isolated.size(); ++i)
      stages.push_back({{"stage", r.isolated[i].stage},
                        {"isolated", stage_json(r.isolated[i])},
                        {"end_to_end", stage_json(r.end_to_end[i])}});
    j["stages"] = stages;
    outs.write_text(a.json_path, escape::json_text(j) + "\n");
  }
  if (!a.report_dir.empty())
    write_report_files(outs.folder(a.report_dir), source, renderer, plan, trace, r, a.fault);
  outs.publish();
  if (!a.report_dir.empty() && !a.quiet)
    std::printf("report: %s/index.html\n", a.report_dir.c_str());
  return r.verdict == parity::Verdict::fail ? 1 : 0;
}

// compare --backend vulkan: bloomref's stage shaders through Vulkan compute, judged as GL's.
// The profile: on Mesa's software device, lavapipe's (llvmpipe's sampler and store code, its
// compute shaders keeping denormals: what vulkan-info measures); another device gets the
// fixed-point profile.
int compare_vulkan(const CompareArgs& a, OutputSet& outs, const LoadedImage& in,
                   const std::string& source) {
  if (a.shaders != "fragment") throw ParamError("--gl-shaders applies to the GL backend");
  const gpu::Fault fault = a.fault == "none" ? gpu::Fault::none : gpu::parse_fault(a.fault);
  if (fault != gpu::Fault::none && !gpu::fault_applies(fault, a.pipeline.params.method))
    throw ParamError("--inject-fault " + a.fault + " is not in --method " +
                     to_string(a.pipeline.params.method) + "'s shaders");
  auto ctx = vulkan::Context::create();  // VulkanUnavailable -> exit 3
  const bool software = ctx->info().type == "cpu";
  const parity::DeviceProfile profile =
      a.profile == "auto" ? (software ? parity::profile_lavapipe() : parity::profile_nvidia_like())
                          : parity::profile_named(a.profile);
  const Plan plan = parity::plan_for_device(a.pipeline.params, in.image.cview(), profile, source);
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  vulkan::SourceEdit edit;
  if (fault != gpu::Fault::none)
    edit = [fault](const std::string& file, std::string text) {
      return gpu::apply_fault(fault, file, std::move(text));
    };
  // The host's faults, injected by the Vulkan host as the GL host injects them.
  vulkan::HostFaults host;
  host.repeat_wrap = fault == gpu::Fault::repeat_wrap;
  host.skip_pass = fault == gpu::Fault::skip_pass;
  host.f16_storage = fault == gpu::Fault::f16_storage;
  host.level_size = fault == gpu::Fault::level_size;
  host.level_offset = fault == gpu::Fault::level_offset;
  // A mip-chain variant: its host code as a pipeline description (the GL hosts' textures,
  // passes and blending) around bloomref's shaders for it, each pass a compute shader; judged
  // as GL's variants are (the stages drawn, against the oracle run alongside).
  const bool variant = plan.params.mip_variant() || plan.params.composite_mode != CompositeMode::add;
  if (variant && fault != gpu::Fault::none)
    throw ParamError("--inject-fault applies to bloomref's own pipeline shaders; a mip-chain "
                     "variant runs its preset's passes");
  const StageTrace trace = vulkan::execute_vulkan(*ctx, plan, in.image.cview(), edit, host);
  const double device_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  parity::CompareOptions co;
  co.keep_images = !a.report_dir.empty();
  co.direct_exp_tonemap = variant;  // the variants' shaders compute the specification's series
  co.interpolated_reads = variant;  // and read the composite's inputs with texelFetch
  t0 = Clock::now();
  double cpu_ms = 0;
  parity::CapturedStages drawn;
  for (const StageResult& st : trace.stages) drawn[st.name] = parity::CapturedStage{st.image.cview()};
  const parity::ParityResult r =
      variant ? parity::check_with_oracle(plan, in.image.cview(), drawn, profile, co, &cpu_ms)
              : parity::compare_with_oracle(plan, in.image.cview(), trace, profile, co, &cpu_ms);
  const double parity_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const std::string renderer =
      std::string("vulkan (compute, ") +
      (variant ? "its preset's passes as compute shaders" : "bloomref's stage shaders") +
      "): " + ctx->info().name + ", " + ctx->info().driver_info;
  return finish_compare(a, outs, source, renderer, plan, trace, profile, r, device_ms, cpu_ms,
                        parity_ms);
}

int compare_cmd(CompareArgs& a) {
  const gpu::Fault fault = a.fault == "none" ? gpu::Fault::none : gpu::parse_fault(a.fault);
  const gpu::ShaderKind shaders = gpu::parse_shader_kind(a.shaders);
  // Destinations checked before the work; the JSON and the report published together.
  OutputSet outs;
  outs.protect(a.input);
  if (!a.json_path.empty()) outs.add_file(a.json_path, "--json");
  if (!a.report_dir.empty()) outs.add_folder(a.report_dir, "--report", /*whole=*/true);

  std::string source;
  const LoadedImage in = a.pipeline.load_input(a.input, source);
  if (a.backend == "vulkan") return compare_vulkan(a, outs, in, source);
  auto ctx = gpu::GlContext::create();  // GlUnavailable -> exit 3
  const parity::DeviceProfile profile =
      a.profile == "auto" ? (ctx->info().software ? parity::profile_llvmpipe()
                                                  : parity::profile_nvidia_like())
                          : parity::profile_named(a.profile);
  const Plan plan = parity::plan_for_device(a.pipeline.params, in.image.cview(), profile, source);

  gpu::GlOptions go;
  go.shaders = shaders;
  go.keep_all = true;
  go.fault = fault;
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  };
  auto t0 = Clock::now();
  // A mip-chain variant runs through the article's host code with bloomref's own shaders for
  // it (gpu/shaders/pbb_*.frag), whose final pass reads with texture() and calls exp, or
  // through Bevy's render graph with bloomref's GLSL of its passes (gpu/shaders/bevy_*.frag), or
  // Unity URP's SetupBloom with bloomref's GLSL of its passes (gpu/shaders/unity_*.frag).
  const bool variant = plan.params.mip_variant() || plan.params.composite_mode != CompositeMode::add;
  if (variant && (a.fault != "none" || shaders != gpu::ShaderKind::fragment))
    throw ParamError("--fault and --gl-shaders compute apply to bloomref's own pipeline shaders; "
                     "a mip-chain variant runs the article's fragment passes");
  const StageTrace gl = variant ? gpu::execute_gl_mip_chain(*ctx, plan.params, in.image.cview())
                                : gpu::execute_gl(*ctx, plan, in.image.cview(), go);
  const double gl_ms = ms(t0);
  parity::CompareOptions co;
  co.keep_images = !a.report_dir.empty();
  co.direct_exp_tonemap = variant;  // bloomref's shaders compute the specification's series
  co.interpolated_reads = variant;  // and read the composite's inputs with texelFetch
  t0 = Clock::now();
  double cpu_ms = 0;
  // The article's final pass draws composite, tone map and gamma at once: only `output` of them.
  parity::CapturedStages drawn;
  for (const StageResult& st : gl.stages) drawn[st.name] = parity::CapturedStage{st.image.cview()};
  const parity::ParityResult r =
      variant ? parity::check_with_oracle(plan, in.image.cview(), drawn, profile, co, &cpu_ms)
              : parity::compare_with_oracle(plan, in.image.cview(), gl, profile, co, &cpu_ms);
  const double parity_ms = ms(t0);  // includes the oracle run

  std::string host = gpu::to_string(shaders) + " shaders";
  if (variant)
    host = gpu::bevy_layout(plan.params)    ? "Bevy's render graph, bloomref's bevy shaders"
           : gpu::unity_layout(plan.params) ? "URP's SetupBloom, bloomref's unity shaders"
           : gpu::threejs_layout(plan.params) ? "three.js's layout, bloomref's threejs shaders"
                                            : "the article's host, bloomref's pbb shaders";
  const std::string renderer = "gl (" + host + "): " + ctx->info().renderer + ", " + ctx->info().version;
  return finish_compare(a, outs, source, renderer, plan, gl, profile, r, gl_ms, cpu_ms, parity_ms);
}

}  // namespace

std::function<int()> add_compare(CLI::App& app) {
  auto args = std::make_shared<CompareArgs>();
  CLI::App* sub = app.add_subcommand("compare", "judge the GL path stage by stage against the CPU");
  sub->add_option("IN", args->input, "input image; none = --scene");
  sub->add_option("--report", args->report_dir, "write images, tables and index.html to DIR");
  sub->add_option("--json", args->json_path, "write metrics, bounds and verdicts as JSON");
  std::string faults;
  for (const gpu::FaultInfo& f : gpu::fault_list()) faults += (faults.empty() ? "" : ", ") + f.name;
  sub->add_option("--inject-fault", args->fault, "a deliberate GL bug: none, " + faults)
      ->capture_default_str();
  sub->add_option("--gl-shaders", args->shaders, "fragment | compute")->capture_default_str();
  sub->add_option("--backend", args->backend,
                  "gl | vulkan (Vulkan compute with bloomref's stage shaders: gaussian and "
                  "seed 002's chain)")
      ->check(CLI::IsMember({"gl", "vulkan"}))
      ->capture_default_str();
  sub->add_option("--profile", args->profile, "auto | llvmpipe | nvidia (precision profile)")
      ->capture_default_str();
  sub->add_flag("-q,--quiet", args->quiet, "print nothing");
  args->pipeline.add_to(*sub);
  return [args, sub]() -> int {
    if (!sub->parsed()) return -1;
    args->pipeline.finish();
    args->pipeline.kept_traces = 3;  // GL's trace, the oracle's and the driver's textures
    args->pipeline.gl = true;
    return compare_cmd(*args);
  };
}

}  // namespace bloomref::cli
