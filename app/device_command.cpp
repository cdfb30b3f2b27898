#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdio>

#include "app/commands.h"
#include "gpu/context.h"

namespace lfgi::app {

int runDevice(const DeviceOptions& options) {
  auto devices = gpu::listDevices();
  auto ctx = gpu::createContext();
  const VkPhysicalDeviceLimits& lim = ctx->properties.limits;
  uint64_t deviceLocalBytes = 0;
  for (uint32_t i = 0; i < ctx->memoryProperties.memoryHeapCount; ++i)
    if (ctx->memoryProperties.memoryHeaps[i].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      deviceLocalBytes += ctx->memoryProperties.memoryHeaps[i].size;

  nlohmann::ordered_json j;
  j["device"] = ctx->info.name;
  j["type"] = ctx->info.type;
  j["driver"] = ctx->info.driver;
  j["api_version"] =
      fmt::format("{}.{}.{}", VK_API_VERSION_MAJOR(ctx->info.apiVersion),
                  VK_API_VERSION_MINOR(ctx->info.apiVersion), VK_API_VERSION_PATCH(ctx->info.apiVersion));
  j["validation"] = ctx->validationEnabled;
  j["limits"] = {
      {"maxComputeWorkGroupInvocations", lim.maxComputeWorkGroupInvocations},
      {"maxComputeWorkGroupSize",
       {lim.maxComputeWorkGroupSize[0], lim.maxComputeWorkGroupSize[1], lim.maxComputeWorkGroupSize[2]}},
      {"maxComputeWorkGroupCount",
       {lim.maxComputeWorkGroupCount[0], lim.maxComputeWorkGroupCount[1], lim.maxComputeWorkGroupCount[2]}},
      {"maxComputeSharedMemorySize", lim.maxComputeSharedMemorySize},
      {"maxStorageBufferRange", lim.maxStorageBufferRange},
      {"maxPushConstantsSize", lim.maxPushConstantsSize},
      {"timestampPeriodNs", lim.timestampPeriod},
      {"deviceLocalHeapBytes", deviceLocalBytes},
  };
  j["features"] = {{"shaderInt64", ctx->features.shaderInt64},
                   {"shaderBufferInt64Atomics", ctx->features.shaderBufferInt64Atomics},
                   {"shaderFloat16", ctx->features.shaderFloat16},
                   {"storageBuffer16BitAccess", ctx->features.storageBuffer16BitAccess}};
  j["all_devices"] = nlohmann::json::array();
  for (const auto& d : devices) j["all_devices"].push_back({{"name", d.name}, {"type", d.type}});

  if (options.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("device   %s (%s)\ndriver   %s\nVulkan   %s%s\n", ctx->info.name.c_str(),
              ctx->info.type.c_str(), ctx->info.driver.c_str(), j["api_version"].get<std::string>().c_str(),
              ctx->validationEnabled ? " (validation on)" : "");
  std::printf("limits\n");
  for (const auto& [key, value] : j["limits"].items())
    std::printf("  %-32s %s\n", key.c_str(), value.dump().c_str());
  std::printf("features\n");
  for (const auto& [key, value] : j["features"].items())
    std::printf("  %-32s %s\n", key.c_str(), value.dump().c_str());
  if (devices.size() > 1) {
    std::printf("other devices (pick with LFGI_VK_DEVICE=<name substring>)\n");
    for (const auto& d : devices)
      if (d.name != ctx->info.name) std::printf("  %s (%s)\n", d.name.c_str(), d.type.c_str());
  }
  return 0;
}

}  // namespace lfgi::app
