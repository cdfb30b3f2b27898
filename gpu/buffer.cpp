#include "gpu/buffer.h"

#include <cstring>
#include <utility>

#include "core/error.h"

namespace lfgi::gpu {
namespace {

uint32_t findMemoryType(const Context& ctx, uint32_t typeBits, VkMemoryPropertyFlags required,
                        VkMemoryPropertyFlags preferred) {
  const VkPhysicalDeviceMemoryProperties& mp = ctx.memoryProperties;
  for (VkMemoryPropertyFlags want : {required | preferred, required}) {
    for (uint32_t i = 0; i < mp.memoryTypeCount; ++i) {
      if ((typeBits & (1u << i)) && (mp.memoryTypes[i].propertyFlags & want) == want) return i;
    }
  }
  fail("no Vulkan memory type with flags {:#x} on '{}'", required, ctx.info.name);
}

// Staging chunk: bounded so a 1 GB upload does not need a second 1 GB of host-visible memory at once.
constexpr VkDeviceSize kStagingChunk = 64ull << 20;

void checkRange(const Buffer& b, VkDeviceSize offset, std::size_t bytes, const char* what) {
  if (offset > b.size() || bytes > b.size() - offset)
    fail("{}: range [{}, {}) outside buffer of {} bytes", what, offset, offset + bytes, b.size());
}

}  // namespace

Buffer::Buffer(Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, MemoryUsage memory)
    : device_(ctx.device), size_(size), memoryUsage_(memory) {
  if (size == 0) fail("cannot create a zero-byte Vulkan buffer");
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = size;
  info.usage = usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  check(vkCreateBuffer(device_, &info, nullptr, &buffer_), "vkCreateBuffer");
  try {
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, buffer_, &req);
    VkMemoryPropertyFlags required = 0, preferred = 0;
    switch (memory) {
      case MemoryUsage::DeviceLocal:
        required = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
        break;
      case MemoryUsage::Upload:
        required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        break;
      case MemoryUsage::Readback:
        required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        preferred = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
        break;
    }
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = findMemoryType(ctx, req.memoryTypeBits, required, preferred);
    check(vkAllocateMemory(device_, &alloc, nullptr, &memory_), "vkAllocateMemory");
    check(vkBindBufferMemory(device_, buffer_, memory_, 0), "vkBindBufferMemory");
    if (memory != MemoryUsage::DeviceLocal)
      check(vkMapMemory(device_, memory_, 0, size, 0, &mapped_), "vkMapMemory");
  } catch (...) {
    release();
    throw;
  }
}

Buffer::Buffer(Buffer&& o) noexcept
    : device_(std::exchange(o.device_, VK_NULL_HANDLE)),
      buffer_(std::exchange(o.buffer_, VK_NULL_HANDLE)),
      memory_(std::exchange(o.memory_, VK_NULL_HANDLE)),
      size_(std::exchange(o.size_, 0)),
      memoryUsage_(o.memoryUsage_),
      mapped_(std::exchange(o.mapped_, nullptr)) {}

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    release();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    size_ = std::exchange(o.size_, 0);
    memoryUsage_ = o.memoryUsage_;
    mapped_ = std::exchange(o.mapped_, nullptr);
  }
  return *this;
}

Buffer::~Buffer() {
  release();
}

Buffer Buffer::borrow(VkBuffer buffer, VkDeviceSize size) {
  if (buffer == VK_NULL_HANDLE || size == 0) fail("borrowed Vulkan buffer: null handle or zero size");
  Buffer b;
  b.buffer_ = buffer;  // device_ stays null: release() leaves the handle to its owner
  b.size_ = size;
  return b;
}

void Buffer::release() {
  if (device_ == VK_NULL_HANDLE) return;
  if (buffer_) vkDestroyBuffer(device_, buffer_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);  // implicitly unmaps
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  device_ = VK_NULL_HANDLE;
}

Buffer createStorageBuffer(Context& ctx, VkDeviceSize size) {
  return Buffer(ctx, size,
                VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                    VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                MemoryUsage::DeviceLocal);
}

void uploadBuffer(Context& ctx, Buffer& dst, std::span<const std::byte> bytes, VkDeviceSize offset) {
  checkRange(dst, offset, bytes.size(), "uploadBuffer");
  if (bytes.empty()) return;
  if (dst.mapped()) {
    std::memcpy(static_cast<std::byte*>(dst.mapped()) + offset, bytes.data(), bytes.size());
    return;
  }
  VkDeviceSize chunk = std::min<VkDeviceSize>(bytes.size(), kStagingChunk);
  Buffer staging(ctx, chunk, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload);
  for (VkDeviceSize done = 0; done < bytes.size(); done += chunk) {
    VkDeviceSize n = std::min<VkDeviceSize>(chunk, bytes.size() - done);
    std::memcpy(staging.mapped(), bytes.data() + done, n);
    submitAndWait(ctx, [&](VkCommandBuffer cmd) {
      VkBufferCopy region{0, offset + done, n};
      vkCmdCopyBuffer(cmd, staging.handle(), dst.handle(), 1, &region);
    });
  }
}

void readbackBuffer(Context& ctx, const Buffer& src, std::span<std::byte> out, VkDeviceSize offset) {
  checkRange(src, offset, out.size(), "readbackBuffer");
  if (out.empty()) return;
  if (src.mapped()) {
    std::memcpy(out.data(), static_cast<const std::byte*>(src.mapped()) + offset, out.size());
    return;
  }
  VkDeviceSize chunk = std::min<VkDeviceSize>(out.size(), kStagingChunk);
  Buffer staging(ctx, chunk, VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUsage::Readback);
  for (VkDeviceSize done = 0; done < out.size(); done += chunk) {
    VkDeviceSize n = std::min<VkDeviceSize>(chunk, out.size() - done);
    submitAndWait(ctx, [&](VkCommandBuffer cmd) {
      VkBufferCopy region{offset + done, 0, n};
      vkCmdCopyBuffer(cmd, src.handle(), staging.handle(), 1, &region);
      memoryBarrier(cmd);
    });
    std::memcpy(out.data() + done, staging.mapped(), n);
  }
}

void fillBuffer(Context& ctx, Buffer& dst, uint32_t value) {
  submitAndWait(ctx,
                [&](VkCommandBuffer cmd) { vkCmdFillBuffer(cmd, dst.handle(), 0, VK_WHOLE_SIZE, value); });
}

void recordBufferUpdate(VkCommandBuffer cmd, Buffer& dst, std::span<const std::byte> bytes) {
  if (bytes.empty() || bytes.size() > 65536 || bytes.size() % 4 != 0 || bytes.size() > dst.size())
    fail("recordBufferUpdate: {} bytes into a {}-byte buffer (1..65536, a multiple of 4)", bytes.size(),
         dst.size());
  VkMemoryBarrier before{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  before.srcAccessMask = VK_ACCESS_SHADER_READ_BIT;
  before.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1,
                       &before, 0, nullptr, 0, nullptr);
  vkCmdUpdateBuffer(cmd, dst.handle(), 0, bytes.size(), bytes.data());
  VkMemoryBarrier after{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  after.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  after.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1,
                       &after, 0, nullptr, 0, nullptr);
}

}  // namespace lfgi::gpu
