// GPU timestamps: a query pool whose differences give device time in milliseconds, independent of
// host-side submission overhead (which on lavapipe includes LLVM JIT on first use).
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

#include "gpu/context.h"

namespace lfgi::gpu {

class GpuTimer {
 public:
  // capacity: number of timestamps that can be written per recording.
  GpuTimer(Context& ctx, uint32_t capacity);
  GpuTimer(const GpuTimer&) = delete;
  GpuTimer& operator=(const GpuTimer&) = delete;
  ~GpuTimer();

  // Call at the start of a command buffer before any stamp() in it.
  void reset(VkCommandBuffer cmd);
  // Writes timestamp `index` after all previously recorded work completes. Throws if index >= capacity.
  void stamp(VkCommandBuffer cmd, uint32_t index);
  // After the command buffer has completed: milliseconds between stamps `begin` and `end`.
  double elapsedMs(uint32_t begin, uint32_t end) const;

 private:
  VkDevice device_;
  VkQueryPool pool_ = VK_NULL_HANDLE;
  uint32_t capacity_;
  double nsPerTick_;
  uint64_t validMask_;
};

}  // namespace lfgi::gpu
