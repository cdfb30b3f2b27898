// DeviceShading: the probe shading pass (gpu/probe_shading_pass.h) fed from a StreamingManager over a
// CellFileSource, on a Vulkan device; what lfgi::VulkanShading (include/lfgi/runtime_vulkan.h) runs on a
// host's device and what `lfgi fly --render` draws its frames with.
//
// The device holds a pool of as many slots as the manager has (at most one per world cell), each sized for
// the world's largest cell. Stages of upload(camera): gather the cells within keepRadius + one cell of the
// camera in their streaming states (resident with its fade, or fallback-only with its lattice box), free
// the slots of cells no longer resident at the version they hold, upload the maps of cells newly resident
// or relit (StreamingManager::fieldVersion) into free slots, then send the cell table (fades, fallbacks,
// boxes) alone, 160 B per cell.
//
// Game thread: upload() reads the manager's resident fields, so it runs between manager updates, and waits
// for its copies. recordShade() / recordWorldGBuffer() only record; the recorded work reads the pool until
// it completes, so the caller waits for it before the next upload().
#pragma once

#include <glm/glm.hpp>

#include <climits>
#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "gpu/gbuffer_pass.h"
#include "gpu/probe_shading_pass.h"
#include "streaming/cell_file_source.h"
#include "streaming/streaming_manager.h"
#include "worlds/mesh.h"
#include "worlds/synthetic_world.h"

namespace lfgi::streaming {

class DeviceShading {
 public:
  // ctx, manager and source outlive this. keepRadius: the manager's (StreamingConfig::keepRadius).
  DeviceShading(gpu::Context& ctx, const StreamingManager& manager, const CellFileSource& source,
                float keepRadius);

  // Brings the device's light field up to date around camera (see the stages above); returns the bytes
  // uploaded (maps of new or relit cells plus the cell table).
  size_t upload(glm::vec3 camera);
  bool uploaded() const { return haveCells_; }
  // Records the shading of g seen from camera into out. scene: what shadow and AO rays trace (an empty
  // scene with options.direct and sunShadows off, as the runtime); the sky at timeOfDayHours / weather.
  void recordShade(VkCommandBuffer cmd, const shared::GpuCamera& camera, int width, int height,
                   float timeOfDayHours, float weather, const gpu::GpuSceneBuffers& scene,
                   const gpu::ShadingOptions& options, const gpu::GBuffer& g, gpu::ShadeOutput& out);
  // The world's own synthetic geometry: the cells within `ring` cells of `cell` (clamped into the world;
  // ring 1: 3 x 3), built from the source's manifest (worlds::buildCell; each cell's mesh kept while it
  // stays within ring + 1 of the cell asked for) and kept until another cell or ring is asked for.
  const gpu::GpuSceneBuffers& worldScene(glm::ivec2 cell, int ring = 1);
  // The same cells' meshes merged (what worldScene uploads; a path tracer's scene of the same view).
  worlds::TriangleMesh worldMesh(glm::ivec2 cell, int ring = 1);
  // Records a G-buffer of worldScene(cell, ring) seen from camera into g, then a memory barrier for the
  // shading.
  void recordWorldGBuffer(VkCommandBuffer cmd, const shared::GpuCamera& camera, glm::ivec2 cell,
                          gpu::GBuffer& g, int ring = 1);
  // An empty scene (shading that traces nothing).
  const gpu::GpuSceneBuffers& noScene() const { return noScene_; }
  // Device memory held for the light field now (probe maps, cells), bytes.
  size_t deviceBytes() const { return pass_.deviceBytes(); }

 private:
  // One cell the pass sees, in its streaming state.
  struct CellEntry {
    glm::ivec2 cell{0};
    const ProbeField* field = nullptr;  // resident: its field; else shaded from the fallback alone
    uint64_t version = 0;               // StreamingManager::fieldVersion (0: not resident)
    float fade = 0.0f;
    ShL1 fallback{};
    ProbeGrid box;  // fallback-only: the cell's probe lattice (its file's, or a valid cell's moved here)
  };
  // What each device slot holds (cell and field version; version 0: free).
  struct DeviceSlot {
    glm::ivec2 cell{0};
    uint64_t version = 0;
  };
  std::vector<CellEntry> gatherCells(glm::vec3 camera) const;
  ProbeGrid boxOf(glm::ivec2 c) const;
  int slotFor(const CellEntry& e, size_t& uploaded);

  gpu::Context& ctx_;
  const StreamingManager& manager_;
  const CellFileSource& source_;
  float keepRadius_;
  gpu::ProbeShadingPass pass_;
  gpu::GBufferPass gbuffer_;
  gpu::GpuSceneBuffers noScene_;
  std::unique_ptr<worlds::SyntheticWorld> world_;
  gpu::GpuSceneBuffers worldScene_;
  glm::ivec2 worldSceneCell_{INT_MIN, INT_MIN};
  int worldSceneRing_ = 0;
  std::map<std::pair<int, int>, worlds::TriangleMesh> cellMeshes_;
  std::vector<DeviceSlot> slots_;
  int64_t probesPerSlot_ = 0;
  bool poolReserved_ = false, placeholderPool_ = false, haveCells_ = false;
  ProbeGrid templateBox_;  // a valid cell's lattice, for cells without a file
  glm::ivec2 templateCell_{0};
};

}  // namespace lfgi::streaming
