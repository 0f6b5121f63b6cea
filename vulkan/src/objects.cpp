#include <cstring>

#include "vk_objects.h"

namespace bloomref::vulkan {
namespace {

// Memory for requirements `req` with properties `props`.
VkDeviceMemory allocate(Context::Impl& ctx, const VkMemoryRequirements& req,
                        VkMemoryPropertyFlags props, const char* what) {
  VkMemoryAllocateInfo a{};
  a.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
  a.allocationSize = req.size;
  a.memoryTypeIndex = ctx.memory_type(req.memoryTypeBits, props);
  VkDeviceMemory m = VK_NULL_HANDLE;
  check(vkAllocateMemory(ctx.device, &a, nullptr, &m), what);
  return m;
}

}  // namespace

Buffer::Buffer(Context::Impl& ctx, VkDeviceSize size, VkBufferUsageFlags usage)
    : ctx_(ctx), size_(size) {
  VkBufferCreateInfo bci{};
  bci.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
  bci.size = size;
  bci.usage = usage;
  bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  check(vkCreateBuffer(ctx.device, &bci, nullptr, &buffer_), "vkCreateBuffer");
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(ctx.device, buffer_, &req);
  memory_ = allocate(ctx, req,
                     VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
                     "vkAllocateMemory (buffer)");
  check(vkBindBufferMemory(ctx.device, buffer_, memory_, 0), "vkBindBufferMemory");
  check(vkMapMemory(ctx.device, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_), "vkMapMemory");
}

Buffer::~Buffer() {
  if (mapped_) vkUnmapMemory(ctx_.device, memory_);
  vkDestroyBuffer(ctx_.device, buffer_, nullptr);
  vkFreeMemory(ctx_.device, memory_, nullptr);
}

Image2D::Image2D(Context::Impl& ctx, int w, int h, VkFormat f, VkImageUsageFlags usage)
    : width(w), height(h), format(f), ctx_(ctx) {
  VkImageCreateInfo ici{};
  ici.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
  ici.imageType = VK_IMAGE_TYPE_2D;
  ici.format = f;
  ici.extent = {std::uint32_t(w), std::uint32_t(h), 1};
  ici.mipLevels = 1;
  ici.arrayLayers = 1;
  ici.samples = VK_SAMPLE_COUNT_1_BIT;
  ici.tiling = VK_IMAGE_TILING_OPTIMAL;
  ici.usage = usage | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  ici.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  check(vkCreateImage(ctx.device, &ici, nullptr, &image_), "vkCreateImage");
  VkMemoryRequirements req{};
  vkGetImageMemoryRequirements(ctx.device, image_, &req);
  memory_ = allocate(ctx, req, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, "vkAllocateMemory (image)");
  check(vkBindImageMemory(ctx.device, image_, memory_, 0), "vkBindImageMemory");
  VkImageViewCreateInfo v{};
  v.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
  v.image = image_;
  v.viewType = VK_IMAGE_VIEW_TYPE_2D;
  v.format = f;
  v.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  check(vkCreateImageView(ctx.device, &v, nullptr, &view_), "vkCreateImageView");
  // Every use (transfer, sampling, storage) is in the general layout.
  ctx.submit([&](VkCommandBuffer cb) {
    VkImageMemoryBarrier b{};
    b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    b.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    b.newLayout = VK_IMAGE_LAYOUT_GENERAL;
    b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image_;
    b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    b.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                         0, 0, nullptr, 0, nullptr, 1, &b);
  });
}

Image2D::~Image2D() {
  vkDestroyImageView(ctx_.device, view_, nullptr);
  vkDestroyImage(ctx_.device, image_, nullptr);
  vkFreeMemory(ctx_.device, memory_, nullptr);
}

std::uint32_t Image2D::texel_bytes() const {
  switch (format) {
    case VK_FORMAT_R32G32B32A32_SFLOAT: return 16;
    case VK_FORMAT_R16G16B16A16_SFLOAT: return 8;
    default: return 4;  // packed 32-bit formats
  }
}

namespace {

// A full barrier between the transfers and shader work around a copy.
void all_commands_barrier(VkCommandBuffer cb) {
  VkMemoryBarrier m{};
  m.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
  m.srcAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  m.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       0, 1, &m, 0, nullptr, 0, nullptr);
}

VkBufferImageCopy whole(const Image2D& img) {
  VkBufferImageCopy r{};
  r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  r.imageExtent = {std::uint32_t(img.width), std::uint32_t(img.height), 1};
  return r;
}

}  // namespace

void Image2D::upload(const void* bytes) {
  const VkDeviceSize n = VkDeviceSize(width) * height * texel_bytes();
  Buffer staging(ctx_, n, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
  std::memcpy(staging.data(), bytes, n);
  ctx_.submit([&](VkCommandBuffer cb) {
    all_commands_barrier(cb);
    const VkBufferImageCopy r = whole(*this);
    vkCmdCopyBufferToImage(cb, staging.handle(), image_, VK_IMAGE_LAYOUT_GENERAL, 1, &r);
    all_commands_barrier(cb);
  });
}

std::vector<unsigned char> Image2D::download() {
  const VkDeviceSize n = VkDeviceSize(width) * height * texel_bytes();
  Buffer staging(ctx_, n, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  ctx_.submit([&](VkCommandBuffer cb) {
    all_commands_barrier(cb);
    const VkBufferImageCopy r = whole(*this);
    vkCmdCopyImageToBuffer(cb, image_, VK_IMAGE_LAYOUT_GENERAL, staging.handle(), 1, &r);
    all_commands_barrier(cb);
  });
  const auto* p = static_cast<const unsigned char*>(staging.data());
  return std::vector<unsigned char>(p, p + n);
}

namespace {
std::vector<std::pair<std::uint32_t, VkDescriptorType>> numbered(std::vector<VkDescriptorType> t) {
  std::vector<std::pair<std::uint32_t, VkDescriptorType>> out;
  for (std::uint32_t i = 0; i < t.size(); ++i) out.emplace_back(i, t[i]);
  return out;
}
}  // namespace

ComputePipeline::ComputePipeline(Context::Impl& ctx, const std::uint32_t* code,
                                 std::size_t code_bytes, std::vector<VkDescriptorType> types,
                                 std::uint32_t push_bytes)
    : ComputePipeline(ctx, code, code_bytes, numbered(std::move(types)), push_bytes, "main") {}

VkDescriptorType ComputePipeline::type_of(std::uint32_t binding) const {
  for (const auto& [b, t] : types_)
    if (b == binding) return t;
  throw VulkanError("no binding " + std::to_string(binding) + " in the pipeline");
}

ComputePipeline::ComputePipeline(Context::Impl& ctx, const std::uint32_t* code,
                                 std::size_t code_bytes,
                                 std::vector<std::pair<std::uint32_t, VkDescriptorType>> types,
                                 std::uint32_t push_bytes, const std::string& entry)
    : ctx_(ctx), types_(std::move(types)), push_bytes_(push_bytes) {
  VkShaderModuleCreateInfo smi{};
  smi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
  smi.codeSize = code_bytes;
  smi.pCode = code;
  check(vkCreateShaderModule(ctx.device, &smi, nullptr, &module_), "vkCreateShaderModule");
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  std::vector<VkDescriptorPoolSize> sizes;
  for (const auto& [binding, type] : types_) {
    VkDescriptorSetLayoutBinding b{};
    b.binding = binding;
    b.descriptorType = type;
    b.descriptorCount = 1;
    b.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    bindings.push_back(b);
    sizes.push_back({type, 1});
  }
  VkDescriptorSetLayoutCreateInfo dl{};
  dl.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
  dl.bindingCount = std::uint32_t(bindings.size());
  dl.pBindings = bindings.data();
  check(vkCreateDescriptorSetLayout(ctx.device, &dl, nullptr, &set_layout_),
        "vkCreateDescriptorSetLayout");
  VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes};
  VkPipelineLayoutCreateInfo pl{};
  pl.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
  pl.setLayoutCount = 1;
  pl.pSetLayouts = &set_layout_;
  pl.pushConstantRangeCount = push_bytes ? 1 : 0;
  pl.pPushConstantRanges = &range;
  check(vkCreatePipelineLayout(ctx.device, &pl, nullptr, &layout_), "vkCreatePipelineLayout");
  VkComputePipelineCreateInfo cp{};
  cp.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
  cp.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
  cp.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cp.stage.module = module_;
  cp.stage.pName = entry.c_str();
  cp.layout = layout_;
  check(vkCreateComputePipelines(ctx.device, VK_NULL_HANDLE, 1, &cp, nullptr, &pipeline_),
        "vkCreateComputePipelines");
  VkDescriptorPoolCreateInfo dp{};
  dp.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
  dp.maxSets = 1;
  if (sizes.empty()) sizes.push_back({VK_DESCRIPTOR_TYPE_SAMPLER, 1});  // a pool has a size
  dp.poolSizeCount = std::uint32_t(sizes.size());
  dp.pPoolSizes = sizes.data();
  check(vkCreateDescriptorPool(ctx.device, &dp, nullptr, &pool_), "vkCreateDescriptorPool");
  VkDescriptorSetAllocateInfo da{};
  da.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
  da.descriptorPool = pool_;
  da.descriptorSetCount = 1;
  da.pSetLayouts = &set_layout_;
  check(vkAllocateDescriptorSets(ctx.device, &da, &set_), "vkAllocateDescriptorSets");
}

ComputePipeline::~ComputePipeline() {
  vkDestroyDescriptorPool(ctx_.device, pool_, nullptr);
  vkDestroyPipeline(ctx_.device, pipeline_, nullptr);
  vkDestroyPipelineLayout(ctx_.device, layout_, nullptr);
  vkDestroyDescriptorSetLayout(ctx_.device, set_layout_, nullptr);
  vkDestroyShaderModule(ctx_.device, module_, nullptr);
}

void ComputePipeline::bind_image(std::uint32_t binding, VkImageView view, VkSampler sampler) {
  const VkDescriptorImageInfo ii{sampler, view, VK_IMAGE_LAYOUT_GENERAL};
  write(binding, &ii, nullptr);
}

void ComputePipeline::bind_buffer(std::uint32_t binding, VkBuffer buffer, VkDeviceSize size) {
  const VkDescriptorBufferInfo bi{buffer, 0, size};
  write(binding, nullptr, &bi);
}

void ComputePipeline::write(std::uint32_t binding, const VkDescriptorImageInfo* image,
                            const VkDescriptorBufferInfo* buffer) {
  VkWriteDescriptorSet w{};
  w.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type_of(binding);
  w.pImageInfo = image;
  w.pBufferInfo = buffer;
  vkUpdateDescriptorSets(ctx_.device, 1, &w, 0, nullptr);
}

void ComputePipeline::dispatch(VkCommandBuffer cb, const void* push, std::uint32_t gx,
                               std::uint32_t gy) const {
  vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_);
  vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, layout_, 0, 1, &set_, 0, nullptr);
  if (push_bytes_) vkCmdPushConstants(cb, layout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes_, push);
  vkCmdDispatch(cb, gx, gy, 1);
}

Sampler::Sampler(Context::Impl& ctx, VkFilter filter, bool repeat)
    : Sampler(ctx, filter,
              repeat ? VK_SAMPLER_ADDRESS_MODE_REPEAT : VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE) {}

Sampler::Sampler(Context::Impl& ctx, VkFilter filter, VkSamplerAddressMode mode) : ctx_(ctx) {
  VkSamplerCreateInfo s{};
  s.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
  s.magFilter = s.minFilter = filter;
  s.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  s.addressModeU = s.addressModeV = s.addressModeW = mode;
  s.borderColor = VK_BORDER_COLOR_FLOAT_TRANSPARENT_BLACK;  // GL's default border colour
  s.maxLod = 0.0f;
  check(vkCreateSampler(ctx.device, &s, nullptr, &sampler_), "vkCreateSampler");
}

Sampler::~Sampler() { vkDestroySampler(ctx_.device, sampler_, nullptr); }

}  // namespace bloomref::vulkan
