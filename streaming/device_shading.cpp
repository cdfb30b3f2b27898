#include "streaming/device_shading.h"

#include <algorithm>
#include <cstdlib>

#include "core/error.h"
#include "gpu/buffer.h"
#include "worlds/gpu_materials.h"
#include "worlds/sky.h"
#include "worlds/world_cells.h"

namespace lfgi::streaming {

DeviceShading::DeviceShading(gpu::Context& ctx, const StreamingManager& manager, const CellFileSource& source,
                             float keepRadius)
    : ctx_(ctx), manager_(manager), source_(source), keepRadius_(keepRadius), pass_(ctx), gbuffer_(ctx) {
  noScene_ = gpu::uploadGpuScene(ctx_, gpu::buildGpuScene({}, {}, {}, {}));
  const WorldLayout& l = manager_.layout();
  bool haveTemplate = false;
  for (int z = 0; z < l.cells.y; ++z)
    for (int x = 0; x < l.cells.x; ++x) {
      const CellFileInfo& info = source_.info({x, z});
      if (info.state != CellFileState::Valid) continue;
      probesPerSlot_ = std::max(probesPerSlot_, info.probes);
      if (!haveTemplate) templateCell_ = {x, z}, templateBox_ = info.grid, haveTemplate = true;
    }
  // As many device slots as cells can be resident at once: the manager's slots, at most every cell.
  slots_.resize(size_t(std::min<int64_t>(manager_.slotCount(), int64_t(l.cells.x) * l.cells.y)));
}

ProbeGrid DeviceShading::boxOf(glm::ivec2 c) const {
  const CellFileInfo& info = source_.info(c);
  if (info.state == CellFileState::Valid) return info.grid;
  ProbeGrid g = templateBox_;  // same placement in the cell as the valid cell's
  const glm::vec2 shift = glm::vec2(c - templateCell_) * manager_.layout().cellSize;
  g.origin += glm::vec3(shift.x, 0.0f, shift.y);
  return g;
}

// Every cell within keepRadius + one cell of the camera (every resident cell is within keepRadius).
std::vector<DeviceShading::CellEntry> DeviceShading::gatherCells(glm::vec3 camera) const {
  const WorldLayout& l = manager_.layout();
  const float reach = keepRadius_ + l.cellSize;
  const glm::ivec2 lo = glm::max(l.cellOf(camera - glm::vec3(reach, 0.0f, reach)), glm::ivec2(0));
  const glm::ivec2 hi = glm::min(l.cellOf(camera + glm::vec3(reach, 0.0f, reach)), l.cells - 1);
  std::vector<CellEntry> out;
  for (int z = lo.y; z <= hi.y; ++z)
    for (int x = lo.x; x <= hi.x; ++x) {
      const glm::ivec2 c{x, z};
      if (l.distanceToCell(camera, c) > reach) continue;
      CellEntry e;
      e.cell = c;
      e.fallback = source_.fallback(c);
      e.field = manager_.residentField(c);
      if (e.field) {
        e.version = manager_.fieldVersion(c);
        e.fade = manager_.fade(c);
      } else {
        e.box = boxOf(c);
      }
      out.push_back(e);
    }
  if (out.empty()) {  // the camera far outside the world: its nearest cell still gives light
    CellEntry e;
    e.cell = glm::clamp(l.cellOf(camera), glm::ivec2(0), l.cells - 1);
    e.fallback = source_.fallback(e.cell);
    e.box = boxOf(e.cell);
    out.push_back(e);
  }
  return out;
}

// The device slot holding e's field at its version: the one it is in, else a free one it is uploaded to.
int DeviceShading::slotFor(const CellEntry& e, size_t& uploaded) {
  int free = -1;
  for (size_t k = 0; k < slots_.size(); ++k) {
    if (slots_[k].version == e.version && slots_[k].cell == e.cell) return int(k);
    if (slots_[k].version == 0 && free < 0) free = int(k);
  }
  if (free < 0) fail("DeviceShading: more resident cells than the {} device slots", slots_.size());
  if (!poolReserved_) {  // the first resident field gives the map resolutions (every cell decodes alike)
    pass_.reservePool(int(slots_.size()), probesPerSlot_, e.field->irradianceResolution, e.field->resolution);
    poolReserved_ = true;
  }
  uploaded += pass_.uploadPoolSlot(free, *e.field);
  slots_[size_t(free)] = {e.cell, e.version};
  return free;
}

size_t DeviceShading::upload(glm::vec3 camera) {
  const std::vector<CellEntry> entries = gatherCells(camera);
  for (DeviceSlot& d : slots_)  // free what is no longer resident at that version
    if (manager_.fieldVersion(d.cell) != d.version) d.version = 0;
  std::vector<gpu::ShadingCellInput> in;
  std::vector<int> slotOf;
  size_t uploaded = 0;
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
  if (!poolReserved_ && !placeholderPool_) {  // nothing resident yet: one-probe slots keep bindings valid
    pass_.reservePool(int(slots_.size()), 1, 1, 1);
    placeholderPool_ = true;
  }
  pass_.setPoolCells(in, slotOf);
  haveCells_ = true;
  return uploaded + in.size() * sizeof(shared::ShadeCell);
}

void DeviceShading::recordShade(VkCommandBuffer cmd, const shared::GpuCamera& camera, int width, int height,
                                float timeOfDayHours, float weather, const gpu::GpuSceneBuffers& scene,
                                const gpu::ShadingOptions& options, const gpu::GBuffer& g,
                                gpu::ShadeOutput& out) {
  if (!haveCells_) fail("DeviceShading: recordShade() before the first upload()");
  worlds::SkyState sky;
  sky.timeOfDayHours = timeOfDayHours;
  sky.overcast = weather;
  pass_.recordView(cmd, worlds::makeSky(sky).params, camera, width, height, scene, options);
  pass_.record(cmd, scene, g, out);
}

worlds::TriangleMesh DeviceShading::worldMesh(glm::ivec2 cell, int ring) {
  const WorldLayout& l = manager_.layout();
  cell = glm::clamp(cell, glm::ivec2(0), l.cells - 1);
  if (!world_) world_ = std::make_unique<worlds::SyntheticWorld>(source_.world());
  // Keep the built meshes of the cells within ring + 1 of this one only: a long flight does not keep every
  // cell it passed, and a step to the next cell still finds the ones it shares.
  std::erase_if(cellMeshes_, [&](const auto& kv) {
    return std::abs(kv.first.first - cell.x) > ring + 1 || std::abs(kv.first.second - cell.y) > ring + 1;
  });
  worlds::TriangleMesh mesh;
  for (int dz = -ring; dz <= ring; ++dz)
    for (int dx = -ring; dx <= ring; ++dx) {
      const worlds::CellCoord c{cell.x + dx, cell.y + dz};
      if (!world_->contains(c)) continue;
      auto it = cellMeshes_.find({c.x, c.z});
      if (it == cellMeshes_.end())
        it = cellMeshes_.emplace(std::pair(c.x, c.z), worlds::buildCell(*world_, c).mesh).first;
      mesh.append(it->second);
    }
  return mesh;
}

const gpu::GpuSceneBuffers& DeviceShading::worldScene(glm::ivec2 cell, int ring) {
  cell = glm::clamp(cell, glm::ivec2(0), manager_.layout().cells - 1);
  if (cell == worldSceneCell_ && ring == worldSceneRing_) return worldScene_;
  const worlds::TriangleMesh mesh = worldMesh(cell, ring);
  worldScene_ = gpu::uploadGpuScene(
      ctx_,
      gpu::buildGpuScene(mesh.positions, mesh.indices, mesh.triangleMaterial, worlds::gpuMaterials(mesh)));
  worldSceneCell_ = cell;
  worldSceneRing_ = ring;
  return worldScene_;
}

void DeviceShading::recordWorldGBuffer(VkCommandBuffer cmd, const shared::GpuCamera& camera, glm::ivec2 cell,
                                       gpu::GBuffer& g, int ring) {
  const gpu::GpuSceneBuffers& scene = worldScene(cell, ring);
  gbuffer_.recordCamera(cmd, camera, g.width, g.height, scene);
  gbuffer_.record(cmd, scene, g);
  gpu::memoryBarrier(cmd);
}

}  // namespace lfgi::streaming
