// `lfgi world generate | info | export-cell | edit`: the synthetic world as cells on disk
// (worlds/world_cells.h) and its hand edits (worlds/world_edits.h).
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <map>
#include <mutex>
#include <thread>

#include "app/cli_args.h"
#include "app/commands.h"
#include "core/error.h"
#include "core/progress.h"
#include "worlds/gltf_io.h"
#include "worlds/world_cells.h"

namespace lfgi::app {

int runWorldGenerate(const WorldGenerateOptions& opt) {
  worlds::WorldParams params;
  params.seed = opt.seed;
  params.sizeM = opt.sizeM;
  params.cellM = opt.cellM;
  (void)worlds::SyntheticWorld(params);  // validates
  worlds::writeWorldManifest(opt.outDir, params);
  params = worlds::readWorldManifest(opt.outDir);  // an existing manifest's edits apply to the cells
  const worlds::SyntheticWorld world(params);
  std::vector<worlds::CellCoord> todo;
  if (opt.all) {
    for (int z = 0; z < world.cellsZ(); ++z)
      for (int x = 0; x < world.cellsX(); ++x) todo.push_back({x, z});
  }
  for (const std::string& c : opt.cells) {
    worlds::CellCoord cc = parseCellArg(c, "--cells");
    if (!world.contains(cc))
      fail("--cells {}: outside the world ({} x {} cells)", c, world.cellsX(), world.cellsZ());
    todo.push_back(cc);
  }
  spdlog::info("world: {} m x {} m, cells of {} m ({} x {}), seed {} -> {}", params.sizeM, params.sizeM,
               params.cellM, world.cellsX(), world.cellsZ(), params.seed, opt.outDir);
  if (todo.empty()) {
    spdlog::info("wrote the manifest; cells are generated on demand, or all now with --all");
    return 0;
  }
  const size_t total = todo.size();
  std::vector<worlds::CellCoord> pending;
  for (const auto& c : todo)
    if (!worlds::cellDone(opt.outDir, c)) pending.push_back(c);
  const size_t already = total - pending.size();
  if (already > 0) spdlog::info("resuming: {} of {} cells already done", already, total);

  InterruptGuard guard;
  Progress progress("cells", total, "cells", already);
  std::atomic<size_t> next{0}, done{already};
  std::mutex errorMutex;
  std::string firstError;
  auto worker = [&] {
    while (!InterruptGuard::interrupted()) {
      size_t i = next.fetch_add(1);
      if (i >= pending.size()) return;
      try {
        worlds::writeCell(opt.outDir, worlds::buildCell(world, pending[i]));
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(errorMutex);
        if (firstError.empty()) firstError = e.what();
        return;
      }
      ++done;
    }
  };
  const int threads = std::max(1, opt.threads > 0 ? opt.threads : int(std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  auto failed = [&] {
    std::lock_guard<std::mutex> lock(errorMutex);
    return !firstError.empty();
  };
  while (done.load() < total && !failed() && !InterruptGuard::interrupted()) {
    progress.update(done.load());
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  for (auto& t : pool) t.join();
  progress.update(done.load());
  progress.finish();
  if (!firstError.empty()) fail("{}", firstError);
  if (InterruptGuard::interrupted()) {
    spdlog::warn("interrupted after {} of {} cells; run the same command again to resume", done.load(),
                 total);
    return 130;
  }
  spdlog::info("done: {} cells in {}", total, opt.outDir);
  return 0;
}

int runWorldInfo(const WorldInfoOptions& opt) {
  worlds::WorldParams params = worlds::readWorldManifest(opt.dir);
  worlds::SyntheticWorld world(params);
  size_t cells = 0, triangles = 0, surfels = 0, surfelRaw = 0, surfelDraco = 0;
  std::map<std::string, size_t> probes, categories, kinds;
  double area = 0.0;
  for (int z = 0; z < world.cellsZ(); ++z)
    for (int x = 0; x < world.cellsX(); ++x) {
      if (!worlds::cellDone(opt.dir, {x, z})) continue;
      nlohmann::ordered_json j = worlds::readCellJson(opt.dir, {x, z});
      try {
        ++cells;
        triangles += j.at("triangles").get<size_t>();
        area += j.at("surface_area_m2").get<double>();
        surfels += j.at("surfels").at("count").get<size_t>();
        surfelRaw += j.at("surfels").at("raw_bytes").get<size_t>();
        surfelDraco += j.at("surfels").at("draco_bytes").get<size_t>();
        for (auto& [k, v] : j.at("probes").items()) probes[k] += v.get<size_t>();
        for (auto& [k, v] : j.at("category_triangles").items()) categories[k] += v.get<size_t>();
        ++kinds[j.at("kind").get<std::string>()];
      } catch (const nlohmann::json::exception& e) {
        fail("{}: missing or wrong field ({})", worlds::cellJsonPath(opt.dir, {x, z}).string(), e.what());
      }
    }
  nlohmann::ordered_json j;
  j["seed"] = params.seed;
  j["size_m"] = params.sizeM;
  j["cell_m"] = params.cellM;
  j["cells_total"] = world.cellsX() * world.cellsZ();
  j["cells_generated"] = cells;
  j["triangles"] = triangles;
  j["surface_area_m2"] = area;
  j["surfels"] = surfels;
  j["surfel_raw_bytes"] = surfelRaw;
  j["surfel_draco_bytes"] = surfelDraco;
  j["surfel_compression_ratio"] = surfelDraco ? double(surfelRaw) / double(surfelDraco) : 0.0;
  j["probes"] = probes;
  j["category_triangles"] = categories;
  j["cell_kinds"] = kinds;
  if (opt.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("world %s: %.0f m x %.0f m, cells %.0f m, seed %llu\n", opt.dir.c_str(), params.sizeM,
              params.sizeM, params.cellM, (unsigned long long)params.seed);
  std::printf("cells generated   %zu of %d%s\n", cells, world.cellsX() * world.cellsZ(),
              cells == 0 ? " (run `lfgi world generate ... --all`)" : "");
  std::printf("triangles         %zu (%.0f m2 of surface)\n", triangles, area);
  std::printf("surfels           %zu, Draco %zu bytes (%.2f x smaller than raw %zu)\n", surfels, surfelDraco,
              j["surfel_compression_ratio"].get<double>(), surfelRaw);
  std::printf("probes            ");
  for (auto& [k, v] : probes) std::printf("%s %zu  ", k.c_str(), v);
  std::printf("\ncell kinds        ");
  for (auto& [k, v] : kinds) std::printf("%s %zu  ", k.c_str(), v);
  std::printf("\ntriangles by kind ");
  for (auto& [k, v] : categories) std::printf("%s %zu  ", k.c_str(), v);
  std::printf("\n");
  return 0;
}

int runWorldEdit(const WorldEditOptions& opt) {
  std::vector<worlds::WorldEdit> edits;
  for (const auto& [flag, text] : opt.edits) {
    worlds::WorldEditKind kind = worlds::WorldEditKind::kAddBox;
    if (flag == "add-building")
      kind = worlds::WorldEditKind::kAddBuilding;
    else if (flag == "clear-region")
      kind = worlds::WorldEditKind::kClearRegion;
    else if (flag != "add-box")
      fail("world edit: unknown edit flag --{}", flag);
    edits.push_back(worlds::parseWorldEdit(kind, text));
  }
  if (edits.empty())
    fail("world edit {}: nothing to do (give --add-building, --add-box or --clear-region)", opt.dir);
  const worlds::SyntheticWorld before(worlds::readWorldManifest(opt.dir));
  const worlds::SyntheticWorld after(worlds::appendWorldEdits(opt.dir, edits));
  // Cells whose content changed: compare the content hashes of every cell the new edits overlap.
  std::vector<worlds::CellCoord> candidates, changed;
  for (const worlds::WorldEdit& e : edits)
    for (const worlds::CellCoord c : after.editCells(e))
      if (std::find(candidates.begin(), candidates.end(), c) == candidates.end()) candidates.push_back(c);
  std::sort(candidates.begin(), candidates.end(),
            [](auto a, auto b) { return a.z != b.z ? a.z < b.z : a.x < b.x; });
  for (const worlds::CellCoord c : candidates)
    if (before.generateCell(c).contentHash() != after.generateCell(c).contentHash()) changed.push_back(c);
  // Bake inputs: a cell's capture scene is its 3 x 3 block (bake/world_bake.h), and probe placement reads
  // the neighbours' solids, so every in-world cell next to a changed one is stale too.
  std::vector<worlds::CellCoord> stale;
  for (int z = 0; z < after.cellsZ(); ++z)
    for (int x = 0; x < after.cellsX(); ++x)
      for (const worlds::CellCoord c : changed)
        if (std::abs(c.x - x) <= 1 && std::abs(c.z - z) <= 1) {
          stale.push_back({x, z});
          break;
        }
  auto list = [](const std::vector<worlds::CellCoord>& cells) {
    std::string s;
    for (const worlds::CellCoord c : cells) s += fmt::format(" {},{}", c.x, c.z);
    return s.empty() ? std::string(" none") : s;
  };
  // Generated cell directories (lfgi world generate) of stale cells are out of date: drop their finished
  // marker so the next `lfgi world generate --all` rebuilds them.
  size_t regenerate = 0;
  for (const worlds::CellCoord c : stale) {
    std::error_code ec;
    if (std::filesystem::remove(worlds::cellJsonPath(opt.dir, c), ec)) ++regenerate;
  }
  std::printf("world edit: %zu edit(s) appended to %s (%zu in all)\n", edits.size(),
              (std::filesystem::path(opt.dir) / "world.json").string().c_str(), after.params().edits.size());
  std::printf("content changed in %zu cells:%s\n", changed.size(), list(changed).c_str());
  std::printf("bake inputs changed in %zu cells (changed cells and their in-world neighbours):%s\n",
              stale.size(), list(stale).c_str());
  if (regenerate > 0)
    std::printf(
        "%zu generated cells are out of date; rerun `lfgi world generate --out %s --all ...` to rebuild "
        "them\n",
        regenerate, opt.dir.c_str());
  return 0;
}

int runWorldExportCell(const WorldExportOptions& opt) {
  worlds::WorldParams params = worlds::readWorldManifest(opt.dir);
  worlds::SyntheticWorld world(params);
  worlds::CellCoord c = parseCellArg(opt.cell, "--cell");
  if (!world.contains(c))
    fail("--cell {}: outside the world ({} x {} cells)", opt.cell, world.cellsX(), world.cellsZ());
  worlds::TriangleMesh mesh = world.generateCell(c);
  worlds::exportGlb(opt.out, mesh);
  spdlog::info("wrote {} ({} triangles, {} materials)", opt.out, mesh.triangleCount(), mesh.materials.size());
  return 0;
}

}  // namespace lfgi::app
