// lfgi::VulkanShading (include/lfgi/runtime_vulkan.h): the probe shading pass (gpu/probe_shading_pass.h) on
// a host's device, fed from the Runtime's streaming manager. The device holds a pool of as many slots as the
// manager has (each sized for the world's largest cell); stages of upload(): gather the cells around the
// camera in their streaming states, free the slots of cells no longer resident, upload the maps of cells
// newly resident or relit into free slots, then send the cell table (fades, fallbacks, boxes) alone.
#include "lfgi/runtime_vulkan.h"

#include <fmt/format.h>

#include <climits>
#include <cmath>
#include <optional>

#include "core/error.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/gbuffer_pass.h"
#include "gpu/probe_shading_pass.h"
#include "streaming/runtime_impl.h"
#include "worlds/gpu_materials.h"
#include "worlds/sky.h"
#include "worlds/synthetic_world.h"
#include "worlds/world_cells.h"

namespace lfgi {

namespace {

// One cell the pass sees, in its streaming state.
struct CellEntry {
  glm::ivec2 cell{0};
  const ProbeField* field = nullptr;  // resident: its field; else shaded from the fallback alone
  uint64_t version = 0;               // StreamingManager::fieldVersion (0: not resident)
  float fade = 0.0f;
  ShL1 fallback{};
  ProbeGrid box;  // fallback-only: the cell's probe lattice (its file's, or a valid cell's moved here)
};

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
  std::optional<gpu::ProbeShadingPass> pass;
  std::optional<gpu::GBufferPass> gbuffer;
  gpu::GpuSceneBuffers noScene;  // the shading pass traces nothing (no sun shadows, no AO)
  // recordWorldGBuffer: the synthetic world's 3 x 3 cells around the camera's cell.
  std::unique_ptr<worlds::SyntheticWorld> world;
  gpu::GpuSceneBuffers worldScene;
  glm::ivec2 worldSceneCell{INT_MIN, INT_MIN};
  // lfgi's own outputs the host does not take (direct and total; specular when not given).
  gpu::Buffer scratchDirect, scratchSpecular, scratchTotal;
  VkDeviceSize scratchBytes = 0;
  // The device pool: what each slot holds (cell and field version; version 0: free).
  struct DeviceSlot {
    glm::ivec2 cell{0};
    uint64_t version = 0;
  };
  std::vector<DeviceSlot> slots;
  int64_t probesPerSlot = 0;
  bool poolReserved = false, placeholderPool = false, haveCells = false;
  ProbeGrid templateBox;  // a valid cell's lattice, for cells without a file
  glm::ivec2 templateCell{0};

  Impl(Runtime::Impl& runtime, const VulkanDevice& device);
  std::vector<CellEntry> gatherCells() const;
  ProbeGrid boxOf(glm::ivec2 c) const;
  int slotFor(const CellEntry& e, std::size_t& uploaded);
  std::size_t uploadCells(const std::vector<CellEntry>& entries);
  void ensureScratch(VkDeviceSize bytes);
  void ensureWorldScene(glm::ivec2 cell);
};

VulkanShading::Impl::Impl(Runtime::Impl& runtime, const VulkanDevice& device)
    : rt(runtime), ctx(gpu::adoptContext(hostDevice(device))) {
  pass.emplace(*ctx);
  gbuffer.emplace(*ctx);
  noScene = gpu::uploadGpuScene(*ctx, gpu::buildGpuScene({}, {}, {}, {}));
  const streaming::WorldLayout& l = rt.manager->layout();
  bool haveTemplate = false;
  for (int z = 0; z < l.cells.y; ++z)
    for (int x = 0; x < l.cells.x; ++x) {
      const streaming::CellFileInfo& info = rt.source->info({x, z});
      if (info.state != streaming::CellFileState::Valid) continue;
      probesPerSlot = std::max(probesPerSlot, info.probes);
      if (!haveTemplate) templateCell = {x, z}, templateBox = info.grid, haveTemplate = true;
    }
  // As many device slots as cells can be resident at once: the manager's slots, at most every cell.
  slots.resize(size_t(std::min<int64_t>(rt.manager->slotCount(), int64_t(l.cells.x) * l.cells.y)));
}

ProbeGrid VulkanShading::Impl::boxOf(glm::ivec2 c) const {
  const streaming::CellFileInfo& info = rt.source->info(c);
  if (info.state == streaming::CellFileState::Valid) return info.grid;
  ProbeGrid g = templateBox;  // same placement in the cell as the valid cell's
  const glm::vec2 shift = glm::vec2(c - templateCell) * rt.manager->layout().cellSize;
  g.origin += glm::vec3(shift.x, 0.0f, shift.y);
  return g;
}

// Every cell within keepRadius + one cell of the camera (every resident cell is within keepRadius).
std::vector<CellEntry> VulkanShading::Impl::gatherCells() const {
  const streaming::WorldLayout& l = rt.manager->layout();
  const float reach = rt.config.keepRadius + l.cellSize;
  const glm::ivec2 lo = glm::max(l.cellOf(rt.camera - glm::vec3(reach, 0.0f, reach)), glm::ivec2(0));
  const glm::ivec2 hi = glm::min(l.cellOf(rt.camera + glm::vec3(reach, 0.0f, reach)), l.cells - 1);
  std::vector<CellEntry> out;
  for (int z = lo.y; z <= hi.y; ++z)
    for (int x = lo.x; x <= hi.x; ++x) {
      const glm::ivec2 c{x, z};
      if (l.distanceToCell(rt.camera, c) > reach) continue;
      CellEntry e;
      e.cell = c;
      e.fallback = rt.source->fallback(c);
      e.field = rt.manager->residentField(c);
      if (e.field) {
        e.version = rt.manager->fieldVersion(c);
        e.fade = rt.manager->fade(c);
      } else {
        e.box = boxOf(c);
      }
      out.push_back(e);
    }
  if (out.empty()) {  // the camera far outside the world: its nearest cell still gives light
    CellEntry e;
    e.cell = glm::clamp(l.cellOf(rt.camera), glm::ivec2(0), l.cells - 1);
    e.fallback = rt.source->fallback(e.cell);
    e.box = boxOf(e.cell);
    out.push_back(e);
  }
  return out;
}

// The device slot holding e's field at its version: the one it is in, else a free one it is uploaded to.
int VulkanShading::Impl::slotFor(const CellEntry& e, std::size_t& uploaded) {
  int free = -1;
  for (size_t k = 0; k < slots.size(); ++k) {
    if (slots[k].version == e.version && slots[k].cell == e.cell) return int(k);
    if (slots[k].version == 0 && free < 0) free = int(k);
  }
  if (free < 0) fail("lfgi VulkanShading: more resident cells than the {} device slots", slots.size());
  if (!poolReserved) {  // the first resident field gives the map resolutions (every cell decodes alike)
    pass->reservePool(int(slots.size()), probesPerSlot, e.field->irradianceResolution, e.field->resolution);
    poolReserved = true;
  }
  uploaded += pass->uploadPoolSlot(free, *e.field);
  slots[size_t(free)] = {e.cell, e.version};
  return free;
}

std::size_t VulkanShading::Impl::uploadCells(const std::vector<CellEntry>& entries) {
  for (DeviceSlot& d : slots) {  // free what is no longer resident at that version
    const bool current = rt.manager->fieldVersion(d.cell) == d.version;
    if (!current) d.version = 0;
  }
  std::vector<gpu::ShadingCellInput> in;
  std::vector<int> slotOf;
  std::size_t uploaded = 0;
  for (const CellEntry& e : entries) {
    gpu::ShadingCellInput c;
    c.fallback = e.fallback;
    if (e.field) {
      c.field = e.field;
      c.fade = e.fade;
      slotOf.push_back(slotFor(e, uploaded));
    } else {
      c.fallbackOnly = true;
      c.box = e.box;
      slotOf.push_back(-1);
    }
    in.push_back(c);
  }
  if (!poolReserved && !placeholderPool) {  // nothing resident yet: one-probe slots keep the bindings valid
    pass->reservePool(int(slots.size()), 1, 1, 1);
    placeholderPool = true;
  }
  pass->setPoolCells(in, slotOf);
  haveCells = true;
  return uploaded + in.size() * sizeof(shared::ShadeCell);
}

void VulkanShading::Impl::ensureScratch(VkDeviceSize bytes) {
  if (bytes == scratchBytes) return;
  scratchDirect = gpu::createStorageBuffer(*ctx, bytes);
  scratchSpecular = gpu::createStorageBuffer(*ctx, bytes);
  scratchTotal = gpu::createStorageBuffer(*ctx, bytes);
  scratchBytes = bytes;
}

void VulkanShading::Impl::ensureWorldScene(glm::ivec2 cell) {
  if (cell == worldSceneCell) return;
  if (!world) world = std::make_unique<worlds::SyntheticWorld>(worlds::readWorldManifest(rt.config.world));
  worlds::TriangleMesh mesh;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dx = -1; dx <= 1; ++dx)
      if (world->contains({cell.x + dx, cell.y + dz}))
        mesh.append(worlds::buildCell(*world, {cell.x + dx, cell.y + dz}).mesh);
  worldScene = gpu::uploadGpuScene(
      *ctx,
      gpu::buildGpuScene(mesh.positions, mesh.indices, mesh.triangleMaterial, worlds::gpuMaterials(mesh)));
  worldSceneCell = cell;
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
  return asRuntimeError([&] { return impl_->uploadCells(impl_->gatherCells()); });
}

void VulkanShading::record(VkCommandBuffer cmd, const ShadeTarget& target, const View& view) {
  checkTarget(target, true);
  checkView(view);
  if (!impl_->haveCells) throw RuntimeError("lfgi VulkanShading: record() before the first upload()");
  asRuntimeError([&] {
    const VkDeviceSize bytes = VkDeviceSize(target.width) * target.height * 16;
    impl_->ensureScratch(bytes);
    const shared::GpuCamera camera = gpuCamera(view, target);
    worlds::SkyState sky;
    sky.timeOfDayHours = impl_->rt.timeOfDayHours;
    gpu::ShadingOptions options;
    options.direct = false;
    options.sunShadows = false;
    impl_->pass->recordView(cmd, worlds::makeSky(sky).params, camera, int(target.width), int(target.height),
                            impl_->noScene, options);
    gpu::ShadeOutput out;
    out.width = int(target.width);
    out.height = int(target.height);
    out.direct = gpu::Buffer::borrow(impl_->scratchDirect.handle(), bytes);
    out.diffuse = gpu::Buffer::borrow(target.diffuse, bytes);
    out.specular =
        gpu::Buffer::borrow(target.specular ? target.specular : impl_->scratchSpecular.handle(), bytes);
    out.total = gpu::Buffer::borrow(impl_->scratchTotal.handle(), bytes);
    impl_->pass->record(cmd, impl_->noScene, borrowedGBuffer(target), out);
  });
}

void VulkanShading::recordWorldGBuffer(VkCommandBuffer cmd, const ShadeTarget& target, const View& view) {
  checkTarget(target, false);
  checkView(view);
  asRuntimeError([&] {
    const streaming::WorldLayout& l = impl_->rt.manager->layout();
    impl_->ensureWorldScene(glm::clamp(l.cellOf(vec3Of(view.target)), glm::ivec2(0), l.cells - 1));
    const shared::GpuCamera camera = gpuCamera(view, target);
    impl_->gbuffer->recordCamera(cmd, camera, int(target.width), int(target.height), impl_->worldScene);
    gpu::GBuffer g = borrowedGBuffer(target);
    impl_->gbuffer->record(cmd, impl_->worldScene, g);
    gpu::memoryBarrier(cmd);
  });
}

std::size_t VulkanShading::deviceBytes() const {
  return impl_->pass->deviceBytes();
}

}  // namespace lfgi
