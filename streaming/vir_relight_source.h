// VirRelightSource: a CellSource decorator whose relight is VIR relighting of the cell's surfels on the
// GPU ("refreshes them through VIR relighting", docs/DESIGN.md §1), for any inner source (CellFileSource,
// SyntheticCellSource, ...). layout / fallback / maxCellBytes / load / setTimeOfDay go to the inner source
// unchanged, except that load() regenerates the loaded field's distance moments from the cell's surfels
// when options.momentsOnLoad (see below); relightInto / relightWeatherInto relight the resident field:
//   1. the cell's surfels (and the probes' relocation offsets) from the SurfelProvider, cached per cell
//      (LRU, at most options.surfelCacheBytes of surfels + offsets; a cell bigger than that is relit
//      uncached);
//   2. gpu::VirFieldRelighter (gpu/vir_probe_field.h) on the current field's grid, resolutions and active
//      probes, for makeSky(options.sky with the relight's time of day and overcast): sun / moon through
//      the VIR shadow map, probe irradiance of the last frame as the next bounce, VIR splat into the
//      probes, without the directly seen discs (as the codec's fields: the shading pass adds them);
//   3. `out` gets grid, resolutions, active and (empty) offsets / normal / albedo exactly as `current`
//      (geometry channels consistent with the cell, same bytes: the staging field never grows), radiance,
//      distance moments and irradiance of every active probe from the relight; inactive probes keep
//      current's values (the inner source's SH fallback evaluation).
// Seed: when `current` is this source's own last VIR result for the cell (a 64-bit hash of its irradiance
// and distance moments is kept per cell), its irradiance seeds frame 1's bounce and options.seededFrames
// frames run; otherwise (a fresh codec load) options.frames frames run from direct light. The records
// cost 16 bytes per relit cell.
//
// A cell whose provider has no surfels: every active probe sees only the sky.
//
// Load (docs/ARCHITECTURE.md, "Where visibility comes from"): the codec carries radiance; the visibility
// its decoder returns is not trusted. With options.momentsOnLoad (default) load() runs the inner load,
// then gpu::VirFieldRelighter::regenerateMoments on the cell's surfels (step 1's cache), so the
// resident field's Chebyshev weights come from the geometry from the first frame on. Costs one VIR frame
// without sun or bounce per load (stats: momentsLoads, momentsMsTotal).
//
// Threading contract: construct and setWeather() on the game thread. setTimeOfDay() forwards to the inner
// source (its contract); load() runs the inner load (its contract), then the moments under the GPU mutex
// below. load(), relightInto() / relightWeatherInto() may be called from several IO
// threads at once (never two for the same cell at once, as the manager guarantees): the GPU work (the
// Vulkan context is one-thread-at-a-time) and the scratch field run under one mutex, so relights are
// serialised; the surfel cache and the per-cell records have their own mutex (held only for look-ups).
// The provider is called from an IO thread, under the GPU mutex (one call at a time). stats() from any
// thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "gpu/context.h"
#include "gpu/vir_probe_field.h"
#include "streaming/cell_source.h"
#include "worlds/sky.h"
#include "worlds/surfels.h"
#include "worlds/synthetic_world.h"

namespace lfgi::streaming {

// One cell's relight input: its surfels (world space; may include neighbours' for their shadows) and the
// relocation offsets of its probes (grid probe count entries, or empty: probes at their lattice points).
struct CellSurfels {
  std::vector<worlds::Surfel> surfels;
  std::vector<glm::vec3> offsets;
  size_t bytes() const {
    return surfels.size() * sizeof(worlds::Surfel) + offsets.size() * sizeof(glm::vec3);
  }
};
// Throws lfgi::Error naming the cell / file when the cell's surfels cannot be had.
using SurfelProvider = std::function<CellSurfels(glm::ivec2 cell)>;

// The world directory's cells (worlds/world_cells.h): WORLD/cells/cell_X_Z.surfels (Draco) and
// cell_X_Z.probes when `lfgi world generate --all` wrote them, else worlds::buildCell of the manifest's
// world (deterministic: the same surfels and probe placement the bake used; costs the cell's generation,
// ~0.1-1 s, once per cached cell). Reads world.json at construction (lfgi::Error naming it).
SurfelProvider worldSurfelProvider(const std::filesystem::path& worldDir);
// A world known by its manifest alone (served over HTTP: CellFileSource::world()): every cell is
// worlds::buildCell of it, the same surfels and probe placement the bake used.
SurfelProvider worldSurfelProvider(const worlds::WorldParams& world);

// The cell's probe offsets with the surfels of the cell and its 8 neighbours (those inside the layout), so
// a border probe's moments see the walls next door (what `lfgi render --probes codec` splats). inner is
// called once per cell asked for, 9 times in all.
SurfelProvider neighbourhoodSurfelProvider(SurfelProvider inner, const WorldLayout& layout);

struct VirRelightOptions {
  worlds::SkyState sky{};  // latitude, day, turbidity; time of day and overcast come per relight
  float weather = 0.0f;    // overcast for relightInto without one (setWeather changes it)
  int frames = 3;          // relight frames from a codec field: direct + 2 bounces
  int seededFrames = 2;    // frames when seeded by the previous VIR result
  float maxRange = 64.0f;  // m, VIR splat range
  size_t surfelCacheBytes = size_t(256) << 20;
  // Chebyshev weights in the surfels' gather of probe irradiance (gpu::RelightOptions::chebyshev). On
  // (default, as the bake's VIR probes): no bounce leaks through walls, but measured on a ground plane
  // under probes it also hides most of the plane from the probes (bounce light -37 % in the downward
  // irradiance, -9 % without it; vir_relight_source_test.cpp): a known defect of the gather.
  bool gatherChebyshev = true;
  // Regenerate a loaded field's distance moments from the cell's surfels (see the header comment).
  bool momentsOnLoad = true;
  // Relight by VIR (steps 1-3 above). False: the inner source relights (its own time-of-day keys) and, with
  // momentsOnLoad, the relit field's moments are regenerated as at load (the installed runtime's choice).
  bool relightByVir = true;
  // Throws lfgi::Error naming the bad field.
  void validate() const;
};

struct VirRelightStats {
  uint64_t relights = 0, seeded = 0, cacheHits = 0, cacheMisses = 0, momentsLoads = 0;
  double relightMsTotal = 0.0, gpuMsTotal = 0.0, providerMsTotal = 0.0, momentsMsTotal = 0.0;
  size_t cacheBytes = 0;   // surfels + offsets cached now
  size_t recordBytes = 0;  // per-cell seed records
};

class VirRelightSource final : public CellSource {
 public:
  // inner and ctx must outlive this. Throws lfgi::Error for bad options or a device without what VIR
  // needs (64-bit atomics).
  VirRelightSource(CellSource& inner, gpu::Context& ctx, VirRelightOptions options, SurfelProvider provider);
  ~VirRelightSource() override;

  WorldLayout layout() const override { return inner_.layout(); }
  ShL1 fallback(glm::ivec2 cell) const override { return inner_.fallback(cell); }
  bool fallbackFollowsTimeOfDay() const override { return inner_.fallbackFollowsTimeOfDay(); }
  size_t maxCellBytes() const override { return inner_.maxCellBytes(); }
  void load(glm::ivec2 cell, ProbeField& out) override;
  void setTimeOfDay(float hours) override { inner_.setTimeOfDay(hours); }
  void setWeather(float overcast);  // [0, 1], lfgi::Error otherwise
  void relightInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                   float timeOfDayHours) override {
    relightWeatherInto(cell, current, out, timeOfDayHours, weather_.load());
  }
  void relightWeatherInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out, float timeOfDayHours,
                          float weather) override;

  VirRelightStats stats() const;

 private:
  std::shared_ptr<const CellSurfels> surfelsOf(glm::ivec2 cell);
  // load()'s second stage: out's distance moments from the cell's surfels (options_.momentsOnLoad).
  void regenerateMoments(glm::ivec2 cell, ProbeField& out);
  // cs's offsets when they match a grid of `count` probes, else none (warned).
  static std::span<const glm::vec3> offsetsFor(glm::ivec2 cell, const CellSurfels& cs, size_t count);

  CellSource& inner_;
  VirRelightOptions options_;
  SurfelProvider provider_;
  std::atomic<float> weather_{0.0f};

  std::mutex gpuMutex_;  // the relighter, the scratch field
  std::unique_ptr<gpu::VirFieldRelighter> relighter_;
  ProbeField scratch_;
  gpu::VirFieldStats fieldStats_;

  mutable std::mutex cacheMutex_;                                          // cache, records, stats
  std::list<std::pair<int64_t, std::shared_ptr<const CellSurfels>>> lru_;  // front: most recent
  size_t cacheBytes_ = 0;
  std::map<int64_t, uint64_t> records_;  // per cell: lightingHash of its last relight
  VirRelightStats stats_;
};

// 64-bit FNV-1a of a field's irradiance and distance arrays (the seed's identity check).
uint64_t lightingHash(const ProbeField& field);

}  // namespace lfgi::streaming
