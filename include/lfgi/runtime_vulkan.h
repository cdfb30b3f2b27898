// lfgi runtime on the host's Vulkan device (docs/embedding.md): the probe shading pass recorded into the
// host's own command buffer. Include it only if the host renders with Vulkan; <lfgi/runtime.h> alone
// needs no Vulkan header.
//
// Contract
//   - The host owns the instance, the device and the queue: lfgi takes them as inputs (VulkanDevice) and
//     never creates or destroys any of them (open the Runtime with Runtime::open(config, device), so its VIR
//     visibility runs on this device too). The device must be Vulkan 1.3 with VK_KHR_push_descriptor and
//     VkPhysicalDeviceVulkan13Features::maintenance4 enabled (a device without them is a RuntimeError
//     naming what is missing). lfgi creates its own pipelines, buffers and one command pool on that device
//     and destroys exactly those in ~VulkanShading.
//   - upload(), after Runtime::update() each frame, on the game thread: brings lfgi's device copy of the
//     light field up to date (the probes of cells that became resident or were relit; otherwise only the
//     fades and fallbacks, a few hundred bytes). It submits copies on VulkanDevice::queue and waits for
//     them, so the host must not submit on that queue from another thread meanwhile, and must not have a
//     command buffer recorded by record() still executing (the buffers it reads are replaced).
//   - record() records one compute dispatch into the host's command buffer; it binds its own pipeline and
//     push descriptors (the host rebinds its own compute state after). Before it, the host makes its
//     G-buffer writes visible to compute-shader reads; after it, a barrier from compute-shader writes
//     before the host reads the outputs. The recorded work reads lfgi's buffers until it completes: the
//     host waits for it before the next upload() and before destroying VulkanShading.
//   - Output per pixel: indirect diffuse radiance (albedo / pi x irradiance from the probes with
//     Chebyshev visibility, cross-faded with the SH L1 fallback while cells stream) and indirect specular
//     radiance. Direct light is the host's. A point inside the world is never without light.
//   - Limits: the relight cross-fade that Runtime::sample() applies after a time-of-day relight is not on
//     the device (the device switches to the new lighting at the swap).
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>

#include "lfgi/runtime.h"

namespace lfgi {

struct VulkanDevice {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physicalDevice = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;  // compute-capable, of queueFamily: upload() submits here
  uint32_t queueFamily = 0;
  bool pushDescriptorEnabled = false;  // VK_KHR_push_descriptor was enabled at vkCreateDevice
  bool maintenance4Enabled = false;    // VkPhysicalDeviceVulkan13Features::maintenance4 was enabled
  // For Runtime::open(config, device) with RuntimeConfig::virVisibility (VIR needs 64-bit atomics):
  bool shaderInt64Enabled = false;   // VkPhysicalDeviceFeatures::shaderInt64 was enabled
  bool int64AtomicsEnabled = false;  // VkPhysicalDeviceVulkan12Features::shaderBufferInt64Atomics was enabled
  // lfgi locks it around each of its submits and waits on `queue` (its IO threads submit VIR work there);
  // a host that submits on `queue` from a thread other than the game thread, or while an lfgi call or
  // lfgi's IO may run, locks it too. Required by open(config, device) when virVisibility and ioThreads > 0.
  std::mutex* queueMutex = nullptr;
};

// The view the G-buffer was rendered from (world metres, y up).
struct View {
  float position[3] = {0.0f, 0.0f, 0.0f};
  float target[3] = {0.0f, 0.0f, -1.0f};
  float verticalFovDeg = 60.0f;
};

// Host-owned storage buffers (VK_BUFFER_USAGE_STORAGE_BUFFER_BIT), each width x height vec4 (16 bytes),
// pixel (x, y) at y * width + x, y = 0 the top row.
struct ShadeTarget {
  uint32_t width = 0, height = 0;
  // G-buffer (read):
  VkBuffer position = VK_NULL_HANDLE;  // xyz world position; w: hit distance, < 0 for no surface (sky)
  VkBuffer normal = VK_NULL_HANDLE;    // xyz unit normal facing the viewer; w: roughness
  VkBuffer albedo = VK_NULL_HANDLE;    // rgb albedo; w: metallic
  VkBuffer emission = VK_NULL_HANDLE;  // rgb emission; w: 1 for a back face inside solid (unlit), else 0
  // Outputs (written):
  VkBuffer diffuse = VK_NULL_HANDLE;   // rgb indirect diffuse radiance; w: sum of probe weights
  VkBuffer specular = VK_NULL_HANDLE;  // rgb indirect specular radiance; w: 1. May be null (not written)
};

class LFGI_API VulkanShading {
 public:
  // Throws RuntimeError for a null handle, a device without what the contract needs, or no shaders found
  // (they are installed beside the library: share/lfgi/shaders). runtime must outlive the VulkanShading.
  static std::unique_ptr<VulkanShading> create(Runtime& runtime, const VulkanDevice& device);
  ~VulkanShading();
  VulkanShading(const VulkanShading&) = delete;
  VulkanShading& operator=(const VulkanShading&) = delete;

  // After Runtime::update(), before record(): see the contract. Returns the bytes uploaded this call.
  std::size_t upload();
  // Records the shading of target seen from view (see the contract). Throws RuntimeError for a null
  // G-buffer or diffuse buffer, a size of 0, or a camera that is not finite.
  void record(VkCommandBuffer cmd, const ShadeTarget& target, const View& view);
  // Tools and examples: records a G-buffer of the world's own synthetic geometry (the 3 x 3 cells around the
  // cell holding view.target, clamped into the world, as `lfgi render --cell`; ray cast on the device) into
  // target's G-buffer buffers, then the barrier record() needs. An engine fills the G-buffer from its own
  // geometry pass instead.
  void recordWorldGBuffer(VkCommandBuffer cmd, const ShadeTarget& target, const View& view);
  // Device memory lfgi holds for the light field now (probe maps, cells), bytes.
  std::size_t deviceBytes() const;

 private:
  struct Impl;
  explicit VulkanShading(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lfgi
