// GPU buffers. DeviceLocal buffers are never mapped: uploads and readbacks go through a staging buffer
// and vkCmdCopyBuffer, on every device (also on lavapipe, where all memory is host-visible), so the copy
// path that a real GPU needs is the one the tests exercise. Upload/Readback buffers are persistently
// mapped, host-coherent memory.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <span>

#include "gpu/context.h"

namespace lfgi::gpu {

enum class MemoryUsage { DeviceLocal, Upload, Readback };

// Move-only owner of a VkBuffer and its memory.
class Buffer {
 public:
  Buffer() = default;
  Buffer(Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, MemoryUsage memory);
  Buffer(Buffer&& other) noexcept;
  Buffer& operator=(Buffer&& other) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer();
  // A view of a buffer someone else owns (a host engine's): binds like any Buffer, never destroyed here.
  // size: the bytes the passes may address (the owner's allocation must hold at least that many).
  static Buffer borrow(VkBuffer buffer, VkDeviceSize size);

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  MemoryUsage memory() const { return memoryUsage_; }
  void* mapped() const { return mapped_; }  // null for DeviceLocal

 private:
  void release();
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  MemoryUsage memoryUsage_ = MemoryUsage::DeviceLocal;
  void* mapped_ = nullptr;
};

// A device-local storage buffer that can also be copied to and from (the usual case for passes).
Buffer createStorageBuffer(Context& ctx, VkDeviceSize size);

// Copies bytes into dst at offset (staging + copy for DeviceLocal, memcpy for mapped buffers) and waits.
// Throws lfgi::Error if offset + bytes.size() exceeds dst.size().
void uploadBuffer(Context& ctx, Buffer& dst, std::span<const std::byte> bytes, VkDeviceSize offset = 0);

// Copies src[offset, offset + out.size()) into out and waits. Throws on out-of-range.
void readbackBuffer(Context& ctx, const Buffer& src, std::span<std::byte> out, VkDeviceSize offset = 0);

// Fills the buffer with a 32-bit pattern on the device (vkCmdFillBuffer) and waits.
void fillBuffer(Context& ctx, Buffer& dst, uint32_t value);

// Records an in-stream update of dst[0, bytes.size()) (vkCmdUpdateBuffer: at most 65536 bytes, a multiple of
// 4) between two barriers: earlier compute reads finish before it, later compute reads see it. For small
// per-view parameters recorded into a command buffer someone else submits. Throws lfgi::Error on a bad size.
void recordBufferUpdate(VkCommandBuffer cmd, Buffer& dst, std::span<const std::byte> bytes);

template <typename T>
void upload(Context& ctx, Buffer& dst, std::span<const T> data, VkDeviceSize offset = 0) {
  uploadBuffer(ctx, dst, std::as_bytes(data), offset);
}
template <typename T>
void readback(Context& ctx, const Buffer& src, std::span<T> out, VkDeviceSize offset = 0) {
  readbackBuffer(ctx, src, std::as_writable_bytes(out), offset);
}

}  // namespace lfgi::gpu
