// `lfgi bake`: world cells -> cell files (docs/DESIGN.md §3-4); the per-cell work is bake/world_bake.h
// bakeCell, written to cells/cell_X_Z.vdb atomically.
// Idempotent: a cell whose file exists with the same input hash (bake/world_bake.h: world seed, cell, the
// mesh hashes of the cell and its 8 neighbours, probe grid, flags and offsets, every bake option) is
// skipped; a corrupt existing file is rebaked. Interruptible (Ctrl-C: exit 130; the cell in flight is
// dropped, not written half-trained; a rerun resumes with it; tests/interrupt_bake.sh). Slurm:
// --array-index/--array-size bake one contiguous share of the selected cells.
// --codec shared: OUT/shared_model.vdb is pre-trained first (or reused when its input hash matches; an
// interrupted pre-training resumes from OUT/shared_model.ckpt), then every cell is fitted against it.
// Bookkeeping (bake/bake_records.h): cells/cell_X_Z.json per baked cell (kind, seconds by stage, bytes,
// host, time), cells/cell_X_Z.failed per failed cell; a failed cell does not stop the others, the exit
// code is 1 when any failed.
#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "app/cli_args.h"
#include "app/world_bake_command.h"
#include "bake/bake_records.h"
#include "core/cell_file.h"
#include "core/cell_store.h"
#include "core/error.h"
#include "core/progress.h"
#include "core/quantize.h"
#include "core/shared_model.h"
#include "streaming/flythrough.h"
#include "worlds/world_cells.h"

namespace lfgi::app {

namespace fs = std::filesystem;

namespace {

// "X,Z" cells and "A-B" / "A" linear index ranges (index = z * cellsX + x), comma-free ranges.
std::vector<worlds::CellCoord> selectCells(const worlds::SyntheticWorld& world,
                                           const std::vector<std::string>& args) {
  std::vector<worlds::CellCoord> cells;
  const int64_t total = int64_t(world.cellsX()) * world.cellsZ();
  if (args.empty()) {
    for (int64_t i = 0; i < total; ++i) cells.push_back({int(i % world.cellsX()), int(i / world.cellsX())});
    return cells;
  }
  for (const std::string& a : args) {
    if (a.find(',') != std::string::npos) {
      worlds::CellCoord c = parseCellArg(a, "--cells");
      if (!world.contains(c))
        fail("--cells {}: outside the world ({} x {} cells)", a, world.cellsX(), world.cellsZ());
      cells.push_back(c);
      continue;
    }
    long long lo = 0, hi = 0;
    char dash = 0, extra = 0;
    int n = std::sscanf(a.c_str(), "%lld%c%lld%c", &lo, &dash, &hi, &extra);
    if (n == 1)
      hi = lo;
    else if (n != 3 || dash != '-')
      fail("--cells '{}': expected X,Z or an index range A-B", a);
    if (lo < 0 || hi < lo || hi >= total)
      fail("--cells '{}': indices must satisfy 0 <= A <= B < {}", a, total);
    for (long long i = lo; i <= hi; ++i) cells.push_back({int(i % world.cellsX()), int(i / world.cellsX())});
  }
  return cells;
}

}  // namespace

std::vector<worlds::CellCoord> selectBakeCells(const worlds::SyntheticWorld& world,
                                               const WorldBakeOptions& opt) {
  std::vector<worlds::CellCoord> cells;
  if (!opt.path.empty()) {
    if (!opt.cells.empty()) fail("--path {} and --cells: give one of them", opt.path);
    streaming::FlythroughOptions fo;
    fo.path = opt.path;
    const streaming::WorldLayout layout{
        {0.0f, 0.0f}, float(world.params().cellM), {world.cellsX(), world.cellsZ()}};
    for (glm::ivec2 c : streaming::flightPathCells(layout, fo, opt.pathRadius)) cells.push_back({c.x, c.y});
  } else {
    cells = selectCells(world, opt.cells);
  }
  if (opt.arraySize > 0) cells = bake::arrayShare(cells, opt.arrayIndex, opt.arraySize);
  return cells;
}

namespace {

// --codec shared: the world's shared model first (reused when up to date; resumable pre-training). False
// when the pre-training was interrupted.
bool prepareSharedModel(const worlds::SyntheticWorld& world, const bake::WorldBakeSettings& settings,
                        const fs::path& out, std::optional<ResolvedSharedModel>& shared) {
  bool reused = false;
  try {
    const SharedModel m = bake::ensureSharedModel(world, settings, out, &reused);
    shared =
        ResolvedSharedModel{dequantizeWeights(m.weights), m.weightsHash(), sharedModelPath(out).string()};
    std::fprintf(stderr, "shared model %s: %s %016llx, %d steps on %s, mean irradiance error %.2f %%\n",
                 shared->name.c_str(), reused ? "up to date" : "trained",
                 static_cast<unsigned long long>(shared->hash), m.stats.steps, m.stats.cells.c_str(),
                 100.0 * m.stats.errorAchieved);
  } catch (const Error& e) {
    if (!InterruptGuard::interrupted()) throw;
    std::fprintf(stderr, "\n%s\n", e.what());
    return false;
  }
  return true;
}

// What the cell loop shares, and its running tally.
struct BakeRun {
  const WorldBakeOptions& opt;
  const worlds::SyntheticWorld& world;
  const fs::path& out;
  const std::optional<ResolvedSharedModel>& shared;
  Progress& progress;
  size_t total = 0;  // cells of this run
  size_t done = 0, skipped = 0, networks = 0;
  size_t bytesTotal = 0;
  std::vector<worlds::CellCoord> failed;
};

enum class CellOutcome { kBaked, kSkipped, kInterrupted };

// One cell: skipped when its file is up to date, else baked, written, read back and recorded. Throws
// when the cell fails.
CellOutcome bakeOneCell(BakeRun& run, const worlds::CellCoord c) {
  const bake::WorldBakeSettings& settings = run.opt.settings;
  const fs::path& out = run.out;
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const fs::path file = bake::cellFilePath(out, c);
  bake::CellBakeInputs inputs =
      bake::prepareCellBake(run.world, c, settings, run.shared ? run.shared->hash : 0);
  const double prepareSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
  std::string why;
  const bake::CellBakeState state = bake::cellBakeState(file, inputs.inputHash, &why);
  if (state == bake::CellBakeState::Done) {
    bake::clearCellBakeFailure(out, c);
    ++run.skipped;
    ++run.done;
    run.progress.update(run.done);
    return CellOutcome::kSkipped;
  }
  if (state == bake::CellBakeState::Stale) spdlog::info("{}: inputs changed, rebaking", file.string());
  if (state == bake::CellBakeState::Corrupt) spdlog::warn("rebaking: {}", why);
  if (settings.stageProgress)  // a log (Slurm, CI): where the bake is before the cell's own lines
    std::fprintf(stderr, "cell %d,%d (%s): baking, %zu of %zu cells done\n", c.x, c.z,
                 std::string(worlds::cellKindName(run.world.cellKind(c))).c_str(), run.done, run.total);
  const uint64_t inputHash = inputs.inputHash;
  bake::CellBakeReport report;
  CellFile cf;
  try {
    cf = bake::bakeCell(run.world, std::move(inputs), settings, &report, run.shared ? &*run.shared : nullptr);
  } catch (const Error&) {
    if (!InterruptGuard::interrupted()) throw;
    // Interrupted mid-cell: that cell is not written (bakeCell throws rather than return a partial
    // model).
    // Only the per-cell codec's model search keeps checkpoints (bake/world_bake.h checkpointDir).
    const bool kept = settings.codec == "per-cell" && !settings.checkpointDir.empty();
    std::fprintf(
        stderr,
        "\nbake: interrupted during cell %d,%d (not written%s) after %zu cells; run the same command "
        "again to resume\n",
        c.x, c.z, kept ? "; its training checkpoints are kept" : "", run.done);
    return CellOutcome::kInterrupted;
  }
  if (run.opt.reproducible) cf.stats.trainingSeconds = 0.0;  // the only run-dependent field of the file
  writeCellFile(file, cf);
  CellFileBytes bytes;
  readCellFile(file, &bytes);  // read back through every check: what we wrote is what a reader accepts
  if (!settings.checkpointDir.empty()) bake::removeCellCheckpoints(settings.checkpointDir, c);
  bake::CellBakeRecord record;
  record.cell = c;
  record.kind = run.world.cellKind(c);
  record.inputHash = inputHash;
  record.probes = report.probes;
  record.network = report.network;
  record.model = cf.stats.model;
  record.prepareSeconds = prepareSeconds;
  record.captureSeconds = report.captureSeconds;
  record.trainingSeconds = report.trainingSeconds;
  record.totalSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
  record.bytes = bytes.total;
  record.host = bake::hostName();
  record.finishedUtc = bake::utcNow();
  bake::writeCellBakeRecord(out, record);
  bake::clearCellBakeFailure(out, c);
  run.bytesTotal += bytes.total;
  run.networks += report.network ? 1 : 0;
  const std::string target = cf.stats.errorTarget > 0.0
                                 ? fmt::format("target {:.1f} %", 100.0 * cf.stats.errorTarget)
                                 : std::string("no search, no target");
  std::fprintf(stderr, "\ncell %d,%d: %zu probes, %s, irradiance error %.2f %% (%s), %zu bytes, %.1f s\n",
               c.x, c.z, report.probes, cf.stats.model.c_str(), 100.0 * cf.stats.errorAchieved,
               target.c_str(), bytes.total, record.totalSeconds);
  return CellOutcome::kBaked;
}

// The closing summary; exit code 1 when any cell failed.
int reportBake(const BakeRun& run, size_t cellCount) {
  const fs::path& out = run.out;
  std::printf(
      "done: %zu cells (%zu already baked, %zu with a network, %zu failed), %zu bytes written, in %s\n",
      cellCount, run.skipped, run.networks, run.failed.size(), run.bytesTotal,
      (out / "cells").string().c_str());
  if (!run.failed.empty()) {
    std::string list;
    for (const worlds::CellCoord c : run.failed) list += fmt::format(" {},{}", c.x, c.z);
    std::fprintf(stderr, "bake: %zu cell(s) failed:%s (errors in %s/cell_X_Z.failed); rerun to retry them\n",
                 run.failed.size(), list.c_str(), (out / "cells").string().c_str());
    return 1;
  }
  return 0;
}

}  // namespace

int runWorldBake(const WorldBakeOptions& options) {
  const worlds::SyntheticWorld world(worlds::readWorldManifest(options.world));
  const std::vector<worlds::CellCoord> cells = selectBakeCells(world, options);
  options.settings.validate();
  const fs::path out = options.outDir.empty() ? fs::path(options.world) / "baked" : fs::path(options.outDir);
  fs::create_directories(out / "cells");
  // How this run works (not hashed): checkpoints beside the cell files, stage lines in a log.
  WorldBakeOptions opt = options;
  opt.settings.checkpointDir = out / "cells";
  opt.settings.stageProgress = ::isatty(STDERR_FILENO) != 1;
  const bake::WorldBakeSettings& settings = opt.settings;

  InterruptGuard guard;
  std::optional<ResolvedSharedModel> shared;
  if (settings.sharedCodec() && !prepareSharedModel(world, settings, out, shared)) return 130;
  Progress progress("bake", cells.size(), "cells");
  BakeRun run{opt, world, out, shared, progress, cells.size()};
  for (const worlds::CellCoord c : cells) {
    if (InterruptGuard::interrupted()) {
      std::fprintf(stderr, "bake: interrupted after %zu cells; run the same command again to resume\n",
                   run.done);
      return 130;
    }
    // A failing cell is recorded (cells/cell_X_Z.failed) and the rest are still tried; the exit code is
    // non-zero at the end, so a Slurm task fails and is retried (scripts/slurm/bake.sbatch).
    try {
      const CellOutcome outcome = bakeOneCell(run, c);
      if (outcome == CellOutcome::kInterrupted) return 130;
      if (outcome == CellOutcome::kSkipped) continue;
    } catch (const std::exception& e) {
      if (InterruptGuard::interrupted()) {
        std::fprintf(stderr,
                     "\nbake: interrupted during cell %d,%d (not written) after %zu cells; run the same "
                     "command again to resume\n",
                     c.x, c.z, run.done);
        return 130;
      }
      std::fprintf(stderr, "\ncell %d,%d: failed: %s\n", c.x, c.z, e.what());
      bake::writeCellBakeFailure(out, c, e.what());
      run.failed.push_back(c);
    }
    ++run.done;
    run.progress.update(run.done);
  }
  progress.finish();
  const int code = reportBake(run, cells.size());
  if (opt.arraySize > 0 || opt.regionCells == 0) return code;
  return std::max(code, runPack({opt.world, out.string(), opt.regionCells}));
}

int runPack(const PackOptions& opt) {
  const worlds::WorldParams params = worlds::readWorldManifest(opt.world);
  const int cells = int(std::lround(params.sizeM / params.cellM));
  const fs::path out = opt.outDir.empty() ? fs::path(opt.world) / "baked" : fs::path(opt.outDir);
  const auto t0 = std::chrono::steady_clock::now();
  const PackStats s = packRegions(out / "cells", out / "regions", {cells, cells}, opt.regionCells);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const std::string& e : s.skipped) std::fprintf(stderr, "pack: left out: %s\n", e.c_str());
  std::printf(
      "pack: %d cells in %d regions of %dx%d (%d written, %d unchanged, %d removed), %llu bytes "
      "(%llu written) in %.1f s: light field %llu B, probe masks %llu B, container %.1f B/cell -> %s\n",
      s.cells, s.regions, opt.regionCells, opt.regionCells, s.written, s.unchanged, s.removed,
      (unsigned long long)s.bytes, (unsigned long long)s.bytesWritten, seconds,
      (unsigned long long)s.parts.payload, (unsigned long long)s.parts.topology,
      s.parts.containerPerCell(size_t(s.cells)), (out / "regions").string().c_str());
  return s.skipped.empty() ? 0 : 1;
}

}  // namespace lfgi::app
