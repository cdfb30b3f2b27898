// `lfgi bake`: world cells -> cell files (DESIGN.md §3-4); the per-cell work is bake/world_bake.h
// bakeCell, written to cells/cell_X_Z.vdb atomically.
// Idempotent: a cell whose file exists with the same input hash (bake/world_bake.h: world seed, cell, the
// mesh hashes of the cell and its 8 neighbours, probe grid, flags and offsets, every bake option) is
// skipped; a corrupt existing file is rebaked. Interruptible
// between cells (Ctrl-C: exit 130, rerun resumes with the next cell). Slurm: --array-index/--array-size
// bake one contiguous share of the selected cells.
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "app/cli_args.h"
#include "app/world_bake_command.h"
#include "core/cell_file.h"
#include "core/error.h"
#include "core/progress.h"
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

}  // namespace

bake::WorldBakeSettings worldBakeSettings(const WorldBakeOptions& opt) {
  bake::WorldBakeSettings s;
  s.errorTarget = opt.errorTarget;
  s.keys = opt.keys;
  s.resolution = opt.resolution;
  s.spp = opt.spp;
  s.bounces = opt.bounces;
  s.maxSteps = opt.maxSteps;
  s.threads = opt.threads;
  s.seed = opt.seed;
  s.validate();
  return s;
}

std::vector<worlds::CellCoord> selectBakeCells(const worlds::SyntheticWorld& world, const WorldBakeOptions& opt) {
  std::vector<worlds::CellCoord> cells = selectCells(world, opt.cells);
  if (opt.arraySize > 0) cells = bake::arrayShare(cells, opt.arrayIndex, opt.arraySize);
  return cells;
}

int runWorldBake(const WorldBakeOptions& opt) {
  const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.world));
  const std::vector<worlds::CellCoord> cells = selectBakeCells(world, opt);
  const bake::WorldBakeSettings settings = worldBakeSettings(opt);
  const fs::path out = opt.outDir.empty() ? fs::path(opt.world) / "baked" : fs::path(opt.outDir);
  fs::create_directories(out / "cells");

  InterruptGuard guard;
  Progress progress("bake", cells.size(), "cells");
  size_t done = 0, skipped = 0, networks = 0;
  size_t bytesTotal = 0;
  for (const worlds::CellCoord c : cells) {
    if (InterruptGuard::interrupted()) {
      std::fprintf(stderr, "bake: interrupted after %zu cells; run the same command again to resume\n", done);
      return 130;
    }
    const fs::path file = bake::cellFilePath(out, c);
    bake::CellBakeInputs inputs = bake::prepareCellBake(world, c, settings);
    std::string why;
    const bake::CellBakeState state = bake::cellBakeState(file, inputs.inputHash, &why);
    if (state == bake::CellBakeState::Done) {
      ++skipped;
      ++done;
      progress.update(done);
      continue;
    }
    if (state == bake::CellBakeState::Stale) spdlog::info("{}: inputs changed, rebaking", file.string());
    if (state == bake::CellBakeState::Corrupt) spdlog::warn("rebaking: {}", why);
    bake::CellBakeReport report;
    const CellFile cf = bake::bakeCell(world, std::move(inputs), settings, &report);
    writeCellFile(file, cf);
    CellFileBytes bytes;
    readCellFile(file, &bytes);  // read back through every check: what we wrote is what a reader accepts
    bytesTotal += bytes.total;
    networks += report.network ? 1 : 0;
    std::fprintf(stderr, "\ncell %d,%d: %zu probes, %s, irradiance error %.2f %% (target %.1f %%), %zu bytes, %.1f s\n", c.x,
                 c.z, report.probes, cf.stats.model.c_str(), 100.0 * cf.stats.errorAchieved, 100.0 * opt.errorTarget,
                 bytes.total, report.totalSeconds);
    ++done;
    progress.update(done);
  }
  progress.finish();
  std::printf("done: %zu cells (%zu already baked, %zu with a network), %zu bytes written, in %s\n", cells.size(), skipped,
              networks, bytesTotal, (out / "cells").string().c_str());
  return 0;
}

}  // namespace lfgi::app
