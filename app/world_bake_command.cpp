// `lfgi bake`: world cells -> cell files (DESIGN.md §3-4). Per cell: build the cell (probes placed as
// `lfgi world` places them), capture its active probes under the lighting keys with Embree (the cell's
// mesh + its 8 neighbours'), choose the smallest model that meets the error target (bake/
// generator_training.h chooseCellModel: no network when SH L1 suffices, else the cheapest generator),
// quantize (int8 weights per channel, int8 latents), measure the quantized model's error, write
// cells/cell_X_Z.vdb atomically.
// Idempotent: a cell whose file exists with the same input hash (world seed, cell, mesh hash, probe grid,
// flags and offsets, every bake option) is skipped; a corrupt existing file is rebaked. Interruptible
// between cells (Ctrl-C: exit 130, rerun resumes with the next cell). Slurm: --array-index/--array-size
// bake one contiguous share of the selected cells.
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "app/cli_args.h"
#include "app/commands.h"
#include "bake/embree_scene.h"
#include "bake/generator_training.h"
#include "core/cell_file.h"
#include "core/error.h"
#include "core/half.h"
#include "core/progress.h"
#include "core/sh.h"
#include "worlds/world_cells.h"

namespace lfgi::app {

namespace fs = std::filesystem;

namespace {

// "X,Z" cells and "A-B" / "A" linear index ranges (index = z * cellsX + x), comma-free ranges.
std::vector<worlds::CellCoord> selectCells(const worlds::SyntheticWorld& world, const std::vector<std::string>& args) {
  std::vector<worlds::CellCoord> cells;
  const int64_t total = int64_t(world.cellsX()) * world.cellsZ();
  if (args.empty()) {
    for (int64_t i = 0; i < total; ++i) cells.push_back({int(i % world.cellsX()), int(i / world.cellsX())});
    return cells;
  }
  for (const std::string& a : args) {
    if (a.find(',') != std::string::npos) {
      worlds::CellCoord c = parseCellArg(a, "--cells");
      if (!world.contains(c)) fail("--cells {}: outside the world ({} x {} cells)", a, world.cellsX(), world.cellsZ());
      cells.push_back(c);
      continue;
    }
    long long lo = 0, hi = 0;
    char dash = 0, extra = 0;
    int n = std::sscanf(a.c_str(), "%lld%c%lld%c", &lo, &dash, &hi, &extra);
    if (n == 1) hi = lo;
    else if (n != 3 || dash != '-') fail("--cells '{}': expected X,Z or an index range A-B", a);
    if (lo < 0 || hi < lo || hi >= total) fail("--cells '{}': indices must satisfy 0 <= A <= B < {}", a, total);
    for (long long i = lo; i <= hi; ++i) cells.push_back({int(i % world.cellsX()), int(i / world.cellsX())});
  }
  return cells;
}

std::vector<bake::LightingKeySpec> parseKeys(const std::string& text) {
  std::vector<bake::LightingKeySpec> keys;
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

// SH L1 radiance of the whole cell at the first key: the mean of the probes' projections (FP16).
CellFallback fallbackOf(const bake::GeneratorTrainingSet& set) {
  const bake::LightingKey& key = set.keys.front();
  ShL1 mean;
  for (const bake::ProbeCapture& p : key.probes) {
    ShL1 sh = shProject<4>(p.radiance, p.resolution);
    for (int k = 0; k < 4; ++k) mean.c[size_t(k)] += sh.c[size_t(k)] / float(key.probes.size());
  }
  CellFallback f;
  f.kind = CellFallback::Kind::PerCell;
  for (int k = 0; k < 4; ++k)
    for (int c = 0; c < 3; ++c) f.shHalf.push_back(floatToHalfClamped(mean.c[size_t(k)][c]));
  return f;
}

}  // namespace

int runWorldBake(const WorldBakeOptions& opt) {
  const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.world));
  std::vector<worlds::CellCoord> cells = selectCells(world, opt.cells);
  if (opt.arraySize > 0) {
    if (opt.arrayIndex < 0 || opt.arrayIndex >= opt.arraySize)
      fail("--array-index {} outside [0, --array-size {})", opt.arrayIndex, opt.arraySize);
    const size_t n = cells.size(), a = n * size_t(opt.arrayIndex) / size_t(opt.arraySize),
                 b = n * size_t(opt.arrayIndex + 1) / size_t(opt.arraySize);
    cells = std::vector<worlds::CellCoord>(cells.begin() + ptrdiff_t(a), cells.begin() + ptrdiff_t(b));
  }
  const std::vector<bake::LightingKeySpec> keys = parseKeys(opt.keys);
  const fs::path out = opt.outDir.empty() ? fs::path(opt.world) / "baked" : fs::path(opt.outDir);
  fs::create_directories(out / "cells");

  bake::CaptureOptions capture;
  capture.resolution = opt.resolution;
  capture.irradianceResolution = std::max(2, opt.resolution / 2);
  capture.samplesPerTexel = opt.spp;
  capture.maxBounces = opt.bounces;
  capture.seed = opt.seed;
  // A miss records this distance: a few cells, not the 10 km default, so the generator's distance range
  // (1.5 x the 95th percentile) keeps centimetre precision where visibility needs it.
  capture.maxDistance = float(4.0 * world.cellSizeM());
  bake::validateCaptureOptions(capture);
  bake::ModelSizingOptions sizing;
  sizing.irradianceErrorTarget = opt.errorTarget;
  sizing.noNetworkKinds = {bake::CellModelKind::kShL1};  // the cell file stores one SH L1 per cell
  sizing.training.maxSteps = opt.maxSteps;
  sizing.training.seed = opt.seed;
  sizing.training.threads = opt.threads;
  sizing.training.validate();

  InterruptGuard guard;
  Progress progress("bake", cells.size(), "cells");
  size_t done = 0, skipped = 0, networks = 0;
  size_t bytesTotal = 0;
  for (const worlds::CellCoord c : cells) {
    if (InterruptGuard::interrupted()) {
      std::fprintf(stderr, "bake: interrupted after %zu cells; run the same command again to resume\n", done);
      return 130;
    }
    const fs::path file = out / "cells" / fmt::format("cell_{}_{}.vdb", c.x, c.z);
    worlds::BuiltCell cell = worlds::buildCell(world, c);
    ContentHasher hasher;
    hasher.add(std::string("lfgi-bake-v1")).addValue(world.params().seed).addValue(c.x).addValue(c.z);
    hasher.addValue(cell.stats.meshHash).addValue(cell.probes.grid.origin).addValue(cell.probes.grid.spacing);
    hasher.addValue(cell.probes.grid.dims);
    hasher.add(std::as_bytes(std::span(cell.probes.flags))).add(std::as_bytes(std::span(cell.probes.offsets)));
    hasher.addValue(capture.resolution).addValue(capture.samplesPerTexel).addValue(capture.maxBounces);
    hasher.addValue(capture.seed).addValue(capture.maxDistance).add(opt.keys).addValue(opt.errorTarget).addValue(opt.maxSteps);
    const uint64_t inputHash = hasher.digest();
    if (fs::exists(file)) {
      try {
        if (readCellFile(file).inputHash == inputHash) {
          ++skipped;
          ++done;
          progress.update(done);
          continue;
        }
        spdlog::info("{}: inputs changed, rebaking", file.string());
      } catch (const Error& e) {
        spdlog::warn("rebaking: {}", e.what());
      }
    }
    // Capture the active probes in the cell and its 8 neighbours' geometry.
    worlds::TriangleMesh mesh = std::move(cell.mesh);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx)
        if ((dx || dz) && world.contains({c.x + dx, c.z + dz})) mesh.append(world.generateCell({c.x + dx, c.z + dz}));
    const bake::EmbreeScene scene(std::move(mesh), fmt::format("cell {},{}", c.x, c.z));
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
    cf.inputHash = inputHash;
    cf.grid = cell.probes.grid;
    cf.active = active;
    if (positions.empty()) {  // every probe inside solid: an empty cell holds only a dark fallback
      cf.fallback.shHalf.assign(12, floatToHalfClamped(0.0f));
      cf.stats.model = "no probes";
    } else {
      const bake::GeneratorTrainingSet set = bake::captureTrainingSet(
          scene, positions, cell.probes.grid.origin, cell.probes.grid.boxMax(), keys, capture, {}, false);
      bake::CellModelChoice choice = bake::chooseCellModel(set, flags, sizing);
      cf.fallback = fallbackOf(set);
      cf.stats.errorTarget = opt.errorTarget;
      cf.stats.trainingSeconds = choice.trainingSeconds;
      cf.stats.model = choice.describe();
      cf.stats.errorAchieved = choice.error.irradianceRelativeRms;
      if (choice.kind == bake::CellModelKind::kGenerator && choice.generator) {
        bake::TrainedGenerator& g = *choice.generator;
        CellGenerator gen;
        gen.weights = quantizeWeights(g.weights, WeightPrecision::Int8);
        if (!g.latents.empty()) gen.latents = quantizeLatents(g.latents, g.weights.arch.latentDim, 8);
        cf.outputScale = g.scale;
        // The stored error is the quantized model's (what a reader decodes).
        bake::TrainedGenerator q = g;
        q.weights = dequantizeWeights(gen.weights);
        if (!g.latents.empty()) q.latents = dequantizeLatents(gen.latents);
        cf.stats.errorAchieved = bake::evaluateGenerator(q, set).irradianceRelativeRms;
        cf.stats.model += " int8";
        cf.generator = std::move(gen);
        ++networks;
      }
    }
    writeCellFile(file, cf);
    CellFileBytes bytes;
    readCellFile(file, &bytes);  // read back through every check: what we wrote is what a reader accepts
    bytesTotal += bytes.total;
    std::fprintf(stderr, "\ncell %d,%d: %zu probes, %s, irradiance error %.2f %% (target %.1f %%), %zu bytes\n", c.x, c.z,
                 positions.size(), cf.stats.model.c_str(), 100.0 * cf.stats.errorAchieved, 100.0 * opt.errorTarget,
                 bytes.total);
    ++done;
    progress.update(done);
  }
  progress.finish();
  std::printf("done: %zu cells (%zu already baked, %zu with a network), %zu bytes written, in %s\n", cells.size(), skipped,
              networks, bytesTotal, (out / "cells").string().c_str());
  return 0;
}

}  // namespace lfgi::app
