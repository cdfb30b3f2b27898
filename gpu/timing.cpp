#include "gpu/timing.h"

#include <vector>

#include "core/error.h"

namespace lfgi::gpu {

GpuTimer::GpuTimer(Context& ctx, uint32_t capacity)
    : device_(ctx.device), capacity_(capacity), nsPerTick_(ctx.properties.limits.timestampPeriod) {
  uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(ctx.physicalDevice, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(ctx.physicalDevice, &count, families.data());
  uint32_t bits = families[ctx.queueFamily].timestampValidBits;
  validMask_ = bits >= 64 ? ~0ull : ((1ull << bits) - 1);
  VkQueryPoolCreateInfo info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  info.queryType = VK_QUERY_TYPE_TIMESTAMP;
  info.queryCount = capacity;
  check(vkCreateQueryPool(device_, &info, nullptr, &pool_), "vkCreateQueryPool");
}

GpuTimer::~GpuTimer() {
  if (pool_) vkDestroyQueryPool(device_, pool_, nullptr);
}

void GpuTimer::reset(VkCommandBuffer cmd) {
  vkCmdResetQueryPool(cmd, pool_, 0, capacity_);
}

void GpuTimer::stamp(VkCommandBuffer cmd, uint32_t index) {
  if (index >= capacity_) fail("GpuTimer: timestamp {} out of range (capacity {})", index, capacity_);
  vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool_, index);
}

double GpuTimer::elapsedMs(uint32_t begin, uint32_t end) const {
  if (begin >= capacity_ || end >= capacity_) fail("GpuTimer: timestamps {}..{} out of range", begin, end);
  uint64_t t[2] = {0, 0};
  for (int i = 0; i < 2; ++i) {
    check(vkGetQueryPoolResults(device_, pool_, i == 0 ? begin : end, 1, sizeof(uint64_t), &t[i],
                                sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
          "vkGetQueryPoolResults");
  }
  uint64_t ticks = ((t[1] & validMask_) - (t[0] & validMask_)) & validMask_;
  return static_cast<double>(ticks) * nsPerTick_ * 1e-6;
}

}  // namespace lfgi::gpu
