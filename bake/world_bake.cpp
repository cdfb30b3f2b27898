#include "bake/world_bake.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include <fmt/format.h>

#include "core/quantize.h"

#include "bake/embree_scene.h"
#include "core/cell_fallback.h"
#include "core/cell_store.h"
#include "core/error.h"
#include "core/half.h"
#include "core/metrics.h"
#include "core/progress.h"
#include "core/sh.h"

namespace lfgi::bake {

namespace fs = std::filesystem;

void WorldBakeSettings::validate() const {
  if (!(errorTarget >= 0.001 && errorTarget <= 1.0))
    fail("bake error target {} outside [0.001, 1]", errorTarget);
  if (resolution != 8 && resolution != 16 && resolution != 32)
    fail("bake resolution {}: expected 8, 16 or 32", resolution);
  if (spp < 1 || bounces < 0 || maxSteps < 1 || threads < 1)
    fail("bake settings: spp {} >= 1, bounces {} >= 0, max steps {} >= 1, threads {} >= 1 required", spp,
         bounces, maxSteps, threads);
  for (int w : modelWidths)
    if (w != 8 && w != 16 && w != 32 && w != 64) fail("bake model width {}: expected 8, 16, 32 or 64", w);
  for (int z : modelLatents)
    if (z != 4 && z != 8 && z != 16) fail("bake model latent size {}: expected 4, 8 or 16", z);
  if (codec != "per-cell" && codec != "shared" && codec != "sh-l1")
    fail("bake codec '{}': expected per-cell, shared or sh-l1", codec);
  if (sharedSteps < 1) fail("bake shared steps {} >= 1 required", sharedSteps);
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
      fail(
          "--keys '{}': expected HOURS[:OVERCAST],... with hours in [0, 24] and overcast in [0, 1], got '{}'",
          text, item);
    keys.push_back({t, n == 3 ? w : 0.0f});
    start = end + 1;
  }
  return keys;
}

CaptureOptions bakeCaptureOptions(const WorldBakeSettings& settings, float maxDistance) {
  CaptureOptions capture;
  capture.resolution = settings.resolution;
  capture.irradianceResolution = std::max(2, settings.resolution / 2);
  capture.samplesPerTexel = settings.spp;
  capture.maxBounces = settings.bounces;
  capture.seed = settings.seed;
  capture.maxDistance = maxDistance;
  validateCaptureOptions(capture);
  return capture;
}

CaptureOptions worldBakeCaptureOptions(const worlds::SyntheticWorld& world,
                                       const WorldBakeSettings& settings) {
  // A miss records this distance: a few cells, not the 10 km default, so the generator's distance range
  // (1.5 x the 95th percentile) keeps centimetre precision where visibility needs it.
  return bakeCaptureOptions(settings, float(4.0 * world.cellSizeM()));
}

fs::path cellFilePath(const fs::path& outDir, worlds::CellCoord c) {
  return outDir / "cells" / cellFileName({c.x, c.z});
}

fs::path cellCheckpointPrefix(const fs::path& dir, worlds::CellCoord c, uint64_t inputHash) {
  return dir / fmt::format("cell_{}_{}.{:016x}.train", c.x, c.z, inputHash);
}

int removeCellCheckpoints(const fs::path& dir, worlds::CellCoord c) {
  const std::string prefix = fmt::format("cell_{}_{}.", c.x, c.z);
  int removed = 0;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) == 0 && name.find(".train.candidate") != std::string::npos &&
        fs::remove(e.path(), ec))
      ++removed;
  }
  return removed;
}

std::vector<worlds::CellCoord> arrayShare(const std::vector<worlds::CellCoord>& cells, int index, int size) {
  if (size < 1 || index < 0 || index >= size)
    fail("--array-index {} outside [0, --array-size {})", index, size);
  const size_t n = cells.size(), a = n * size_t(index) / size_t(size),
               b = n * size_t(index + 1) / size_t(size);
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
    return x.timeOfDayHours < y.timeOfDayHours ||
           (x.timeOfDayHours == y.timeOfDayHours && x.weather < y.weather);
  };
  std::stable_sort(order.begin(), order.end(), less);
  order.erase(std::unique(order.begin(), order.end(), [&](size_t a, size_t b) { return !less(a, b); }),
              order.end());
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

// --codec sh-l1: every probe's own SH L1 per key (entries in the training set's probe order = the active
// probes' order) in the cell file's int8 layout (15 B per probe per key), and the irradiance relative RMS
// of the stored SH's cosine convolution against the captures'.
CellFallback perProbeFallbackOf(const GeneratorTrainingSet& set, double* irradianceError) {
  CellFallback f;
  f.kind = CellFallback::Kind::PerProbe;
  f.keyHours.clear();
  f.keyOvercast.clear();
  std::vector<const ProbeCapture*> probes;  // entry order
  for (size_t i : fileKeyOrder(set.keys)) {
    const LightingKey& key = set.keys[i];
    f.keyHours.push_back(key.timeOfDayHours);
    f.keyOvercast.push_back(key.weather);
    for (const ProbeCapture& p : key.probes) {
      const ShL1 sh = shProject<4>(p.radiance, p.resolution);
      for (int k = 0; k < 4; ++k)
        for (int c = 0; c < 3; ++c) f.shHalf.push_back(floatToHalfClamped(sh.c[size_t(k)][c]));
      probes.push_back(&p);
    }
  }
  quantizeFallbackToInt8(f);
  std::vector<float> got, want;
  for (size_t e = 0; e < probes.size(); ++e) {
    const ProbeCapture& p = *probes[e];
    const size_t values = p.irradiance.size();
    got.resize(got.size() + values);
    shProbeMaps(shFromHalves(f.shHalf.data() + e * 12), p.resolution, p.irradianceResolution, nullptr,
                got.data() + got.size() - values);
    want.insert(want.end(), p.irradiance.begin(), p.irradiance.end());
  }
  *irradianceError = relativeRms(got, want);
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
                    const uint64_t (&neighbours)[9], const WorldBakeSettings& settings,
                    uint64_t sharedModelHash) {
  const CaptureOptions capture = worldBakeCaptureOptions(world, settings);
  ContentHasher hasher;
  // The version names what an older cell file lacks, so an incremental bake rewrites it: v4, training
  // sets without the directly seen discs and the per-probe irradiance loss (bake/generator_training.h).
  hasher.add(std::string("lfgi-bake-v4")).addValue(world.params().seed).addValue(c.x).addValue(c.z);
  for (uint64_t h : neighbours) hasher.addValue(h);
  hasher.addValue(cell.stats.meshHash).addValue(cell.probes.grid.origin).addValue(cell.probes.grid.spacing);
  hasher.addValue(cell.probes.grid.dims);
  hasher.add(std::as_bytes(std::span(cell.probes.flags))).add(std::as_bytes(std::span(cell.probes.offsets)));
  hasher.addValue(capture.resolution).addValue(capture.samplesPerTexel).addValue(capture.maxBounces);
  hasher.addValue(capture.seed)
      .addValue(capture.maxDistance)
      .add(settings.keys)
      .addValue(settings.errorTarget);
  hasher.addValue(settings.maxSteps).addValue(settings.threads);
  hasher.add(std::string("models"));
  for (int w : settings.modelWidths) hasher.addValue(w);
  hasher.add(std::string("/"));
  for (int z : settings.modelLatents) hasher.addValue(z);
  // The per-cell codec's hash is unchanged from before the codec choice existed (no rebake of its worlds).
  if (settings.sharedCodec()) hasher.add(std::string("codec shared")).addValue(sharedModelHash);
  if (settings.codec == "sh-l1") hasher.add(std::string("codec sh-l1 int8"));
  return hasher.digest();
}

// The active probes of a built cell (not inside solid): positions, flags, and the grid's active mask.
struct ActiveProbes {
  std::vector<glm::vec3> positions;
  std::vector<uint8_t> flags, active;
};
ActiveProbes activeProbes(const worlds::BuiltCell& cell) {
  ActiveProbes a;
  a.active.assign(cell.probes.flags.size(), 0);
  for (size_t i = 0; i < cell.probes.flags.size(); ++i) {
    if (cell.probes.flags[i] & worlds::kProbeDisabledSolid) continue;
    a.positions.push_back(cell.probes.position(int64_t(i)));
    a.flags.push_back(cell.probes.flags[i]);
    a.active[i] = 1;
  }
  return a;
}

// The cell's captures under every lighting key (the generator's training set). Consumes in.sceneMesh.
GeneratorTrainingSet captureCell(const worlds::SyntheticWorld& world, CellBakeInputs& in,
                                 const ActiveProbes& probes, const WorldBakeSettings& settings) {
  const EmbreeScene scene(std::move(in.sceneMesh), fmt::format("cell {},{}", in.cell.x, in.cell.z));
  return captureTrainingSet(scene, probes.positions, in.built.probes.grid.origin,
                            in.built.probes.grid.boxMax(), parseLightingKeys(settings.keys),
                            worldBakeCaptureOptions(world, settings), {}, settings.stageProgress);
}

// Fit options of a cell against the shared model (and, with pre-training steps, the pre-training's).
SharedTrainingOptions sharedFitOptions(const WorldBakeSettings& settings, int steps, double target,
                                       int quantBits) {
  SharedTrainingOptions o;
  o.training.arch = sharedModelArch(settings);
  o.training.maxSteps = steps;
  o.training.evalEvery = std::max(1, std::min(100, steps / 4));
  o.training.irradianceErrorTarget = target;
  o.training.batchSize = 512;
  o.training.seed = settings.seed;
  o.training.threads = settings.threads;
  o.training.latentQuantBits = quantBits;
  o.training.showProgress = settings.stageProgress;
  // FiLM on the linear layer's C0 channels only: bench/codec's shared_adapter setting (bake/OVERVIEW.md).
  o.adapterStages = 1;
  o.adapterQuantBits = quantBits;
  return o;
}

// Order of the world's cells for the shared model's sample: by a hash of (seed, x, z).
uint64_t sampleOrderKey(uint64_t seed, worlds::CellCoord c) {
  return ContentHasher().addValue(seed).addValue(c.x).addValue(c.z).digest();
}

ModelSizingOptions cellSizingOptions(const WorldBakeSettings& settings, worlds::CellCoord c,
                                     uint64_t inputHash) {
  ModelSizingOptions sizing;
  sizing.irradianceErrorTarget = settings.errorTarget;
  sizing.noNetworkKinds = {CellModelKind::kShL1};  // the cell file stores one SH L1 per cell
  sizing.training.maxSteps = settings.maxSteps;
  sizing.training.seed = settings.seed;
  sizing.training.threads = settings.threads;
  sizing.training.showProgress = settings.stageProgress;
  if (!settings.checkpointDir.empty()) {
    sizing.training.checkpoint = cellCheckpointPrefix(settings.checkpointDir, c, inputHash);
    sizing.training.keepFinishedCheckpoint = true;  // finished candidates resume without training
  }
  sizing.training.validate();
  if (!settings.modelWidths.empty() || !settings.modelLatents.empty()) {
    auto listed = [](const std::vector<int>& v, int x) {
      return v.empty() || std::find(v.begin(), v.end(), x) != v.end();
    };
    for (const GeneratorArch& a : sizingCandidates(settings.resolution, LatentSource::Stored))
      if (listed(settings.modelWidths, a.convChannels.front()) && listed(settings.modelLatents, a.latentDim))
        sizing.candidates.push_back(a);
  }
  return sizing;
}

// The cell fitted to the world's shared model: its quantized latents and adapter into cf.
void storeSharedFit(worlds::CellCoord c, const GeneratorTrainingSet& set, const WorldBakeSettings& settings,
                    const ResolvedSharedModel* shared, CellFile& cf, CellBakeReport& r) {
  // Latents + adapter against the frozen dequantized shared model, int8 quantized in the loop.
  const CellAdaptation fit = fitCellToSharedGenerator(
      shared->weights, set, sharedFitOptions(settings, settings.maxSteps, settings.errorTarget, 8));
  if (InterruptGuard::interrupted()) fail("bake: cell {},{}: interrupted during training", c.x, c.z);
  const GeneratorArch& arch = shared->weights.arch;
  CellGenerator gen;
  gen.weights.arch = arch;
  gen.weights.precision = WeightPrecision::Int8;
  gen.latents = quantizeLatents(fit.latents, arch.latentDim, 8);
  gen.shared = CellSharedModelRef{shared->hash, quantizeAdapter(fit.adapter, 8)};
  cf.outputScale = fit.scale;
  // The stored error is the quantized cell's through the decoder weights a reader builds.
  TrainedGenerator q;
  q.weights = resolveCellWeights(gen, shared, fmt::format("cell {},{}", c.x, c.z));
  q.latents = dequantizeLatents(gen.latents);
  q.scale = fit.scale;
  cf.stats.errorAchieved = evaluateGenerator(q, set).irradianceRelativeRms;
  cf.stats.trainingSeconds = fit.report.seconds;
  cf.stats.model = fmt::format("shared z{} C{} + FiLM {} int8", arch.latentDim, arch.convChannels.front(),
                               gen.shared->adapter.stages);
  r.trainingSeconds = fit.report.seconds;
  cf.generator = std::move(gen);
  r.network = true;
}

// The chosen per-cell generator int8 quantized into cf.
void storeGenerator(const TrainedGenerator& g, const GeneratorTrainingSet& set, CellFile& cf,
                    CellBakeReport& r) {
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

}  // namespace

CellBakeInputs prepareCellBake(const worlds::SyntheticWorld& world, worlds::CellCoord c,
                               const WorldBakeSettings& settings, uint64_t sharedModelHash) {
  settings.validate();
  if (!world.contains(c))
    fail("bake: cell {},{} outside the world ({} x {} cells)", c.x, c.z, world.cellsX(), world.cellsZ());
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
  in.inputHash = hashInputs(world, c, in.built, in.neighbourMeshHashes, settings, sharedModelHash);
  return in;
}

uint64_t cellInputHash(const worlds::SyntheticWorld& world, worlds::CellCoord c,
                       const WorldBakeSettings& settings, uint64_t sharedModelHash) {
  return prepareCellBake(world, c, settings, sharedModelHash).inputHash;
}

void encodeCellCodec(worlds::CellCoord c, const GeneratorTrainingSet& set,
                     std::span<const uint8_t> probeFlags, const WorldBakeSettings& settings,
                     const ResolvedSharedModel* shared, CellFile& cf, CellBakeReport* report) {
  if (settings.sharedCodec() && !shared)
    fail("bake: cell {},{}: --codec shared needs the world's shared model", c.x, c.z);
  if (settings.codec == "sh-l1") {
    cf.generator.reset();
    cf.fallback = perProbeFallbackOf(set, &cf.stats.errorAchieved);
    cf.stats.errorTarget = 0.0;  // no model search aims at it
    cf.stats.model = "no network: SH L1 int8 per probe";
    cf.stats.trainingSeconds = 0.0;
    if (report) {
      report->network = false;
      report->trainingSeconds = 0.0;
    }
    return;
  }
  const ModelSizingOptions sizing = cellSizingOptions(settings, c, cf.inputHash);
  CellBakeReport r;
  // Shared codec: a simple cell still stores no network; every other cell fits the shared model below.
  std::optional<CellModelChoice> noNetwork;
  if (settings.sharedCodec()) noNetwork = chooseNoNetworkModel(set, probeFlags, sizing);
  const bool fitShared = settings.sharedCodec() && !noNetwork;
  CellModelChoice choice = noNetwork   ? std::move(*noNetwork)
                           : fitShared ? CellModelChoice{}
                                       : chooseCellModel(set, probeFlags, sizing);
  cf.fallback = fallbackOf(set);
  cf.stats.errorTarget = settings.errorTarget;
  if (fitShared) {
    storeSharedFit(c, set, settings, shared, cf, r);
  } else {
    // On Ctrl-C, training stops and chooseCellModel returns the best model so far. Stored under this
    // cell's input hash, that half-trained model would be skipped by every rerun (and differ from an
    // uninterrupted bake), so an interrupted cell is an error and nothing is written for it.
    if (InterruptGuard::interrupted()) fail("bake: cell {},{}: interrupted during training", c.x, c.z);
    cf.stats.trainingSeconds = choice.trainingSeconds;
    cf.stats.model = choice.describe();
    cf.stats.errorAchieved = choice.error.irradianceRelativeRms;
    r.trainingSeconds = choice.trainingSeconds;
  }
  if (choice.kind == CellModelKind::kGenerator && choice.generator)
    storeGenerator(*choice.generator, set, cf, r);
  if (report) {
    report->network = r.network;
    report->trainingSeconds = r.trainingSeconds;
  }
}

CellFile bakeCell(const worlds::SyntheticWorld& world, CellBakeInputs in, const WorldBakeSettings& settings,
                  CellBakeReport* report, const ResolvedSharedModel* shared) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  if (settings.sharedCodec() && !shared)
    fail("bake: cell {},{}: --codec shared needs the world's shared model", in.cell.x, in.cell.z);
  const std::vector<LightingKeySpec> keys = parseLightingKeys(settings.keys);
  const worlds::CellCoord c = in.cell;
  const worlds::BuiltCell& cell = in.built;
  const ActiveProbes probes = activeProbes(cell);
  CellFile cf;
  cf.worldSeed = world.params().seed;
  cf.cellX = c.x;
  cf.cellZ = c.z;
  cf.inputHash = in.inputHash;
  cf.grid = cell.probes.grid;
  cf.active = probes.active;
  CellBakeReport r;
  r.probes = probes.positions.size();
  if (probes.positions.empty()) {  // every probe inside solid: an empty cell holds only a dark fallback
    cf.fallback = darkFallback(keys);
    cf.stats.model = "no probes";
  } else {
    const GeneratorTrainingSet set = captureCell(world, in, probes, settings);
    r.captureSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
    encodeCellCodec(c, set, probes.flags, settings, shared, cf, &r);
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

// ---- the shared codec's world model ----------------------------------------------------------------------

GeneratorArch sharedModelArch(const WorldBakeSettings& settings) {
  const int width = settings.modelWidths.empty() ? 32 : settings.modelWidths.front();
  const int latent = settings.modelLatents.empty() ? 8 : settings.modelLatents.front();
  for (const GeneratorArch& a : sizingCandidates(settings.resolution, LatentSource::Stored))
    if (a.convChannels.front() == width && a.latentDim == latent) return a;
  fail("bake: no shared generator of width {} and latent size {} at resolution {}", width, latent,
       settings.resolution);
}

std::vector<worlds::CellCoord> sharedModelCells(const worlds::SyntheticWorld& world,
                                                const WorldBakeSettings& settings) {
  std::vector<worlds::CellCoord> order;
  for (int z = 0; z < world.cellsZ(); ++z)
    for (int x = 0; x < world.cellsX(); ++x) order.push_back({x, z});
  std::sort(order.begin(), order.end(), [&](worlds::CellCoord a, worlds::CellCoord b) {
    return sampleOrderKey(settings.seed, a) < sampleOrderKey(settings.seed, b);
  });
  std::vector<worlds::CellKind> present;  // cellKind is cheap, buildCell is not: stop once each kind is found
  for (const worlds::CellCoord c : order)
    if (std::find(present.begin(), present.end(), world.cellKind(c)) == present.end())
      present.push_back(world.cellKind(c));
  std::vector<worlds::CellCoord> chosen;
  std::vector<worlds::CellKind> kinds;
  for (const worlds::CellCoord c : order) {
    if (kinds.size() == present.size()) break;
    const worlds::CellKind k = world.cellKind(c);
    if (std::find(kinds.begin(), kinds.end(), k) != kinds.end()) continue;
    if (activeProbes(worlds::buildCell(world, c)).positions.empty()) continue;
    chosen.push_back(c);
    kinds.push_back(k);
  }
  if (chosen.empty()) fail("bake --codec shared: no cell of the world has an active probe to pre-train on");
  return chosen;
}

namespace {

// The sample cells of sharedModelCells prepared with their own (per-cell codec) inputs: their input hashes
// enter the shared model's, and ensureSharedModel captures them, so each is prepared once.
std::vector<CellBakeInputs> prepareSharedModelCells(const worlds::SyntheticWorld& world,
                                                    const WorldBakeSettings& settings) {
  WorldBakeSettings perCell = settings;  // the sample cells' own inputs, independent of the codec
  perCell.codec = "per-cell";
  std::vector<CellBakeInputs> cells;
  for (const worlds::CellCoord c : sharedModelCells(world, settings))
    cells.push_back(prepareCellBake(world, c, perCell));
  return cells;
}

uint64_t hashSharedModelInputs(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings,
                               const std::vector<CellBakeInputs>& cells) {
  const GeneratorArch arch = sharedModelArch(settings);
  ContentHasher h;
  h.add(std::string("lfgi-shared-model-v2")).addValue(world.params().seed).addValue(settings.sharedSteps);
  for (const CellBakeInputs& in : cells) h.addValue(in.cell.x).addValue(in.cell.z).addValue(in.inputHash);
  h.addValue(arch.latentDim).addValue(arch.condDim);
  for (int ch : arch.convChannels) h.addValue(ch);
  return h.digest();
}

}  // namespace

uint64_t sharedModelInputHash(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings) {
  return hashSharedModelInputs(world, settings, prepareSharedModelCells(world, settings));
}

uint64_t currentSharedModelHash(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings,
                                const fs::path& outDir) {
  if (!settings.sharedCodec()) return 0;
  const fs::path path = sharedModelPath(outDir);
  std::error_code ec;
  if (!fs::exists(path, ec)) return 0;
  try {
    uint64_t hash = 0;
    const SharedModel m = readSharedModel(path, &hash);
    return m.inputHash == sharedModelInputHash(world, settings) ? hash : 0;
  } catch (const Error&) {
    return 0;
  }
}

SharedModel ensureSharedModel(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings,
                              const fs::path& outDir, bool* reused) {
  settings.validate();
  const fs::path path = sharedModelPath(outDir);
  std::vector<CellBakeInputs> cells = prepareSharedModelCells(world, settings);
  const uint64_t inputHash = hashSharedModelInputs(world, settings, cells);
  std::error_code ec;
  if (reused) *reused = false;
  if (fs::exists(path, ec)) {
    try {
      SharedModel m = readSharedModel(path);
      if (m.inputHash == inputHash && m.worldSeed == world.params().seed) {
        if (reused) *reused = true;
        return m;
      }
      std::fprintf(stderr, "%s: pre-training inputs changed, training the shared model again\n",
                   path.string().c_str());
    } catch (const Error& e) {
      std::fprintf(stderr, "%s; training the shared model again\n", e.what());
    }
  }
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  std::vector<GeneratorTrainingSet> sets;
  std::string names;
  for (CellBakeInputs& in : cells) {
    const worlds::CellCoord c = in.cell;
    if (InterruptGuard::interrupted()) fail("bake: interrupted while capturing the shared model's cells");
    std::fprintf(stderr, "shared model: capturing cell %d,%d (%s)\n", c.x, c.z,
                 std::string(worlds::cellKindName(world.cellKind(c))).c_str());
    const ActiveProbes probes = activeProbes(in.built);
    sets.push_back(captureCell(world, in, probes, settings));
    names += fmt::format("{}{},{} {}", names.empty() ? "" : "; ", c.x, c.z,
                         worlds::cellKindName(world.cellKind(c)));
  }
  // A fixed budget (no early stop), as bench/codec's shared model; resumable from the checkpoint.
  SharedTrainingOptions o = sharedFitOptions(settings, settings.sharedSteps, 0.0, 0);
  o.training.checkpoint = outDir / "shared_model.ckpt";
  o.training.checkpointEvery = 250;
  o.training.showProgress = true;
  const SharedGenerator g = pretrainSharedGenerator(sets, o);
  if (g.report.interrupted || InterruptGuard::interrupted())
    fail("bake: interrupted during shared-model pre-training (checkpoint {} kept; rerun to resume)",
         o.training.checkpoint.string());
  if (g.report.diverged) fail("bake: shared-model pre-training diverged after {} steps", g.report.steps);
  SharedModel m;
  m.worldSeed = world.params().seed;
  m.inputHash = inputHash;
  m.weights = quantizeWeights(g.weights, WeightPrecision::Int8);
  m.stats.steps = g.report.steps;
  m.stats.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  m.stats.errorAchieved = g.report.irradianceRelativeRms;
  m.stats.cells = names;
  writeSharedModel(path, m);
  fs::remove(o.training.checkpoint, ec);
  return m;
}

}  // namespace lfgi::bake
