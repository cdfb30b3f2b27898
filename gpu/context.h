// Headless Vulkan 1.3 compute context. One call creates instance + device + queue + command pool.
//
// Device choice: $LFGI_VK_DEVICE (case-insensitive substring of the device name) if set, else the
// first discrete GPU, then integrated, virtual, and finally a CPU device (Mesa lavapipe). Validation
// layers are enabled when ContextOptions::validation or $LFGI_VK_VALIDATION=1 asks and the Khronos layer
// is installed; every validation error is counted in Context::validationErrors (tests assert 0).
//
// Threading: a Context may be used from one thread at a time (its queue and command pool are not
// internally synchronised). Several Contexts may live in one process.
#pragma once

#include <vulkan/vulkan.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace lfgi::gpu {

struct ContextOptions {
  std::string deviceName;   // substring to match; empty: $LFGI_VK_DEVICE, else the best device
  bool validation = false;  // also enabled by $LFGI_VK_VALIDATION=1
};

struct DeviceInfo {
  std::string name;
  std::string type;  // "discrete", "integrated", "virtual", "cpu", "other"
  std::string driver;
  uint32_t apiVersion = 0;
  uint32_t vendorId = 0;
  uint32_t deviceId = 0;
};

// Optional features found and enabled on the device; passes check these before relying on them.
struct DeviceFeatures {
  bool shaderInt64 = false;
  bool shaderBufferInt64Atomics = false;
  bool shaderFloat16 = false;
  bool storageBuffer16BitAccess = false;
  bool synchronization2 = false;
  bool dynamicRendering = false;  // mandatory in 1.3; gpu/graphics.h needs it
};

struct Context {
  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physicalDevice = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  uint32_t queueFamily = 0;
  VkCommandPool commandPool = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties properties{};
  VkPhysicalDeviceMemoryProperties memoryProperties{};
  DeviceInfo info;
  DeviceFeatures features;
  bool validationEnabled = false;
  std::atomic<uint32_t> validationErrors{0};
  std::atomic<uint32_t> validationWarnings{0};
  PFN_vkCmdPushDescriptorSetKHR cmdPushDescriptorSet = nullptr;
  // False for a context adopted from a host (adoptContext): the destructor then destroys only the command
  // pool lfgi created, never the host's device or instance, and does not wait for the host's device.
  bool ownsDevice = true;
  // Held around every submit and wait on `queue` when set (a queue shared with a host engine's threads).
  std::mutex* queueMutex = nullptr;

  Context() = default;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context();
};

// Creates the context. Throws lfgi::Error with an actionable message when Vulkan is unavailable, no
// device exists (names VK_ICD_FILENAMES / VK_DRIVER_FILES and the lavapipe package), the requested
// device is not found (lists the available ones), or the device lacks Vulkan 1.3 / push descriptors.
std::unique_ptr<Context> createContext(const ContextOptions& options = {});

// A device a host engine created and owns (lfgi/runtime_vulkan.h): lfgi records into it and submits on
// its queue, never destroys it.
struct HostDevice {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physicalDevice = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;  // a queue of queueFamily with compute and transfer
  uint32_t queueFamily = 0;
  bool pushDescriptorEnabled = false;  // VK_KHR_push_descriptor among the device's enabled extensions
  bool maintenance4Enabled = false;    // VkPhysicalDeviceVulkan13Features::maintenance4 enabled
  bool shaderInt64Enabled = false;     // VkPhysicalDeviceFeatures::shaderInt64 enabled (VIR)
  bool int64AtomicsEnabled = false;    // VkPhysicalDeviceVulkan12Features::shaderBufferInt64Atomics (VIR)
  std::mutex* queueMutex = nullptr;    // Context::queueMutex
};

// Wraps a host's device in a Context that does not own it (ownsDevice = false; its own command pool on
// queueFamily for uploads). Throws lfgi::Error naming what is missing: a null handle, a device below
// Vulkan 1.3, push descriptors or maintenance4 not enabled, a queue family without compute.
std::unique_ptr<Context> adoptContext(const HostDevice& host);

// Lists every physical device the loader sees (creates a short-lived instance). Throws like createContext.
std::vector<DeviceInfo> listDevices();

// Records commands into a one-shot command buffer, submits it and waits for completion.
void submitAndWait(Context& ctx, const std::function<void(VkCommandBuffer)>& record);

// Full compute/transfer -> compute/transfer/host memory barrier (between dependent dispatches/copies).
void memoryBarrier(VkCommandBuffer cmd);

// Throws lfgi::Error("<what>: <VkResult name>") unless result is VK_SUCCESS.
void check(VkResult result, const char* what);
const char* resultName(VkResult result);

}  // namespace lfgi::gpu
