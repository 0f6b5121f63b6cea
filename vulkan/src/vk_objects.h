// The Vulkan objects bloomref's compute work uses (internal to the vulkan library): the
// context's handles, and buffers, images and a compute pipeline that free what they hold.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "bloomref/vulkan/context.h"

namespace bloomref::vulkan {

/// Throws VulkanError naming `what` and the result unless it is VK_SUCCESS.
void check(VkResult r, const char* what);

struct Context::Impl {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory{};
  DeviceInfo info;
  /// Two timestamps (before and after a dispatch), made on first use; null where the compute
  /// queue has no timestamps (DeviceInfo::timestamp_valid_bits 0).
  VkQueryPool timestamps = VK_NULL_HANDLE;
  VkQueryPool timestamp_pool();

  /// A memory type with `bits` allowed and every flag of `want`; throws VulkanError if none.
  std::uint32_t memory_type(std::uint32_t bits, VkMemoryPropertyFlags want) const;
  /// Records commands with `record`, submits them and waits for them to finish.
  template <class F>
  void submit(F record) {
    VkCommandBuffer cb = begin();
    record(cb);
    end_and_wait(cb);
  }
  VkCommandBuffer begin();
  void end_and_wait(VkCommandBuffer cb);
};

/// A host-visible, coherent buffer mapped for its whole life.
class Buffer {
 public:
  Buffer(Context::Impl& ctx, VkDeviceSize size, VkBufferUsageFlags usage);
  ~Buffer();
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  VkBuffer handle() const { return buffer_; }
  void* data() const { return mapped_; }
  VkDeviceSize size() const { return size_; }

 private:
  Context::Impl& ctx_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
  VkDeviceSize size_ = 0;
};

/// A 2-D image in device memory with its view, in VK_IMAGE_LAYOUT_GENERAL once created
/// (sampled and stored in that layout).
class Image2D {
 public:
  Image2D(Context::Impl& ctx, int width, int height, VkFormat format, VkImageUsageFlags usage);
  ~Image2D();
  Image2D(const Image2D&) = delete;
  Image2D& operator=(const Image2D&) = delete;
  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }
  int width, height;
  VkFormat format;
  /// Bytes per texel of `format` (RGBA32F: 16, RGBA16F: 8).
  std::uint32_t texel_bytes() const;
  /// Copies `bytes` (width x height texels of the image's format) into the image.
  void upload(const void* bytes);
  /// The image's texels as bytes.
  std::vector<unsigned char> download();

 private:
  Context::Impl& ctx_;
  VkImage image_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
};

/// A compute pipeline of SPIR-V `code` whose bindings are `types` (binding i of type types[i])
/// and whose push constants are `push_bytes` long.
class ComputePipeline {
 public:
  ComputePipeline(Context::Impl& ctx, const std::uint32_t* code, std::size_t code_bytes,
                  std::vector<VkDescriptorType> types, std::uint32_t push_bytes);
  /// Bindings numbered as given (binding, type), the entry point `entry`.
  ComputePipeline(Context::Impl& ctx, const std::uint32_t* code, std::size_t code_bytes,
                  std::vector<std::pair<std::uint32_t, VkDescriptorType>> bindings,
                  std::uint32_t push_bytes, const std::string& entry);
  ~ComputePipeline();
  ComputePipeline(const ComputePipeline&) = delete;
  ComputePipeline& operator=(const ComputePipeline&) = delete;
  /// Points binding `binding` at `view` (with `sampler` for a combined image sampler).
  void bind_image(std::uint32_t binding, VkImageView view, VkSampler sampler = VK_NULL_HANDLE);
  /// Points uniform-buffer binding `binding` at the whole of `buffer`.
  void bind_buffer(std::uint32_t binding, VkBuffer buffer, VkDeviceSize size);
  /// Records the dispatch of `groups_x` x `groups_y` work groups with `push` as constants.
  void dispatch(VkCommandBuffer cb, const void* push, std::uint32_t groups_x,
                std::uint32_t groups_y) const;

 private:
  Context::Impl& ctx_;
  std::vector<std::pair<std::uint32_t, VkDescriptorType>> types_;
  std::uint32_t push_bytes_;
  VkDescriptorType type_of(std::uint32_t binding) const;
  /// Points `binding` at an image (with its sampler) or a buffer.
  void write(std::uint32_t binding, const VkDescriptorImageInfo* image,
             const VkDescriptorBufferInfo* buffer);
  VkShaderModule module_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
};

/// A sampler with `filter` on both axes, clamp to edge, normalised coordinates, no mipmaps: GL's
/// GL_LINEAR (or GL_NEAREST) with GL_CLAMP_TO_EDGE.
class Sampler {
 public:
  /// Clamp to edge, or `repeat` (a host fault compare injects).
  Sampler(Context::Impl& ctx, VkFilter filter, bool repeat = false);
  /// Any address mode on both axes (clamp to border: transparent black, as GL's default).
  Sampler(Context::Impl& ctx, VkFilter filter, VkSamplerAddressMode mode);
  ~Sampler();
  Sampler(const Sampler&) = delete;
  Sampler& operator=(const Sampler&) = delete;
  VkSampler handle() const { return sampler_; }

 private:
  Context::Impl& ctx_;
  VkSampler sampler_ = VK_NULL_HANDLE;
};

}  // namespace bloomref::vulkan
