#include "gpu/context.h"

#include <spdlog/spdlog.h>

#include <fmt/format.h>
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>

#include "core/error.h"

namespace lfgi::gpu {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
// What to do when the loader finds no driver/device; names the variables a user can set.
std::string noDeviceHelp() {
  std::string help =
      "install the Mesa lavapipe CPU driver (Debian package mesa-vulkan-drivers), or point "
      "VK_ICD_FILENAMES (VK_DRIVER_FILES on newer loaders) at an ICD manifest such as "
      "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json";
  for (const char* var : {"VK_ICD_FILENAMES", "VK_DRIVER_FILES"})
    if (const char* v = std::getenv(var)) help += fmt::format(" ({} is currently '{}')", var, v);
  return help;
}

bool envFlag(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && std::strcmp(v, "") != 0 && std::strcmp(v, "0") != 0;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

const char* typeName(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "cpu";
    default:
      return "other";
  }
}

int typeRank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 3;
    default:
      return 4;
  }
}

bool layerAvailable(const char* name) {
  uint32_t count = 0;
  if (vkEnumerateInstanceLayerProperties(&count, nullptr) != VK_SUCCESS) return false;
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  return std::any_of(layers.begin(), layers.end(),
                     [&](const VkLayerProperties& l) { return std::strcmp(l.layerName, name) == 0; });
}

bool deviceExtensionAvailable(VkPhysicalDevice pd, const char* name) {
  uint32_t count = 0;
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> exts(count);
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &count, exts.data());
  return std::any_of(exts.begin(), exts.end(),
                     [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, name) == 0; });
}

VKAPI_ATTR VkBool32 VKAPI_CALL debugCallback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                             VkDebugUtilsMessageTypeFlagsEXT,
                                             const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* ctx = static_cast<Context*>(user);
  if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
    ctx->validationErrors.fetch_add(1);
    spdlog::error("vulkan validation: {}", data->pMessage);
  } else if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
    ctx->validationWarnings.fetch_add(1);
    spdlog::warn("vulkan validation: {}", data->pMessage);
  }
  return VK_FALSE;
}

VkInstance createInstance(bool validation, const VkDebugUtilsMessengerCreateInfoEXT* messengerInfo) {
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "lfgi";
  app.pEngineName = "lfgi";
  app.apiVersion = VK_API_VERSION_1_3;

  std::vector<const char*> layers;
  std::vector<const char*> extensions;
  if (validation) {
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pNext = validation ? messengerInfo : nullptr;
  info.pApplicationInfo = &app;
  info.enabledLayerCount = static_cast<uint32_t>(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = static_cast<uint32_t>(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();

  VkInstance instance = VK_NULL_HANDLE;
  VkResult r = vkCreateInstance(&info, nullptr, &instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER) fail("no Vulkan driver could be loaded: {}", noDeviceHelp());
  check(r, "vkCreateInstance");
  return instance;
}

std::vector<VkPhysicalDevice> physicalDevices(VkInstance instance) {
  uint32_t count = 0;
  VkResult r = vkEnumeratePhysicalDevices(instance, &count, nullptr);
  if (r == VK_ERROR_INITIALIZATION_FAILED || count == 0) fail("no Vulkan device found: {}", noDeviceHelp());
  check(r, "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> devices(count);
  check(vkEnumeratePhysicalDevices(instance, &count, devices.data()), "vkEnumeratePhysicalDevices");
  return devices;
}

DeviceInfo describe(VkPhysicalDevice pd) {
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props.pNext = &driver;
  vkGetPhysicalDeviceProperties2(pd, &props);
  DeviceInfo info;
  info.name = props.properties.deviceName;
  info.type = typeName(props.properties.deviceType);
  info.driver = fmt::format("{} {}", driver.driverName, driver.driverInfo);
  info.apiVersion = props.properties.apiVersion;
  info.vendorId = props.properties.vendorID;
  info.deviceId = props.properties.deviceID;
  return info;
}

VkPhysicalDevice pickDevice(const std::vector<VkPhysicalDevice>& devices, const std::string& wanted) {
  if (!wanted.empty()) {
    std::string names;
    for (VkPhysicalDevice pd : devices) {
      DeviceInfo info = describe(pd);
      if (lower(info.name).find(lower(wanted)) != std::string::npos) return pd;
      names += fmt::format("{}'{}'", names.empty() ? "" : ", ", info.name);
    }
    fail("no Vulkan device matches LFGI_VK_DEVICE='{}'; available: {}", wanted, names);
  }
  VkPhysicalDevice best = VK_NULL_HANDLE;
  int bestRank = 1 << 30;
  for (VkPhysicalDevice pd : devices) {
    VkPhysicalDeviceProperties p;
    vkGetPhysicalDeviceProperties(pd, &p);
    if (p.apiVersion < VK_API_VERSION_1_3) continue;
    if (typeRank(p.deviceType) < bestRank) {
      bestRank = typeRank(p.deviceType);
      best = pd;
    }
  }
  if (best == VK_NULL_HANDLE)
    fail("no Vulkan 1.3 device found ({} device(s) older); {}", devices.size(), noDeviceHelp());
  return best;
}

uint32_t pickQueueFamily(VkPhysicalDevice pd) {
  uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &count, families.data());
  // Prefer a family with compute and timestamps; among those, the universal (graphics) one, whose queue
  // is the one every driver optimises first.
  int best = -1;
  for (uint32_t i = 0; i < count; ++i) {
    if (!(families[i].queueFlags & VK_QUEUE_COMPUTE_BIT)) continue;
    if (families[i].timestampValidBits == 0) continue;
    if (best < 0 || (families[i].queueFlags & VK_QUEUE_GRAPHICS_BIT)) best = static_cast<int>(i);
  }
  if (best < 0) fail("Vulkan device has no compute queue with timestamp support");
  return static_cast<uint32_t>(best);
}

}  // namespace

const char* resultName(VkResult r) {
  switch (r) {
#define LFGI_CASE(x) \
  case x:            \
    return #x;
    LFGI_CASE(VK_SUCCESS)
    LFGI_CASE(VK_NOT_READY)
    LFGI_CASE(VK_TIMEOUT)
    LFGI_CASE(VK_INCOMPLETE)
    LFGI_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    LFGI_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    LFGI_CASE(VK_ERROR_INITIALIZATION_FAILED)
    LFGI_CASE(VK_ERROR_DEVICE_LOST)
    LFGI_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    LFGI_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    LFGI_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    LFGI_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    LFGI_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    LFGI_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    LFGI_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
    LFGI_CASE(VK_ERROR_FRAGMENTED_POOL)
    LFGI_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
    LFGI_CASE(VK_ERROR_INVALID_SHADER_NV)
#undef LFGI_CASE
    default:
      return "VK_ERROR_(unknown)";
  }
}

void check(VkResult result, const char* what) {
  if (result != VK_SUCCESS) fail("{} failed: {} ({})", what, resultName(result), static_cast<int>(result));
}

std::vector<DeviceInfo> listDevices() {
  VkInstance instance = createInstance(false, nullptr);
  std::vector<DeviceInfo> out;
  try {
    for (VkPhysicalDevice pd : physicalDevices(instance)) out.push_back(describe(pd));
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
  vkDestroyInstance(instance, nullptr);
  return out;
}

Context::~Context() {
  if (device && !ownsDevice) {
    if (commandPool) vkDestroyCommandPool(device, commandPool, nullptr);
    return;  // the host's device, instance and queue stay the host's
  }
  if (device) {
    vkDeviceWaitIdle(device);
    if (commandPool) vkDestroyCommandPool(device, commandPool, nullptr);
    vkDestroyDevice(device, nullptr);
  }
  if (messenger) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance, messenger, nullptr);
  }
  if (instance) vkDestroyInstance(instance, nullptr);
}

std::unique_ptr<Context> createContext(const ContextOptions& options) {
  auto ctx = std::make_unique<Context>();
  bool wantValidation = options.validation || envFlag("LFGI_VK_VALIDATION");
  ctx->validationEnabled = wantValidation && layerAvailable(kValidationLayer);
  if (wantValidation && !ctx->validationEnabled)
    spdlog::debug("{} not installed; running without validation", kValidationLayer);

  VkDebugUtilsMessengerCreateInfoEXT messengerInfo{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  messengerInfo.messageSeverity =
      VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messengerInfo.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                              VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                              VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messengerInfo.pfnUserCallback = debugCallback;
  messengerInfo.pUserData = ctx.get();

  ctx->instance = createInstance(ctx->validationEnabled, &messengerInfo);
  if (ctx->validationEnabled) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(ctx->instance, "vkCreateDebugUtilsMessengerEXT"));
    if (create)
      check(create(ctx->instance, &messengerInfo, nullptr, &ctx->messenger),
            "vkCreateDebugUtilsMessengerEXT");
  }

  std::string wanted = options.deviceName;
  if (wanted.empty() && std::getenv("LFGI_VK_DEVICE")) wanted = std::getenv("LFGI_VK_DEVICE");
  ctx->physicalDevice = pickDevice(physicalDevices(ctx->instance), wanted);
  ctx->info = describe(ctx->physicalDevice);
  vkGetPhysicalDeviceProperties(ctx->physicalDevice, &ctx->properties);
  vkGetPhysicalDeviceMemoryProperties(ctx->physicalDevice, &ctx->memoryProperties);
  if (ctx->properties.apiVersion < VK_API_VERSION_1_3)
    fail("Vulkan device '{}' supports only Vulkan {}.{}; lfgi needs 1.3", ctx->info.name,
         VK_API_VERSION_MAJOR(ctx->properties.apiVersion), VK_API_VERSION_MINOR(ctx->properties.apiVersion));
  if (!deviceExtensionAvailable(ctx->physicalDevice, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME))
    fail("Vulkan device '{}' lacks {}", ctx->info.name, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME);
  ctx->queueFamily = pickQueueFamily(ctx->physicalDevice);

  // Query optional features, then enable exactly the ones present.
  VkPhysicalDeviceVulkan13Features f13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceVulkan11Features f11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES};
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &f11;
  f11.pNext = &f12;
  f12.pNext = &f13;
  vkGetPhysicalDeviceFeatures2(ctx->physicalDevice, &f2);

  VkPhysicalDeviceVulkan13Features e13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
  VkPhysicalDeviceVulkan12Features e12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceVulkan11Features e11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES};
  VkPhysicalDeviceFeatures2 e2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  e2.pNext = &e11;
  e11.pNext = &e12;
  e12.pNext = &e13;
  e2.features.shaderInt64 = f2.features.shaderInt64;
  e11.storageBuffer16BitAccess = f11.storageBuffer16BitAccess;
  e12.shaderBufferInt64Atomics = f12.shaderBufferInt64Atomics;
  e12.shaderFloat16 = f12.shaderFloat16;
  e13.synchronization2 = f13.synchronization2;
  e13.dynamicRendering = f13.dynamicRendering;  // graphics without render passes (gpu/graphics.h)
  // glslc --target-env=vulkan1.3 emits LocalSizeId, which needs maintenance4 (mandatory in 1.3).
  if (!f13.maintenance4)
    fail("Vulkan device '{}' lacks maintenance4 (mandatory in Vulkan 1.3)", ctx->info.name);
  e13.maintenance4 = VK_TRUE;
  ctx->features.shaderInt64 = f2.features.shaderInt64;
  ctx->features.storageBuffer16BitAccess = f11.storageBuffer16BitAccess;
  ctx->features.shaderBufferInt64Atomics = f12.shaderBufferInt64Atomics;
  ctx->features.shaderFloat16 = f12.shaderFloat16;
  ctx->features.synchronization2 = f13.synchronization2;
  ctx->features.dynamicRendering = f13.dynamicRendering;

  float priority = 1.0f;
  VkDeviceQueueCreateInfo queueInfo{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  queueInfo.queueFamilyIndex = ctx->queueFamily;
  queueInfo.queueCount = 1;
  queueInfo.pQueuePriorities = &priority;
  const char* extensions[] = {VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME};
  VkDeviceCreateInfo deviceInfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  deviceInfo.pNext = &e2;
  deviceInfo.queueCreateInfoCount = 1;
  deviceInfo.pQueueCreateInfos = &queueInfo;
  deviceInfo.enabledExtensionCount = 1;
  deviceInfo.ppEnabledExtensionNames = extensions;
  check(vkCreateDevice(ctx->physicalDevice, &deviceInfo, nullptr, &ctx->device), "vkCreateDevice");
  vkGetDeviceQueue(ctx->device, ctx->queueFamily, 0, &ctx->queue);
  ctx->cmdPushDescriptorSet = reinterpret_cast<PFN_vkCmdPushDescriptorSetKHR>(
      vkGetDeviceProcAddr(ctx->device, "vkCmdPushDescriptorSetKHR"));
  if (!ctx->cmdPushDescriptorSet) fail("vkCmdPushDescriptorSetKHR not found on '{}'", ctx->info.name);

  VkCommandPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  poolInfo.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT | VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  poolInfo.queueFamilyIndex = ctx->queueFamily;
  check(vkCreateCommandPool(ctx->device, &poolInfo, nullptr, &ctx->commandPool), "vkCreateCommandPool");
  spdlog::debug("Vulkan device: {} ({}, {})", ctx->info.name, ctx->info.type, ctx->info.driver);
  return ctx;
}

std::unique_ptr<Context> adoptContext(const HostDevice& host) {
  if (!host.instance || !host.physicalDevice || !host.device || !host.queue)
    fail("host Vulkan device: instance, physical device, device and queue must all be set");
  auto ctx = std::make_unique<Context>();
  ctx->ownsDevice = false;
  ctx->instance = host.instance;
  ctx->physicalDevice = host.physicalDevice;
  ctx->device = host.device;
  ctx->queue = host.queue;
  ctx->queueFamily = host.queueFamily;
  ctx->queueMutex = host.queueMutex;
  ctx->features.shaderInt64 = host.shaderInt64Enabled;
  ctx->features.shaderBufferInt64Atomics = host.int64AtomicsEnabled;
  ctx->info = describe(host.physicalDevice);
  vkGetPhysicalDeviceProperties(host.physicalDevice, &ctx->properties);
  vkGetPhysicalDeviceMemoryProperties(host.physicalDevice, &ctx->memoryProperties);
  if (ctx->properties.apiVersion < VK_API_VERSION_1_3)
    fail("host Vulkan device '{}' supports only Vulkan {}.{}; lfgi needs 1.3", ctx->info.name,
         VK_API_VERSION_MAJOR(ctx->properties.apiVersion), VK_API_VERSION_MINOR(ctx->properties.apiVersion));
  if (!host.pushDescriptorEnabled)
    fail("host Vulkan device '{}': enable {} at vkCreateDevice (lfgi binds its buffers with it)",
         ctx->info.name, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME);
  if (!host.maintenance4Enabled)
    fail(
        "host Vulkan device '{}': enable VkPhysicalDeviceVulkan13Features::maintenance4 at vkCreateDevice "
        "(lfgi's SPIR-V uses LocalSizeId)",
        ctx->info.name);
  uint32_t families = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(host.physicalDevice, &families, nullptr);
  std::vector<VkQueueFamilyProperties> props(families);
  vkGetPhysicalDeviceQueueFamilyProperties(host.physicalDevice, &families, props.data());
  if (host.queueFamily >= families || !(props[host.queueFamily].queueFlags & VK_QUEUE_COMPUTE_BIT))
    fail("host Vulkan device '{}': queue family {} has no compute queue", ctx->info.name, host.queueFamily);
  ctx->cmdPushDescriptorSet = reinterpret_cast<PFN_vkCmdPushDescriptorSetKHR>(
      vkGetDeviceProcAddr(host.device, "vkCmdPushDescriptorSetKHR"));
  if (!ctx->cmdPushDescriptorSet)
    fail("host Vulkan device '{}': vkCmdPushDescriptorSetKHR not found (enable {})", ctx->info.name,
         VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME);
  VkCommandPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  poolInfo.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT | VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  poolInfo.queueFamilyIndex = host.queueFamily;
  check(vkCreateCommandPool(host.device, &poolInfo, nullptr, &ctx->commandPool), "vkCreateCommandPool");
  return ctx;
}

void submitAndWait(Context& ctx, const std::function<void(VkCommandBuffer)>& record) {
  VkCommandBufferAllocateInfo alloc{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  alloc.commandPool = ctx.commandPool;
  alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  alloc.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  check(vkAllocateCommandBuffers(ctx.device, &alloc, &cmd), "vkAllocateCommandBuffers");
  VkFence fence = VK_NULL_HANDLE;
  auto cleanup = [&] {
    if (fence) vkDestroyFence(ctx.device, fence, nullptr);
    vkFreeCommandBuffers(ctx.device, ctx.commandPool, 1, &cmd);
  };
  try {
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
    record(cmd);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(vkCreateFence(ctx.device, &fenceInfo, nullptr, &fence), "vkCreateFence");
    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    {
      std::unique_lock<std::mutex> lock;
      if (ctx.queueMutex) lock = std::unique_lock(*ctx.queueMutex);
      check(vkQueueSubmit(ctx.queue, 1, &submit, fence), "vkQueueSubmit");
    }
    check(vkWaitForFences(ctx.device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
  } catch (...) {
    std::unique_lock<std::mutex> lock;
    if (ctx.queueMutex) lock = std::unique_lock(*ctx.queueMutex);
    vkQueueWaitIdle(ctx.queue);
    cleanup();
    throw;
  }
  cleanup();
}

void memoryBarrier(VkCommandBuffer cmd) {
  VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                          VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT |
                          VK_ACCESS_HOST_READ_BIT;
  VkPipelineStageFlags stages = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
  vkCmdPipelineBarrier(cmd, stages, stages | VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &barrier, 0, nullptr, 0,
                       nullptr);
}

}  // namespace lfgi::gpu
