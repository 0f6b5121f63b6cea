// bloomref Vulkan — a headless compute device: the instance, the physical device chosen, a
// logical device with one compute queue, and what the device says of itself. No surface, no
// window. A machine without a Vulkan loader or device gets VulkanUnavailable (the CLI's exit 3).
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

namespace bloomref::vulkan {

/// No Vulkan instance or no device with a compute queue: the command exits 3, tests skip.
class VulkanUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A Vulkan call that failed on a device that exists: names the call and the VkResult.
class VulkanError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the device reports (vkGetPhysicalDeviceProperties2 and its Vulkan 1.2 chains): the
/// limits and float controls the precision model needs.
struct DeviceInfo {
  std::string name, type, driver_name, driver_info, api_version;
  std::uint32_t vendor_id = 0, device_id = 0;
  std::uint32_t sub_texel_precision_bits = 0, mipmap_precision_bits = 0;
  float timestamp_period_ns = 0;  ///< nanoseconds per timestamp tick
  bool timestamps_on_compute = false;  ///< timestampComputeAndGraphics
  std::uint32_t timestamp_valid_bits = 0;  ///< of the compute queue family
  std::uint32_t max_workgroup_invocations = 0, max_workgroup_size[3] = {0, 0, 0};
  /// SMs or compute units where an extension reports them (compute_units_from says which);
  /// 0 where none does (core Vulkan has no such count).
  std::uint32_t compute_units = 0;
  std::string compute_units_from = "not reported";
  // Float controls (VkPhysicalDeviceVulkan12Properties); "none" where the device is older.
  std::string denorm_behavior_independence, rounding_mode_independence;
  bool denorm_preserve_f16 = false, denorm_preserve_f32 = false;
  bool denorm_flush_f16 = false, denorm_flush_f32 = false;
  bool rounding_rte_f16 = false, rounding_rte_f32 = false;
  bool rounding_rtz_f16 = false, rounding_rtz_f32 = false;
  bool signed_zero_inf_nan_preserve_f32 = false;
  bool shader_float16 = false;  ///< VkPhysicalDeviceVulkan12Features::shaderFloat16
};

/// One compute device. Not copyable; the handles live as long as it does.
class Context {
 public:
  /// The first device of the best kind (discrete, integrated, virtual, CPU) with a compute
  /// queue, or the one whose name contains BLOOMREF_VULKAN_DEVICE when that is set. Throws
  /// VulkanUnavailable when there is none.
  static std::unique_ptr<Context> create();
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& info() const;

  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  Context();
  std::unique_ptr<Impl> impl_;
};

}  // namespace bloomref::vulkan
