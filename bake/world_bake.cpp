#include "bake/world_bake.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include <fmt/format.h>

#include "bake/embree_scene.h"
#include "core/error.h"
#include "core/half.h"
#include "core/progress.h"
#include "core/sh.h"

namespace lfgi::bake {

namespace fs = std::filesystem;

void WorldBakeSettings::validate() const {
  if (!(errorTarget >= 0.001 && errorTarget <= 1.0)) fail("bake error target {} outside [0.001, 1]", errorTarget);
  if (resolution != 8 && resolution != 16 && resolution != 32) fail("bake resolution {}: expected 8, 16 or 32", resolution);
  if (spp < 1 || bounces < 0 || maxSteps < 1 || threads < 1)
    fail("bake settings: spp {} >= 1, bounces {} >= 0, max steps {} >= 1, threads {} >= 1 required", spp, bounces,
         maxSteps, threads);
  for (int w : modelWidths)
    if (w != 8 && w != 16 && w != 32 && w != 64) fail("bake model width {}: expected 8, 16, 32 or 64", w);
  for (int z : modelLatents)
    if (z != 4 && z != 8 && z != 16) fail("bake model latent size {}: expected 4, 8 or 16", z);
  (void)parseLightingKeys(keys);
}

std::vector<LightingKeySpec> parseLightingKeys(const std::string& text) {
  std::vector<LightingKeySpec> keys;
  size_t start = 0;
  while (start <= text.size()) {
    size_t end = text.find(',', start);
    if (end == std::string::npos) end = text.size();
    std::string item = text.substr(start, end - start);
    float t = 0.0f, w = 0.0f;
    char colon = 0, extra = 0;
    int n = std::sscanf(item.c_str(), "%f%c%f%c", &t, &colon, &w, &extra);
    if (!((n == 1) || (n == 3 && colon == ':')) || !(t >= 0.0f && t <= 24.0f) || !(w >= 0.0f && w <= 1.0f))
      fail("--keys '{}': expected HOURS[:OVERCAST],... with hours in [0, 24] and overcast in [0, 1], got '{}'", text, item);
    keys.push_back({t, n == 3 ? w : 0.0f});
    start = end + 1;
  }
  return keys;
}

CaptureOptions worldBakeCaptureOptions(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings) {
  CaptureOptions capture;
  capture.resolution = settings.resolution;
  capture.irradianceResolution = std::max(2, settings.resolution / 2);
  capture.samplesPerTexel = settings.spp;
  capture.maxBounces = settings.bounces;
  capture.seed = settings.seed;
  // A miss records this distance: a few cells, not the 10 km default, so the generator's distance range
  // (1.5 x the 95th percentile) keeps centimetre precision where visibility needs it.
  capture.maxDistance = float(4.0 * world.cellSizeM());
  validateCaptureOptions(capture);
  return capture;
}

fs::path cellFilePath(const fs::path& outDir, worlds::CellCoord c) {
  return outDir / "cells" / fmt::format("cell_{}_{}.vdb", c.x, c.z);
}

std::vector<worlds::CellCoord> arrayShare(const std::vector<worlds::CellCoord>& cells, int index, int size) {
  if (size < 1 || index < 0 || index >= size) fail("--array-index {} outside [0, --array-size {})", index, size);
  const size_t n = cells.size(), a = n * size_t(index) / size_t(size), b = n * size_t(index + 1) / size_t(size);
  return {cells.begin() + ptrdiff_t(a), cells.begin() + ptrdiff_t(b)};
}

namespace {

// Indices of `keys` (LightingKey or LightingKeySpec) in the order the cell file stores its fallback keys:
// sorted by (hours, overcast), a key repeated in --keys once.
template <typename Key>
std::vector<size_t> fileKeyOrder(const std::vector<Key>& keys) {
  std::vector<size_t> order(keys.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  auto less = [&](size_t a, size_t b) {
    const Key &x = keys[a], &y = keys[b];
    return x.timeOfDayHours < y.timeOfDayHours || (x.timeOfDayHours == y.timeOfDayHours && x.weather < y.weather);
  };
  std::stable_sort(order.begin(), order.end(), less);
  order.erase(std::unique(order.begin(), order.end(), [&](size_t a, size_t b) { return !less(a, b); }), order.end());
  return order;
}

// SH L1 radiance of the whole cell per lighting key: the mean of the probes' projections (FP16) of the
// captured radiance maps, i.e. what the generator is trained on (sky, bounces and the capture's sun /
// moon disc deposits), so the fallback at a key is comparable to the decoded cell there. Keys sorted by
// (hours, overcast) as the cell file requires; a key repeated in --keys is stored once.
CellFallback fallbackOf(const GeneratorTrainingSet& set) {
  CellFallback f;
  f.kind = CellFallback::Kind::PerCell;
  f.keyHours.clear();
  f.keyOvercast.clear();
  for (size_t i : fileKeyOrder(set.keys)) {
    const LightingKey& key = set.keys[i];
    ShL1 mean;
    for (const ProbeCapture& p : key.probes) {
      ShL1 sh = shProject<4>(p.radiance, p.resolution);
      for (int k = 0; k < 4; ++k) mean.c[size_t(k)] += sh.c[size_t(k)] / float(key.probes.size());
    }
    f.keyHours.push_back(key.timeOfDayHours);
    f.keyOvercast.push_back(key.weather);
    for (int k = 0; k < 4; ++k)
      for (int c = 0; c < 3; ++c) f.shHalf.push_back(floatToHalfClamped(mean.c[size_t(k)][c]));
  }
  return f;
}

// An empty cell's fallback: dark at every key (same keys as the other cells).
CellFallback darkFallback(const std::vector<LightingKeySpec>& keys) {
  CellFallback f;
  f.kind = CellFallback::Kind::PerCell;
  f.keyHours.clear();
  f.keyOvercast.clear();
  for (size_t i : fileKeyOrder(keys)) {
    f.keyHours.push_back(keys[i].timeOfDayHours);
    f.keyOvercast.push_back(keys[i].weather);
  }
  f.shHalf.assign(12 * f.keyHours.size(), floatToHalfClamped(0.0f));
  return f;
}

uint64_t hashInputs(const worlds::SyntheticWorld& world, worlds::CellCoord c, const worlds::BuiltCell& cell,
                    const uint64_t (&neighbours)[9], const WorldBakeSettings& settings) {
  const CaptureOptions capture = worldBakeCaptureOptions(world, settings);
  ContentHasher hasher;
  // v3: cell file version 2 (one fallback per lighting key), so an incremental bake rewrites v1 cells.
  hasher.add(std::string("lfgi-bake-v3")).addValue(world.params().seed).addValue(c.x).addValue(c.z);
  for (uint64_t h : neighbours) hasher.addValue(h);
  hasher.addValue(cell.stats.meshHash).addValue(cell.probes.grid.origin).addValue(cell.probes.grid.spacing);
  hasher.addValue(cell.probes.grid.dims);
  hasher.add(std::as_bytes(std::span(cell.probes.flags))).add(std::as_bytes(std::span(cell.probes.offsets)));
  hasher.addValue(capture.resolution).addValue(capture.samplesPerTexel).addValue(capture.maxBounces);
  hasher.addValue(capture.seed).addValue(capture.maxDistance).add(settings.keys).addValue(settings.errorTarget);
  hasher.addValue(settings.maxSteps).addValue(settings.threads);
  hasher.add(std::string("models"));
  for (int w : settings.modelWidths) hasher.addValue(w);
  hasher.add(std::string("/"));
  for (int z : settings.modelLatents) hasher.addValue(z);
  return hasher.digest();
}

}  // namespace

CellBakeInputs prepareCellBake(const worlds::SyntheticWorld& world, worlds::CellCoord c, const WorldBakeSettings& settings) {
  settings.validate();
  if (!world.contains(c)) fail("bake: cell {},{} outside the world ({} x {} cells)", c.x, c.z, world.cellsX(), world.cellsZ());
  CellBakeInputs in;
  in.cell = c;
  in.built = worlds::buildCell(world, c);
  in.sceneMesh = in.built.mesh;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dx = -1; dx <= 1; ++dx) {
      const worlds::CellCoord n{c.x + dx, c.z + dz};
      uint64_t& h = in.neighbourMeshHashes[(dz + 1) * 3 + (dx + 1)];
      if (!dx && !dz) {
        h = in.built.stats.meshHash;
      } else if (world.contains(n)) {
        worlds::TriangleMesh m = world.generateCell(n);
        h = m.contentHash();
        in.sceneMesh.append(m);
      }
    }
  in.inputHash = hashInputs(world, c, in.built, in.neighbourMeshHashes, settings);
  return in;
}

uint64_t cellInputHash(const worlds::SyntheticWorld& world, worlds::CellCoord c, const WorldBakeSettings& settings) {
  return prepareCellBake(world, c, settings).inputHash;
}

CellFile bakeCell(const worlds::SyntheticWorld& world, CellBakeInputs in, const WorldBakeSettings& settings,
                  CellBakeReport* report) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const CaptureOptions capture = worldBakeCaptureOptions(world, settings);
  const std::vector<LightingKeySpec> keys = parseLightingKeys(settings.keys);
  ModelSizingOptions sizing;
  sizing.irradianceErrorTarget = settings.errorTarget;
  sizing.noNetworkKinds = {CellModelKind::kShL1};  // the cell file stores one SH L1 per cell
  sizing.training.maxSteps = settings.maxSteps;
  sizing.training.seed = settings.seed;
  sizing.training.threads = settings.threads;
  sizing.training.validate();
  if (!settings.modelWidths.empty() || !settings.modelLatents.empty()) {
    auto listed = [](const std::vector<int>& v, int x) { return v.empty() || std::find(v.begin(), v.end(), x) != v.end(); };
    for (const GeneratorArch& a : sizingCandidates(settings.resolution, LatentSource::Stored))
      if (listed(settings.modelWidths, a.convChannels.front()) && listed(settings.modelLatents, a.latentDim))
        sizing.candidates.push_back(a);
  }

  const worlds::CellCoord c = in.cell;
  const worlds::BuiltCell& cell = in.built;
  std::vector<glm::vec3> positions;
  std::vector<uint8_t> active(cell.probes.flags.size(), 0), flags;
  for (size_t i = 0; i < cell.probes.flags.size(); ++i) {
    if (cell.probes.flags[i] & worlds::kProbeDisabledSolid) continue;
    positions.push_back(cell.probes.position(int64_t(i)));
    flags.push_back(cell.probes.flags[i]);
    active[i] = 1;
  }
  CellFile cf;
  cf.worldSeed = world.params().seed;
  cf.cellX = c.x;
  cf.cellZ = c.z;
  cf.inputHash = in.inputHash;
  cf.grid = cell.probes.grid;
  cf.active = active;
  CellBakeReport r;
  r.probes = positions.size();
  if (positions.empty()) {  // every probe inside solid: an empty cell holds only a dark fallback
    cf.fallback = darkFallback(keys);
    cf.stats.model = "no probes";
  } else {
    const EmbreeScene scene(std::move(in.sceneMesh), fmt::format("cell {},{}", c.x, c.z));
    const GeneratorTrainingSet set =
        captureTrainingSet(scene, positions, cell.probes.grid.origin, cell.probes.grid.boxMax(), keys, capture, {}, false);
    r.captureSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
    CellModelChoice choice = chooseCellModel(set, flags, sizing);
    // On Ctrl-C, training stops and chooseCellModel returns the best model so far. Stored under this
    // cell's input hash, that half-trained model would be skipped by every rerun (and differ from an
    // uninterrupted bake), so an interrupted cell is an error and nothing is written for it.
    if (InterruptGuard::interrupted()) fail("bake: cell {},{}: interrupted during training", c.x, c.z);
    cf.fallback = fallbackOf(set);
    cf.stats.errorTarget = settings.errorTarget;
    cf.stats.trainingSeconds = choice.trainingSeconds;
    cf.stats.model = choice.describe();
    cf.stats.errorAchieved = choice.error.irradianceRelativeRms;
    r.trainingSeconds = choice.trainingSeconds;
    if (choice.kind == CellModelKind::kGenerator && choice.generator) {
      TrainedGenerator& g = *choice.generator;
      CellGenerator gen;
      gen.weights = quantizeWeights(g.weights, WeightPrecision::Int8);
      if (!g.latents.empty()) gen.latents = quantizeLatents(g.latents, g.weights.arch.latentDim, 8);
      cf.outputScale = g.scale;
      // The stored error is the quantized model's (what a reader decodes).
      TrainedGenerator q = g;
      q.weights = dequantizeWeights(gen.weights);
      if (!g.latents.empty()) q.latents = dequantizeLatents(gen.latents);
      cf.stats.errorAchieved = evaluateGenerator(q, set).irradianceRelativeRms;
      cf.stats.model += " int8";
      cf.generator = std::move(gen);
      r.network = true;
    }
  }
  r.totalSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (report) *report = r;
  return cf;
}

CellBakeState cellBakeState(const fs::path& file, uint64_t inputHash, std::string* error) {
  std::error_code ec;
  if (!fs::exists(file, ec)) return CellBakeState::Missing;
  try {
    return readCellFile(file).inputHash == inputHash ? CellBakeState::Done : CellBakeState::Stale;
  } catch (const Error& e) {
    if (error) *error = e.what();
    return CellBakeState::Corrupt;
  }
}

}  // namespace lfgi::bake
