#include "bloomref/vulkan/context.h"

#include <cstdlib>
#include <string>
#include <vector>

#include "vk_objects.h"

namespace bloomref::vulkan {
namespace {

std::string result_name(VkResult r) {
  switch (r) {
    case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_FORMAT_NOT_SUPPORTED: return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    case VK_TIMEOUT: return "VK_TIMEOUT";
    default: return "VkResult " + std::to_string(int(r));
  }
}

std::string type_name(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
  }
}

// Lower is preferred: a GPU before a CPU implementation.
int rank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 3;
    default: return 4;
  }
}

std::string independence(VkShaderFloatControlsIndependence i) {
  switch (i) {
    case VK_SHADER_FLOAT_CONTROLS_INDEPENDENCE_32_BIT_ONLY: return "32-bit-only";
    case VK_SHADER_FLOAT_CONTROLS_INDEPENDENCE_ALL: return "all";
    default: return "none";
  }
}

std::string version(std::uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) +
         "." + std::to_string(VK_API_VERSION_PATCH(v));
}

// The compute queue family of `d`, or -1.
int compute_family(VkPhysicalDevice d, std::uint32_t* timestamp_bits) {
  std::uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(d, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  vkGetPhysicalDeviceQueueFamilyProperties(d, &n, families.data());
  for (std::uint32_t i = 0; i < n; ++i)
    if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
      if (timestamp_bits) *timestamp_bits = families[i].timestampValidBits;
      return int(i);
    }
  return -1;
}

// The device's SMs or compute units, where an extension reports them: NVIDIA's
// VK_NV_shader_sm_builtins (shaderSMCount), AMD's VK_AMD_shader_core_properties (engines x arrays
// per engine x compute units per array). Core Vulkan has no such count.
void compute_units(VkPhysicalDevice d, DeviceInfo& i) {
  std::uint32_t n = 0;
  vkEnumerateDeviceExtensionProperties(d, nullptr, &n, nullptr);
  std::vector<VkExtensionProperties> ext(n);
  vkEnumerateDeviceExtensionProperties(d, nullptr, &n, ext.data());
  auto has = [&](const char* name) {
    for (const VkExtensionProperties& e : ext)
      if (std::string(e.extensionName) == name) return true;
    return false;
  };
  VkPhysicalDeviceProperties2 p{};
  p.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2;
  if (has(VK_NV_SHADER_SM_BUILTINS_EXTENSION_NAME)) {
    VkPhysicalDeviceShaderSMBuiltinsPropertiesNV nv{};
    nv.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_SM_BUILTINS_PROPERTIES_NV;
    p.pNext = &nv;
    vkGetPhysicalDeviceProperties2(d, &p);
    i.compute_units = nv.shaderSMCount;
    i.compute_units_from = "VK_NV_shader_sm_builtins (SMs)";
  } else if (has(VK_AMD_SHADER_CORE_PROPERTIES_EXTENSION_NAME)) {
    VkPhysicalDeviceShaderCorePropertiesAMD amd{};
    amd.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_CORE_PROPERTIES_AMD;
    p.pNext = &amd;
    vkGetPhysicalDeviceProperties2(d, &p);
    i.compute_units = amd.shaderEngineCount * amd.shaderArraysPerEngineCount *
                      amd.computeUnitsPerShaderArray;
    i.compute_units_from = "VK_AMD_shader_core_properties (compute units)";
  }
}

DeviceInfo describe(VkPhysicalDevice d) {
  VkPhysicalDeviceVulkan12Properties p12{};
  p12.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_PROPERTIES;
  VkPhysicalDeviceProperties2 p{};
  p.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2;
  VkPhysicalDeviceProperties base{};
  vkGetPhysicalDeviceProperties(d, &base);
  const bool v12 = base.apiVersion >= VK_API_VERSION_1_2;
  if (v12) p.pNext = &p12;
  vkGetPhysicalDeviceProperties2(d, &p);
  const VkPhysicalDeviceLimits& l = p.properties.limits;
  DeviceInfo i;
  i.name = p.properties.deviceName;
  i.type = type_name(p.properties.deviceType);
  i.api_version = version(p.properties.apiVersion);
  i.vendor_id = p.properties.vendorID;
  i.device_id = p.properties.deviceID;
  i.sub_texel_precision_bits = l.subTexelPrecisionBits;
  i.mipmap_precision_bits = l.mipmapPrecisionBits;
  i.timestamp_period_ns = l.timestampPeriod;
  i.timestamps_on_compute = l.timestampComputeAndGraphics == VK_TRUE;
  i.max_workgroup_invocations = l.maxComputeWorkGroupInvocations;
  for (int k = 0; k < 3; ++k) i.max_workgroup_size[k] = l.maxComputeWorkGroupSize[k];
  compute_family(d, &i.timestamp_valid_bits);
  compute_units(d, i);
  i.denorm_behavior_independence = "none";
  i.rounding_mode_independence = "none";
  if (v12) {
    i.driver_name = p12.driverName;
    i.driver_info = p12.driverInfo;
    i.denorm_behavior_independence = independence(p12.denormBehaviorIndependence);
    i.rounding_mode_independence = independence(p12.roundingModeIndependence);
    i.denorm_preserve_f16 = p12.shaderDenormPreserveFloat16;
    i.denorm_preserve_f32 = p12.shaderDenormPreserveFloat32;
    i.denorm_flush_f16 = p12.shaderDenormFlushToZeroFloat16;
    i.denorm_flush_f32 = p12.shaderDenormFlushToZeroFloat32;
    i.rounding_rte_f16 = p12.shaderRoundingModeRTEFloat16;
    i.rounding_rte_f32 = p12.shaderRoundingModeRTEFloat32;
    i.rounding_rtz_f16 = p12.shaderRoundingModeRTZFloat16;
    i.rounding_rtz_f32 = p12.shaderRoundingModeRTZFloat32;
    i.signed_zero_inf_nan_preserve_f32 = p12.shaderSignedZeroInfNanPreserveFloat32;
    VkPhysicalDeviceVulkan12Features f12{};
    f12.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
    VkPhysicalDeviceFeatures2 f{};
    f.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
    f.pNext = &f12;
    vkGetPhysicalDeviceFeatures2(d, &f);
    i.shader_float16 = f12.shaderFloat16 == VK_TRUE;
  }
  return i;
}

}  // namespace

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS) throw VulkanError(std::string(what) + " failed: " + result_name(r));
}

Context::Context() : impl_(std::make_unique<Impl>()) {}

Context::~Context() {
  Impl& c = *impl_;
  if (c.device) {
    vkDeviceWaitIdle(c.device);
    if (c.pool) vkDestroyCommandPool(c.device, c.pool, nullptr);
    if (c.timestamps) vkDestroyQueryPool(c.device, c.timestamps, nullptr);
    vkDestroyDevice(c.device, nullptr);
  }
  if (c.instance) vkDestroyInstance(c.instance, nullptr);
}

const DeviceInfo& Context::info() const { return impl_->info; }

std::unique_ptr<Context> Context::create() {
  std::unique_ptr<Context> ctx(new Context());
  Impl& c = *ctx->impl_;
  VkApplicationInfo app{};
  app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
  app.pApplicationName = "bloomref";
  app.apiVersion = VK_API_VERSION_1_2;
  VkInstanceCreateInfo ici{};
  ici.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
  ici.pApplicationInfo = &app;
  const VkResult r = vkCreateInstance(&ici, nullptr, &c.instance);
  if (r != VK_SUCCESS)
    throw VulkanUnavailable("no Vulkan instance (" + result_name(r) +
                            "): install a Vulkan driver (Debian: mesa-vulkan-drivers for lavapipe)");
  std::uint32_t n = 0;
  vkEnumeratePhysicalDevices(c.instance, &n, nullptr);
  std::vector<VkPhysicalDevice> devices(n);
  vkEnumeratePhysicalDevices(c.instance, &n, devices.data());
  const char* wanted = std::getenv("BLOOMREF_VULKAN_DEVICE");
  int best = -1, best_rank = 99;
  for (std::uint32_t i = 0; i < n; ++i) {
    VkPhysicalDeviceProperties p{};
    vkGetPhysicalDeviceProperties(devices[i], &p);
    if (compute_family(devices[i], nullptr) < 0 || p.apiVersion < VK_API_VERSION_1_1) continue;
    if (wanted && *wanted && std::string(p.deviceName).find(wanted) == std::string::npos) continue;
    if (rank(p.deviceType) < best_rank) {
      best = int(i);
      best_rank = rank(p.deviceType);
    }
  }
  if (best < 0)
    throw VulkanUnavailable(n == 0 ? "no Vulkan device (install mesa-vulkan-drivers for lavapipe)"
                                   : std::string("no Vulkan 1.1 device with a compute queue") +
                                         (wanted && *wanted ? std::string(" named like '") +
                                                                  wanted + "' (BLOOMREF_VULKAN_DEVICE)"
                                                            : ""));
  c.physical = devices[std::size_t(best)];
  c.queue_family = std::uint32_t(compute_family(c.physical, nullptr));
  c.info = describe(c.physical);
  vkGetPhysicalDeviceMemoryProperties(c.physical, &c.memory);
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo q{};
  q.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
  q.queueFamilyIndex = c.queue_family;
  q.queueCount = 1;
  q.pQueuePriorities = &priority;
  VkDeviceCreateInfo dci{};
  dci.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &q;
  check(vkCreateDevice(c.physical, &dci, nullptr, &c.device), "vkCreateDevice");
  vkGetDeviceQueue(c.device, c.queue_family, 0, &c.queue);
  VkCommandPoolCreateInfo pci{};
  pci.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = c.queue_family;
  check(vkCreateCommandPool(c.device, &pci, nullptr, &c.pool), "vkCreateCommandPool");
  return ctx;
}

std::uint32_t Context::Impl::memory_type(std::uint32_t bits, VkMemoryPropertyFlags want) const {
  for (std::uint32_t i = 0; i < memory.memoryTypeCount; ++i)
    if ((bits & (1u << i)) && (memory.memoryTypes[i].propertyFlags & want) == want) return i;
  throw VulkanError("no memory type with the properties asked for");
}

VkQueryPool Context::Impl::timestamp_pool() {
  if (!timestamps && info.timestamp_valid_bits > 0) {
    VkQueryPoolCreateInfo q{};
    q.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
    q.queryType = VK_QUERY_TYPE_TIMESTAMP;
    q.queryCount = 2;
    check(vkCreateQueryPool(device, &q, nullptr, &timestamps), "vkCreateQueryPool");
  }
  return timestamps;
}

VkCommandBuffer Context::Impl::begin() {
  VkCommandBufferAllocateInfo a{};
  a.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
  a.commandPool = pool;
  a.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  a.commandBufferCount = 1;
  VkCommandBuffer cb = VK_NULL_HANDLE;
  check(vkAllocateCommandBuffers(device, &a, &cb), "vkAllocateCommandBuffers");
  VkCommandBufferBeginInfo b{};
  b.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
  b.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(cb, &b), "vkBeginCommandBuffer");
  return cb;
}

void Context::Impl::end_and_wait(VkCommandBuffer cb) {
  check(vkEndCommandBuffer(cb), "vkEndCommandBuffer");
  VkFenceCreateInfo fci{};
  fci.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
  VkFence fence = VK_NULL_HANDLE;
  check(vkCreateFence(device, &fci, nullptr, &fence), "vkCreateFence");
  VkSubmitInfo s{};
  s.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
  s.commandBufferCount = 1;
  s.pCommandBuffers = &cb;
  VkResult r = vkQueueSubmit(queue, 1, &s, fence);
  if (r == VK_SUCCESS) r = vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX);
  vkDestroyFence(device, fence, nullptr);
  vkFreeCommandBuffers(device, pool, 1, &cb);
  check(r, "vkQueueSubmit / vkWaitForFences");
}

}  // namespace bloomref::vulkan
