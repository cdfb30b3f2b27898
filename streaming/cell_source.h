// Where the streaming manager gets cells from. A CellSource knows the world's cell layout, hands out
// every cell's coarse fallback up front, and loads (reads + validates + decodes) one cell's full light
// field on request. Implementations: SyntheticCellSource (below: an analytic light field, for tests and
// the fly-through benchmark before cells are baked), and CellFileSource (streaming/cell_file_source.h:
// baked OpenVDB cell files, generator or SH-only cells).
//
// Threading contract: layout(), fallback(), fallbackFollowsTimeOfDay(), maxCellBytes() and setTimeOfDay()
// are called from the game thread only;
// load() and relightInto() are called concurrently from the manager's IO threads (several at once, never
// two for the same cell at the same time) and must be thread-safe; with ioThreads = 0 the manager calls
// them on the game thread inside update(). load() throws lfgi::Error on a bad cell (the
// manager logs it, keeps the fallback and never asks for that cell again).
#pragma once

#include <atomic>
#include <cstdint>
#include <set>
#include <utility>

#include <glm/glm.hpp>

#include "core/probe_field.h"
#include "core/sh.h"

namespace lfgi::streaming {

struct WorldLayout {
  glm::vec2 originXZ{0.0f};  // world-space x, z of cell (0, 0)'s min corner
  float cellSize = 64.0f;    // metres
  glm::ivec2 cells{1, 1};    // cells along x and z

  bool contains(glm::ivec2 c) const { return c.x >= 0 && c.y >= 0 && c.x < cells.x && c.y < cells.y; }
  // The cell owning world point (x, z) (half-open boxes; may be outside the world).
  glm::ivec2 cellOf(glm::vec3 p) const {
    return glm::ivec2(glm::floor((glm::vec2(p.x, p.z) - originXZ) / cellSize));
  }
  glm::vec2 cellMin(glm::ivec2 c) const { return originXZ + glm::vec2(c) * cellSize; }
  // Distance in the xz plane from p to the nearest point of cell c's square (0 inside).
  float distanceToCell(glm::vec3 p, glm::ivec2 c) const;
  int64_t linear(glm::ivec2 c) const { return int64_t(c.y) * cells.x + c.x; }
};

class CellSource {
 public:
  virtual ~CellSource() = default;
  virtual WorldLayout layout() const = 0;
  // Always-resident coarse representation: the cell's mean incident radiance as SH L1 (its irradiance
  // for normal n is shIrradiance(fallback, n)). A few dozen bytes per cell.
  // May follow the time of day last set (setTimeOfDay): see fallbackFollowsTimeOfDay.
  virtual ShL1 fallback(glm::ivec2 cell) const = 0;
  // True when fallback() depends on the time of day set by setTimeOfDay (CellFileSource with several
  // lighting keys): StreamingManager then re-reads every cell's fallback when the time of day moves.
  // Default false (fallbacks read once). Game thread.
  virtual bool fallbackFollowsTimeOfDay() const { return false; }
  // Upper bound of ProbeField::bytes() of any loaded cell: the size of one resident slot.
  virtual size_t maxCellBytes() const = 0;
  // Loads cell `cell` into `out`, reusing out's capacity (no allocation when it fits).
  virtual void load(glm::ivec2 cell, ProbeField& out) = 0;
  // The lighting loads started from now on decode under (sources whose cells depend on the time of day:
  // the generator's conditioning). StreamingManager::update calls it first every frame. Default: ignored.
  virtual void setTimeOfDay(float /*hours*/) {}
  // Relight of a resident cell: `out` (a staging field, reusing its capacity) receives the cell's field
  // under time of day `timeOfDayHours`, the same as a fresh load at that time would give. `current` is the
  // resident field (read-only: the game thread keeps shading with it meanwhile). Throws lfgi::Error like
  // load() (the manager logs it and keeps the old lighting). Default: load(cell, out), which decodes under
  // the time of day last set (setTimeOfDay): right for sources whose cells do not depend on it.
  virtual void relightInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                           float timeOfDayHours) {
    (void)current;
    (void)timeOfDayHours;
    load(cell, out);
  }
  // The relight the manager calls: as relightInto, for a time of day and a weather (overcast in [0, 1],
  // FrameInput::weather). Default: relightInto(cell, current, out, timeOfDayHours) (sources whose cells
  // do not follow the weather: the codec's conditioning weather is fixed per source). Same threading.
  virtual void relightWeatherInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                                  float timeOfDayHours, float weather) {
    (void)weather;
    relightInto(cell, current, out, timeOfDayHours);
  }
};

// An analytic light field: every cell has the same probe lattice (spacing, layers), and a probe's
// irradiance map holds E(p, n) = base(p) * (1 + 0.5 n.y) (rgb tinted per channel), base smooth in p, so
// exact values are known anywhere and neighbouring cells agree on shared lattice points. Radiance and
// distance maps are filled with matching constants. Options inject slow loads and corrupt cells.
struct SyntheticSourceOptions {
  WorldLayout layout{{0.0f, 0.0f}, 64.0f, {64, 64}};
  float probeSpacing = 8.0f;  // divides cellSize
  int layers = 3;             // probe layers from y = 0.5 m
  int resolution = 4;         // radiance / distance maps
  int irradianceResolution = 4;
  int loadDelayUs = 0;  // simulated IO + decode time per load (and per relight)
  // Time-of-day dependence (tests of relight): every value is scaled by 1 + timeOfDayGain * (h - 12) / 12
  // for the time of day h a load decodes under (setTimeOfDay) or a relight targets. 0: independent.
  float timeOfDayGain = 0.0f;
  std::set<std::pair<int, int>> corruptCells;  // load() throws for these
};

class SyntheticCellSource final : public CellSource {
 public:
  explicit SyntheticCellSource(SyntheticSourceOptions options);
  WorldLayout layout() const override { return options_.layout; }
  ShL1 fallback(glm::ivec2 cell) const override;
  size_t maxCellBytes() const override { return cellBytes_; }
  void load(glm::ivec2 cell, ProbeField& out) override;
  void setTimeOfDay(float hours) override { timeOfDay_.store(hours); }
  // Fills `out` as load() would at timeOfDayHours (counted in relights(), not loads()).
  void relightInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                   float timeOfDayHours) override;

  // The exact field the probes sample: E(p, n) (at noon, or with timeOfDayGain = 0).
  static glm::vec3 exactIrradiance(glm::vec3 p, glm::vec3 n);
  // The time-of-day scale of every value (see timeOfDayGain).
  float timeOfDayScale(float hours) const { return 1.0f + options_.timeOfDayGain * (hours - 12.0f) / 12.0f; }
  uint64_t loads() const { return loads_.load(); }
  uint64_t relights() const { return relights_.load(); }

 private:
  SyntheticSourceOptions options_;
  size_t cellBytes_ = 0;
  void fill(glm::ivec2 cell, ProbeField& out, float hours) const;

  std::atomic<uint64_t> loads_{0}, relights_{0};
  std::atomic<float> timeOfDay_{12.0f};
};

}  // namespace lfgi::streaming
