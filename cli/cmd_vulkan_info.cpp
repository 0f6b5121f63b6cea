// bloomref vulkan-info [--json FILE] : the Vulkan device, the limits it reports that the
// precision model needs, and the facts a compute probe measures on it.
#include <iostream>
#include <memory>

#include "bloomref/io.h"
#include "bloomref/vulkan/device_facts.h"
#include "commands.h"
#include "escape.h"

namespace bloomref::cli {

std::function<int()> add_vulkan_info(CLI::App& app) {
  auto json_path = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "vulkan-info", "the Vulkan device, its reported limits and its measured precision facts");
  sub->add_option("--json", *json_path, "write them as JSON");
  return [json_path, sub]() -> int {
    if (!sub->parsed()) return -1;
    auto ctx = vulkan::Context::create();  // VulkanUnavailable -> exit 3
    const vulkan::DeviceInfo& i = ctx->info();
    const vulkan::DeviceFacts f = vulkan::measure_device_facts(*ctx);
    nlohmann::ordered_json j = {
        {"api", "vulkan"}, {"device", i.name}, {"type", i.type}, {"driver", i.driver_name},
        {"driver_info", i.driver_info}, {"api_version", i.api_version},
        {"vendor_id", i.vendor_id}, {"device_id", i.device_id},
        {"reported",
         {{"sub_texel_precision_bits", i.sub_texel_precision_bits},
          {"mipmap_precision_bits", i.mipmap_precision_bits},
          {"timestamp_period_ns", i.timestamp_period_ns},
          {"timestamps_on_compute", i.timestamps_on_compute},
          {"timestamp_valid_bits", i.timestamp_valid_bits},
          {"max_workgroup_invocations", i.max_workgroup_invocations},
          {"compute_units", i.compute_units},
          {"compute_units_from", i.compute_units_from},
          {"max_workgroup_size",
           {i.max_workgroup_size[0], i.max_workgroup_size[1], i.max_workgroup_size[2]}},
          {"shader_float16", i.shader_float16},
          {"float_controls",
           {{"denorm_behavior_independence", i.denorm_behavior_independence},
            {"rounding_mode_independence", i.rounding_mode_independence},
            {"denorm_preserve_f16", i.denorm_preserve_f16},
            {"denorm_preserve_f32", i.denorm_preserve_f32},
            {"denorm_flush_f16", i.denorm_flush_f16},
            {"denorm_flush_f32", i.denorm_flush_f32},
            {"rounding_rte_f16", i.rounding_rte_f16},
            {"rounding_rte_f32", i.rounding_rte_f32},
            {"rounding_rtz_f16", i.rounding_rtz_f16},
            {"rounding_rtz_f32", i.rounding_rtz_f32},
            {"signed_zero_inf_nan_preserve_f32", i.signed_zero_inf_nan_preserve_f32}}}}},
        {"measured",
         {{"half_rounding", f.half_rounding}, {"half_of_65520", f.half_of_65520},
          {"half_of_70000", f.half_of_70000}, {"half_denormals_kept", f.half_denormals_kept},
          {"f32_denormals_kept", f.f32_denormals_kept},
          {"shader_denormals_kept", f.shader_denormals_kept},
          {"bilinear_distinct_of_1024", f.bilinear_distinct},
          {"subtexel_bits", f.subtexel_bits}, {"fma_contracted", f.fma_contracted}}}};
    std::cout << escape::json_text(j) << "\n";
    if (!json_path->empty()) save_text(*json_path, escape::json_text(j) + "\n");
    return 0;
  };
}

}  // namespace bloomref::cli
