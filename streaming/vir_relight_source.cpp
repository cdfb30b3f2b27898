#include "streaming/vir_relight_source.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/octahedral.h"
#include "worlds/cell_probe_file.h"
#include "worlds/world_cells.h"

namespace lfgi::streaming {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

constexpr size_t kMaxRecords = 512;  // seed records kept (cells); the oldest is dropped beyond

// Geometry as the cell holds it: same active flags, offsets and optional channels; inactive probes keep
// current's values.
void keepGeometryAndInactive(const ProbeField& current, ProbeField& out) {
  const size_t count = size_t(current.probeCount());
  const int n = current.resolution, m = current.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  out.active.assign(current.active.begin(), current.active.end());
  out.offsets.assign(current.offsets.begin(), current.offsets.end());
  out.normal.assign(current.normal.begin(), current.normal.end());
  out.albedo.assign(current.albedo.begin(), current.albedo.end());
  for (size_t i = 0; i < count; ++i) {
    if (current.isActive(int64_t(i))) continue;
    std::copy_n(current.radiance.begin() + ptrdiff_t(i * n2 * 3), n2 * 3,
                out.radiance.begin() + ptrdiff_t(i * n2 * 3));
    std::copy_n(current.distance.begin() + ptrdiff_t(i * n2 * 2), n2 * 2,
                out.distance.begin() + ptrdiff_t(i * n2 * 2));
    std::copy_n(current.irradiance.begin() + ptrdiff_t(i * m2 * 3), m2 * 3,
                out.irradiance.begin() + ptrdiff_t(i * m2 * 3));
  }
}

}  // namespace

uint64_t lightingHash(const ProbeField& f) {
  uint64_t h = fnv1aSpan(kFnv1aOffset, f.irradiance);
  // The moments change less often than irradiance; every 7th float keeps the check cheap.
  for (size_t i = 0; i < f.distance.size(); i += 7) h = fnv1aValue(h, f.distance[i]);
  return h;
}

namespace {

CellSurfels generatedSurfels(const worlds::SyntheticWorld& world, worlds::CellCoord c) {
  worlds::BuiltCell built = worlds::buildCell(world, c);
  CellSurfels out;
  out.surfels = std::move(built.surfels);
  out.offsets = std::move(built.probes.offsets);
  return out;
}

}  // namespace

SurfelProvider worldSurfelProvider(const std::filesystem::path& worldDir) {
  auto world = std::make_shared<worlds::SyntheticWorld>(worlds::readWorldManifest(worldDir));
  return [world, worldDir](glm::ivec2 cell) {
    const worlds::CellCoord c{cell.x, cell.y};
    const std::filesystem::path surfelFile =
        worldDir / "cells" / fmt::format("cell_{}_{}.surfels", cell.x, cell.y);
    if (!std::filesystem::exists(surfelFile)) return generatedSurfels(*world, c);
    CellSurfels out;
    out.surfels = worlds::decodeSurfels(readFileBytes(surfelFile), surfelFile.string());
    if (auto probes = worlds::readCellProbes(worldDir, c)) out.offsets = std::move(probes->offsets);
    return out;
  };
}

SurfelProvider worldSurfelProvider(const worlds::WorldParams& params) {
  auto world = std::make_shared<worlds::SyntheticWorld>(params);
  return [world](glm::ivec2 cell) { return generatedSurfels(*world, {cell.x, cell.y}); };
}

SurfelProvider neighbourhoodSurfelProvider(SurfelProvider inner, const WorldLayout& layout) {
  return [inner = std::move(inner), layout](glm::ivec2 cell) {
    CellSurfels out = inner(cell);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx) {
        const glm::ivec2 c = cell + glm::ivec2(dx, dz);
        if ((dx == 0 && dz == 0) || !layout.contains(c)) continue;
        const CellSurfels next = inner(c);
        out.surfels.insert(out.surfels.end(), next.surfels.begin(), next.surfels.end());
      }
    return out;
  };
}

void VirRelightOptions::validate() const {
  worlds::validateSkyState(sky);
  if (!(weather >= 0.0f && weather <= 1.0f)) fail("VirRelightOptions.weather = {} outside [0, 1]", weather);
  if (frames < 1 || frames > 64) fail("VirRelightOptions.frames = {} outside [1, 64]", frames);
  if (seededFrames < 1 || seededFrames > 64)
    fail("VirRelightOptions.seededFrames = {} outside [1, 64]", seededFrames);
  if (!(maxRange > 0.0f)) fail("VirRelightOptions.maxRange = {} must be > 0", maxRange);
}

VirRelightSource::VirRelightSource(CellSource& inner, gpu::Context& ctx, VirRelightOptions options,
                                   SurfelProvider provider)
    : inner_(inner), options_(std::move(options)), provider_(std::move(provider)) {
  options_.validate();
  if (!provider_) fail("VirRelightSource: no surfel provider");
  weather_.store(options_.weather);
  relighter_ = std::make_unique<gpu::VirFieldRelighter>(ctx);
}

VirRelightSource::~VirRelightSource() = default;

void VirRelightSource::setWeather(float overcast) {
  if (!(overcast >= 0.0f && overcast <= 1.0f))
    fail("VirRelightSource: weather (overcast) {} outside [0, 1]", overcast);
  weather_.store(overcast);
}

VirRelightStats VirRelightSource::stats() const {
  std::lock_guard lock(cacheMutex_);
  VirRelightStats s = stats_;
  s.cacheBytes = cacheBytes_;
  s.recordBytes = records_.size() * (sizeof(int64_t) + sizeof(uint64_t));
  return s;
}

// Under gpuMutex_ (one provider call at a time).
std::shared_ptr<const CellSurfels> VirRelightSource::surfelsOf(glm::ivec2 cell) {
  const int64_t key = inner_.layout().linear(cell);
  {
    std::lock_guard lock(cacheMutex_);
    for (auto it = lru_.begin(); it != lru_.end(); ++it)
      if (it->first == key) {
        lru_.splice(lru_.begin(), lru_, it);
        ++stats_.cacheHits;
        return lru_.front().second;
      }
  }
  const auto t0 = Clock::now();
  auto s = std::make_shared<const CellSurfels>(provider_(cell));
  const double ms = msSince(t0);
  std::lock_guard lock(cacheMutex_);
  ++stats_.cacheMisses;
  stats_.providerMsTotal += ms;
  if (s->bytes() > options_.surfelCacheBytes) return s;  // relit uncached
  while (!lru_.empty() && cacheBytes_ + s->bytes() > options_.surfelCacheBytes) {
    cacheBytes_ -= lru_.back().second->bytes();
    lru_.pop_back();
  }
  lru_.emplace_front(key, s);
  cacheBytes_ += s->bytes();
  return s;
}

std::span<const glm::vec3> VirRelightSource::offsetsFor(glm::ivec2 cell, const CellSurfels& cs,
                                                        size_t count) {
  if (cs.offsets.size() == count) return cs.offsets;
  if (!cs.offsets.empty())
    spdlog::warn("streaming: cell {},{}: {} probe offsets for a grid of {} probes, relit at lattice points",
                 cell.x, cell.y, cs.offsets.size(), count);
  return {};
}

void VirRelightSource::load(glm::ivec2 cell, ProbeField& out) {
  inner_.load(cell, out);
  regenerateMoments(cell, out);
}

void VirRelightSource::regenerateMoments(glm::ivec2 cell, ProbeField& out) {
  if (!options_.momentsOnLoad || out.probeCount() == 0) return;
  const auto t0 = Clock::now();
  std::lock_guard gpuLock(gpuMutex_);
  std::shared_ptr<const CellSurfels> cs = surfelsOf(cell);
  gpu::VirFieldOptions vo;
  vo.maxRange = options_.maxRange;
  vo.noSurfelsIsSky = true;
  vo.checkInterrupt = false;
  gpu::VirFieldStats st;
  const std::span<const glm::vec3> offsets = offsetsFor(cell, *cs, size_t(out.probeCount()));
  relighter_->regenerateMoments(cs->surfels, offsets, vo, out, scratch_, &st);
  // The probes sit where their moments were seen (the decode's field has no offsets): shading reads
  // probePosition, so it must be the splat's position.
  out.offsets.assign(offsets.begin(), offsets.end());
  const double ms = msSince(t0);
  spdlog::debug("streaming: VIR moments of cell {},{}: {} probes, {:.0f} ms", cell.x, cell.y, st.probes, ms);
  std::lock_guard lock(cacheMutex_);
  ++stats_.momentsLoads;
  stats_.momentsMsTotal += ms;
}

void VirRelightSource::relightWeatherInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                                          float timeOfDayHours, float weather) {
  const WorldLayout lay = inner_.layout();
  if (!lay.contains(cell))
    fail("cell {},{}: outside the {}x{} world", cell.x, cell.y, lay.cells.x, lay.cells.y);
  if (!(weather >= 0.0f && weather <= 1.0f))
    fail("cell {},{}: weather (overcast) {} outside [0, 1]", cell.x, cell.y, weather);
  if (!options_.relightByVir) {
    inner_.relightWeatherInto(cell, current, out, timeOfDayHours, weather);
    regenerateMoments(cell, out);  // the inner decode's moments are not trusted, as at load
    return;
  }
  const auto t0 = Clock::now();
  worlds::SkyState state = options_.sky;
  state.timeOfDayHours = std::clamp(std::fmod(std::fmod(timeOfDayHours, 24.0f) + 24.0f, 24.0f), 0.0f, 24.0f);
  state.overcast = weather;
  const worlds::SkyModel sky = worlds::makeSky(state);
  const int64_t key = lay.linear(cell);
  const size_t count = size_t(current.probeCount());
  const int n = current.resolution, m = current.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  if (current.irradiance.size() != count * m2 * 3 || current.distance.size() != count * n2 * 2 ||
      current.radiance.size() != count * n2 * 3)
    fail("cell {},{}: the resident field's arrays do not match its grid ({} probes, n {}, m {})", cell.x,
         cell.y, count, n, m);

  std::lock_guard gpuLock(gpuMutex_);
  std::shared_ptr<const CellSurfels> cs = surfelsOf(cell);
  const std::span<const glm::vec3> offsets = offsetsFor(cell, *cs, count);

  // Seed: current is our own last result for this cell (no discs in it: its irradiance is the bounce).
  const ProbeField* seed = nullptr;
  {
    std::lock_guard lock(cacheMutex_);
    auto it = records_.find(key);
    if (it != records_.end() && it->second == lightingHash(current)) seed = &current;
  }

  gpu::VirFieldOptions vo;
  vo.resolution = n;
  vo.irradianceResolution = m;
  vo.frames = seed ? options_.seededFrames : options_.frames;
  vo.maxRange = options_.maxRange;
  vo.storeOffsets = false;
  vo.noSurfelsIsSky = true;
  vo.checkInterrupt = false;
  vo.relight.chebyshev = options_.gatherChebyshev;
  relighter_->run(cs->surfels, current.grid, offsets, current.active, sky.params, vo, out, seed,
                  &fieldStats_);
  keepGeometryAndInactive(current, out);
  spdlog::info(
      "streaming: VIR relight of cell {},{} at {:.2f} h overcast {:.2f}: {} probes, {} surfels, {} "
      "frame(s){}, "
      "{:.0f} ms ({:.0f} ms on the device)",
      cell.x, cell.y, timeOfDayHours, weather, fieldStats_.probes, fieldStats_.surfels, vo.frames,
      seed ? " seeded" : "", msSince(t0), fieldStats_.gpuMs);
  const uint64_t hash = lightingHash(out);
  std::lock_guard lock(cacheMutex_);
  records_.insert_or_assign(key, hash);
  while (records_.size() > kMaxRecords) records_.erase(records_.begin());  // bounded (lowest index first)
  ++stats_.relights;
  stats_.seeded += seed ? 1 : 0;
  stats_.gpuMsTotal += fieldStats_.gpuMs;
  stats_.relightMsTotal += msSince(t0);
}

}  // namespace lfgi::streaming
