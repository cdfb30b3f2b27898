// `lfgi bake-status`: where a world bake stands (cells done / stale / missing / failed / corrupt, ETA from
// the measured cell seconds by kind), and with --plan the cost model (bake/bake_records.h) projected to
// larger worlds on N nodes, printed and written as plan.csv + plan.json (default out/bench/bake/, read by
// bench/bake.sh and bench/bake.gp).
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "app/world_bake_command.h"
#include "bake/bake_records.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/progress.h"
#include "worlds/world_cells.h"

namespace lfgi::app {

namespace fs = std::filesystem;

namespace {

constexpr size_t kKinds = bake::kCellKindCount;

std::string kindName(size_t k) {
  return std::string(worlds::cellKindName(worlds::CellKind(k)));
}

void printModel(const bake::BakeCostModel& model, const fs::path& out) {
  std::printf("measured (%zu bake records in %s):\n", model.totalSamples, (out / "cells").string().c_str());
  for (size_t k = 0; k < kKinds; ++k) {
    if (model.samples[k])
      std::printf("  %-7s %4zu cells  %8.2f s/cell\n", kindName(k).c_str(), model.samples[k],
                  model.meanSeconds[k]);
    else
      std::printf("  %-7s    0 cells  %8.2f s/cell (not measured: the mean of all kinds)\n",
                  kindName(k).c_str(), model.overallMeanSeconds);
  }
}

int runPlan(const BakeStatusOptions& opt, const worlds::SyntheticWorld& world, const fs::path& out) {
  if (opt.nodes < 1) fail("--nodes {}: must be at least 1", opt.nodes);
  if (opt.sizesKm2.empty()) fail("--size-km2: give at least one world size");
  const bake::BakeCostModel model = bake::costModelFromRecords(bake::readAllCellBakeRecords(out));
  printModel(model, out);
  std::vector<int> nodeCounts{1};
  if (opt.nodes != 1) nodeCounts.push_back(opt.nodes);

  std::string csv =
      "size_km2,world_m,world_km2,cells,field_cells,suburb_cells,city_cells,park_cells,cell_hours,nodes,"
      "hours\n";
  nlohmann::ordered_json j;
  j["source"] = out.string();
  j["cell_m"] = world.cellSizeM();
  j["seed"] = world.params().seed;
  j["assumption"] = "nodes like the measured one, one cell at a time per node, perfect packing";
  nlohmann::ordered_json measured;
  for (size_t k = 0; k < kKinds; ++k)
    measured[kindName(k)] = {{"cells", model.samples[k]},
                             {"seconds_per_cell", model.secondsPerCell(worlds::CellKind(k))}};
  j["measured"] = measured;
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();

  std::printf(
      "\nprojection (cells of %g m, seed %llu; kind mix from the world generator, no meshes built):\n",
      world.cellSizeM(), static_cast<unsigned long long>(world.params().seed));
  std::printf("  %9s %9s %8s %8s %8s %8s %8s %11s", "km2", "world m", "cells", "field", "suburb", "city",
              "park", "cell-hours");
  for (int n : nodeCounts) std::printf(" %12s", fmt::format("h @ {} node{}", n, n == 1 ? "" : "s").c_str());
  std::printf("\n");
  for (double km2 : opt.sizesKm2) {
    const worlds::WorldParams params = bake::worldParamsForArea(km2, world.cellSizeM(), world.params().seed);
    const bake::BakeProjection p = bake::projectBake(model, params);
    const auto& c = p.mix.cellsByKind;
    std::printf("  %9.2f %9.0f %8zu %8zu %8zu %8zu %8zu %11.2f", p.mix.km2, p.mix.sizeM, p.mix.cells, c[0],
                c[1], c[2], c[3], p.hours(1));
    for (int n : nodeCounts) {
      std::printf(" %12.3f", p.hours(n));
      csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{}\n", km2, p.mix.sizeM, p.mix.km2, p.mix.cells, c[0],
                         c[1], c[2], c[3], p.hours(1), n, p.hours(n));
      rows.push_back({{"size_km2", km2},
                      {"world_km2", p.mix.km2},
                      {"cells", p.mix.cells},
                      {"cells_by_kind", {{"field", c[0]}, {"suburb", c[1]}, {"city", c[2]}, {"park", c[3]}}},
                      {"nodes", n},
                      {"hours", p.hours(n)}});
    }
    std::printf("\n");
  }
  j["projections"] = rows;
  if (!opt.planOut.empty()) {
    const fs::path dir(opt.planOut);
    writeFileAtomic(dir / "plan.csv", csv);
    writeFileAtomic(dir / "plan.json", j.dump(2) + "\n");
    std::printf("wrote %s and plan.json\n", (dir / "plan.csv").string().c_str());
  }
  return 0;
}

}  // namespace

int runBakeStatus(const BakeStatusOptions& opt) {
  const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.bake.world));
  const fs::path out =
      opt.bake.outDir.empty() ? fs::path(opt.bake.world) / "baked" : fs::path(opt.bake.outDir);
  if (opt.plan) return runPlan(opt, world, out);

  const std::vector<worlds::CellCoord> cells = selectBakeCells(world, opt.bake);
  const bake::WorldBakeSettings& settings = opt.bake.settings;
  settings.validate();
  InterruptGuard guard;
  const std::vector<bake::CellStatusEntry> status =
      bake::worldBakeStatus(world, cells, settings, out, !opt.quiet);

  std::array<size_t, 5> count{};
  for (const bake::CellStatusEntry& e : status) ++count[size_t(e.status)];
  std::printf("world %s: %d x %d cells of %g m; bake output %s\n", opt.bake.world.c_str(), world.cellsX(),
              world.cellsZ(), world.cellSizeM(), out.string().c_str());
  std::printf("cells: %zu  done %zu  stale %zu  missing %zu  failed %zu  corrupt %zu\n", status.size(),
              count[size_t(bake::CellStatus::Done)], count[size_t(bake::CellStatus::Stale)],
              count[size_t(bake::CellStatus::Missing)], count[size_t(bake::CellStatus::Failed)],
              count[size_t(bake::CellStatus::Corrupt)]);
  for (const bake::CellStatusEntry& e : status)
    if (e.status == bake::CellStatus::Failed || e.status == bake::CellStatus::Corrupt)
      std::printf("  %s %d,%d: %s\n", bake::cellStatusName(e.status), e.cell.x, e.cell.z, e.detail.c_str());
  if (opt.listStale)
    for (const bake::CellStatusEntry& e : status)
      if (e.status == bake::CellStatus::Stale) std::printf("  stale %d,%d\n", e.cell.x, e.cell.z);

  // ETA: the cells left, each at its kind's measured mean (records of this output directory).
  const size_t left = status.size() - count[size_t(bake::CellStatus::Done)];
  const std::vector<bake::CellBakeRecord> records = bake::readAllCellBakeRecords(out);
  if (left == 0) {
    std::printf("ETA: nothing left to bake\n");
  } else if (records.empty()) {
    std::printf(
        "ETA: unknown (%zu cells left, no measured cells yet: cells/cell_X_Z.json appear as cells finish)\n",
        left);
  } else {
    const bake::BakeCostModel model = bake::costModelFromRecords(records);
    double seconds = 0.0;
    for (const bake::CellStatusEntry& e : status)
      if (e.status != bake::CellStatus::Done) seconds += model.secondsPerCell(e.kind);
    const int nodes = std::max(1, opt.nodes);
    std::printf("ETA: %zu cells left, %s on %d node%s (measured s/cell by kind from %zu records)\n", left,
                Progress::formatDuration(seconds / nodes).c_str(), nodes, nodes == 1 ? "" : "s",
                records.size());
  }
  return 0;
}

}  // namespace lfgi::app
