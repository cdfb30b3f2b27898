// lfgi::VulkanShading (include/lfgi/runtime_vulkan.h): streaming/device_shading.h's probe shading on a
// host's device, fed from the Runtime's streaming manager.
#include "lfgi/runtime_vulkan.h"

#include <fmt/format.h>

#include <cmath>
#include <optional>

#include "core/error.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "streaming/device_shading.h"
#include "streaming/runtime_impl.h"

namespace lfgi {

namespace {

gpu::HostDevice hostDevice(const VulkanDevice& d) {
  gpu::HostDevice h;
  h.instance = d.instance;
  h.physicalDevice = d.physicalDevice;
  h.device = d.device;
  h.queue = d.queue;
  h.queueFamily = d.queueFamily;
  h.pushDescriptorEnabled = d.pushDescriptorEnabled;
  h.maintenance4Enabled = d.maintenance4Enabled;
  h.shaderInt64Enabled = d.shaderInt64Enabled;
  h.int64AtomicsEnabled = d.int64AtomicsEnabled;
  h.queueMutex = d.queueMutex;
  return h;
}

}  // namespace

struct VulkanShading::Impl {
  Runtime::Impl& rt;
  std::unique_ptr<gpu::Context> ctx;  // first: destroyed last (it destroys only its own command pool)
  std::optional<streaming::DeviceShading> shading;
  // lfgi's own outputs the host does not take (direct and total; specular when not given).
  gpu::Buffer scratchDirect, scratchSpecular, scratchTotal;
  VkDeviceSize scratchBytes = 0;

  Impl(Runtime::Impl& runtime, const VulkanDevice& device)
      : rt(runtime), ctx(gpu::adoptContext(hostDevice(device))) {
    shading.emplace(*ctx, *rt.manager, *rt.source, rt.config.keepRadius);
  }
  void ensureScratch(VkDeviceSize bytes);
};

void VulkanShading::Impl::ensureScratch(VkDeviceSize bytes) {
  if (bytes == scratchBytes) return;
  scratchDirect = gpu::createStorageBuffer(*ctx, bytes);
  scratchSpecular = gpu::createStorageBuffer(*ctx, bytes);
  scratchTotal = gpu::createStorageBuffer(*ctx, bytes);
  scratchBytes = bytes;
}

namespace {

void checkTarget(const ShadeTarget& t, bool needOutputs) {
  if (t.width == 0 || t.height == 0 || t.width > 16384 || t.height > 16384)
    throw RuntimeError(
        fmt::format("lfgi VulkanShading: target size {}x{} (1 to 16384 each)", t.width, t.height));
  if (!t.position || !t.normal || !t.albedo || !t.emission)
    throw RuntimeError("lfgi VulkanShading: ShadeTarget position, normal, albedo and emission must be set");
  if (needOutputs && !t.diffuse) throw RuntimeError("lfgi VulkanShading: ShadeTarget::diffuse must be set");
}

void checkView(const View& v) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(v.position[i]) || !std::isfinite(v.target[i]))
      throw RuntimeError("lfgi VulkanShading: View position and target must be finite");
  if (!(v.verticalFovDeg > 0.0f && v.verticalFovDeg < 180.0f))
    throw RuntimeError(
        fmt::format("lfgi VulkanShading: View::verticalFovDeg = {} (0 to 180, exclusive)", v.verticalFovDeg));
}

shared::GpuCamera gpuCamera(const View& v, const ShadeTarget& t) {
  return gpu::makeGpuCamera(vec3Of(v.position), vec3Of(v.target), v.verticalFovDeg, int(t.width),
                            int(t.height));
}

gpu::GBuffer borrowedGBuffer(const ShadeTarget& t) {
  const VkDeviceSize bytes = VkDeviceSize(t.width) * t.height * 16;
  gpu::GBuffer g;
  g.width = int(t.width);
  g.height = int(t.height);
  g.position = gpu::Buffer::borrow(t.position, bytes);
  g.normal = gpu::Buffer::borrow(t.normal, bytes);
  g.albedo = gpu::Buffer::borrow(t.albedo, bytes);
  g.emission = gpu::Buffer::borrow(t.emission, bytes);
  return g;
}

}  // namespace

std::unique_ptr<Runtime> Runtime::open(const RuntimeConfig& config, const VulkanDevice& device) {
  checkRuntimeConfig(config);
  if (config.virVisibility && config.ioThreads > 0 && !device.queueMutex)
    throw RuntimeError(
        "lfgi runtime: VulkanDevice::queueMutex is null, but VIR visibility submits on the host's queue from "
        "lfgi's IO threads (give a mutex, set RuntimeConfig::ioThreads = 0, or virVisibility = false)");
  if (config.virVisibility && !(device.shaderInt64Enabled && device.int64AtomicsEnabled))
    throw RuntimeError(
        "lfgi runtime: VIR visibility needs shaderInt64 and shaderBufferInt64Atomics enabled on the host's "
        "device (VulkanDevice::shaderInt64Enabled / int64AtomicsEnabled), or RuntimeConfig::virVisibility = "
        "false");
  return asRuntimeError([&] {
    std::unique_ptr<gpu::Context> ctx =
        config.virVisibility ? gpu::adoptContext(hostDevice(device)) : nullptr;
    return std::unique_ptr<Runtime>(new Runtime(Impl::open(config, std::move(ctx))));
  });
}

std::unique_ptr<VulkanShading> VulkanShading::create(Runtime& runtime, const VulkanDevice& device) {
  return asRuntimeError([&] {
    return std::unique_ptr<VulkanShading>(new VulkanShading(std::make_unique<Impl>(*runtime.impl_, device)));
  });
}

VulkanShading::VulkanShading(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
VulkanShading::~VulkanShading() = default;

std::size_t VulkanShading::upload() {
  return asRuntimeError([&] { return impl_->shading->upload(impl_->rt.camera); });
}

void VulkanShading::record(VkCommandBuffer cmd, const ShadeTarget& target, const View& view) {
  checkTarget(target, true);
  checkView(view);
  if (!impl_->shading->uploaded())
    throw RuntimeError("lfgi VulkanShading: record() before the first upload()");
  asRuntimeError([&] {
    const VkDeviceSize bytes = VkDeviceSize(target.width) * target.height * 16;
    impl_->ensureScratch(bytes);
    gpu::ShadingOptions options;
    options.direct = false;
    options.sunShadows = false;
    gpu::ShadeOutput out;
    out.width = int(target.width);
    out.height = int(target.height);
    out.direct = gpu::Buffer::borrow(impl_->scratchDirect.handle(), bytes);
    out.diffuse = gpu::Buffer::borrow(target.diffuse, bytes);
    out.specular =
        gpu::Buffer::borrow(target.specular ? target.specular : impl_->scratchSpecular.handle(), bytes);
    out.total = gpu::Buffer::borrow(impl_->scratchTotal.handle(), bytes);
    streaming::DeviceShading& d = *impl_->shading;
    d.recordShade(cmd, gpuCamera(view, target), int(target.width), int(target.height),
                  impl_->rt.timeOfDayHours, 0.0f, d.noScene(), options, borrowedGBuffer(target), out);
  });
}

void VulkanShading::recordWorldGBuffer(VkCommandBuffer cmd, const ShadeTarget& target, const View& view) {
  checkTarget(target, false);
  checkView(view);
  asRuntimeError([&] {
    gpu::GBuffer g = borrowedGBuffer(target);
    impl_->shading->recordWorldGBuffer(cmd, gpuCamera(view, target),
                                       impl_->rt.manager->layout().cellOf(vec3Of(view.target)), g);
  });
}

std::size_t VulkanShading::deviceBytes() const {
  return impl_->shading->deviceBytes();
}

}  // namespace lfgi
