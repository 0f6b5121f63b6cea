// bloomref gl-info [--json FILE] : the GL device and its measured facts.
#include <iostream>
#include <memory>

#include "bloomref/gpu/device_facts.h"
#include "escape.h"
#include "bloomref/io.h"
#include "commands.h"
#include "json_out.h"

namespace bloomref::cli {

std::function<int()> add_gl_info(CLI::App& app) {
  auto json_path = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand("gl-info", "the GL device and its measured precision facts");
  sub->add_option("--json", *json_path, "write the facts as JSON");
  return [json_path, sub]() -> int {
    if (!sub->parsed()) return -1;
    auto ctx = gpu::GlContext::create();
    const gpu::ContextInfo& i = ctx->info();
    const gpu::DeviceFacts f = gpu::measure_device_facts(*ctx);
    nlohmann::ordered_json j = {
        {"platform", i.platform}, {"device", i.device}, {"vendor", i.vendor},
        {"renderer", i.renderer}, {"version", i.version}, {"glsl", i.glsl_version},
        {"half_rounding", f.half_rounding}, {"half_of_65520", f.half_of_65520},
        {"half_of_70000", f.half_of_70000}, {"half_denormals_kept", f.half_denormals_kept},
        {"f32_denormals_kept", f.f32_denormals_kept},
        {"shader_denormals_kept", f.shader_denormals_kept},
        {"bilinear_distinct_of_1024", f.bilinear_distinct}, {"subtexel_bits", f.subtexel_bits},
        {"fma_contracted", f.fma_contracted},
        {"half_denormal_texels", f.half_denormal_texels},
        {"half_filter_denormals", f.half_filter_denormals},
        {"half_filter_normals", f.half_filter_normals}};
    std::cout << escape::json_text(j) << "\n";
    if (!json_path->empty()) save_text(*json_path, escape::json_text(j) + "\n");
    return 0;
  };
}

}  // namespace bloomref::cli
