// Benchmark `world_gen`: generating the 4 km x 4 km synthetic world.
//   phase "generate": every cell's mesh + layout (world.generate), in order, sampling resident memory
//                     after each row of cells: cells/s, triangles/s, and memory that must stay flat;
//   phase "build":    the full per-cell bake input (probe placement + surfels + Draco) on a seeded random
//                     sample of cells: cells/s, surfels/s, probes/s, and the surfel-area error vs the mesh
//                     area (the accuracy twin of the speed figures).
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include "bench/bench_output.h"
#include "core/error.h"
#include "worlds/world_cells.h"

namespace {

double rssMb(const char* field) {  // VmRSS (current) or VmHWM (peak), from /proc/self/status
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind(field, 0) == 0) return std::stod(line.substr(std::string(field).size())) / 1024.0;
  return 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lfgi;
  using Clock = std::chrono::steady_clock;
  CLI::App app{"lfgi benchmark: synthetic world generation"};
  std::string out = "out/bench/world_gen";
  bool quick = false;
  double size = 4096.0;
  int sample = 0;
  app.add_option("--out", out, "Output directory");
  app.add_flag("--quick", quick, "Fewer cells in the build phase");
  app.add_option("--size", size, "World size in metres")->capture_default_str();
  app.add_option("--build-sample", sample, "Cells in the build phase (default 12 quick, 64 full)");
  CLI11_PARSE(app, argc, argv);
  if (sample <= 0) sample = quick ? 12 : 64;
  try {
    bench::BenchOutput o(out, quick);
    o.setDevice("cpu (1 thread)");
    worlds::WorldParams params;
    params.sizeM = size;
    worlds::SyntheticWorld world(params);
    const int nx = world.cellsX(), nz = world.cellsZ();
    o.setColumns({"phase", "cells_done", "elapsed_s", "rss_mb", "triangles", "surfels", "probes_active",
                  "surfel_area_rel_error"});

    // Phase 1: every cell's geometry.
    spdlog::info("generate: {} x {} cells of {} m", nx, nz, params.cellM);
    auto t0 = Clock::now();
    size_t triangles = 0, cells = 0;
    double rssFirstRow = 0.0, rssMax = 0.0;
    for (int z = 0; z < nz; ++z) {
      for (int x = 0; x < nx; ++x) {
        worlds::GeneratedCell g = world.generate({x, z});
        triangles += g.mesh.triangleCount();
        ++cells;
      }
      double rss = rssMb("VmRSS:");
      if (z == 0) rssFirstRow = rss;
      rssMax = std::max(rssMax, rss);
      double el = std::chrono::duration<double>(Clock::now() - t0).count();
      o.addRow({"generate", std::to_string(cells), bench::num(el), bench::num(rss), std::to_string(triangles),
                "0", "0", "0"});
    }
    const double genSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
    spdlog::info(
        "generate: {} cells, {} triangles in {:.1f} s ({:.0f} cells/s); RSS first row {:.1f} MB, max {:.1f} "
        "MB",
        cells, triangles, genSeconds, double(cells) / genSeconds, rssFirstRow, rssMax);

    // Phase 2: full bake input on a random sample (seeded: the same cells every run).
    std::mt19937 rng(42);
    std::vector<worlds::CellCoord> picks;
    for (int i = 0; i < sample; ++i) picks.push_back({int(rng() % uint32_t(nx)), int(rng() % uint32_t(nz))});
    size_t surfels = 0, probes = 0, built = 0;
    double worstAreaErr = 0.0;
    t0 = Clock::now();
    for (const auto& c : picks) {
      worlds::BuiltCell b = worlds::buildCell(world, c);
      double err = std::abs(worlds::surfelArea(b.surfels) - b.mesh.totalArea()) / b.mesh.totalArea();
      worstAreaErr = std::max(worstAreaErr, err);
      surfels += b.stats.surfels;
      probes += b.stats.probesActive;
      ++built;
      double el = std::chrono::duration<double>(Clock::now() - t0).count();
      o.addRow({"build", std::to_string(built), bench::num(el), bench::num(rssMb("VmRSS:")),
                std::to_string(b.stats.triangles), std::to_string(b.stats.surfels),
                std::to_string(b.stats.probesActive), bench::num(err)});
      spdlog::info("build {}/{}: cell {},{} {} - {} surfels, {} probes, {:.0f} ms", built, picks.size(), c.x,
                   c.z, worlds::cellKindName(b.stats.kind), b.stats.surfels, b.stats.probesActive,
                   b.stats.generateMs + b.stats.placeMs + b.stats.surfelMs);
    }
    const double buildSeconds = std::chrono::duration<double>(Clock::now() - t0).count();

    auto& s = o.summary();
    s["world_km2"] = size * size * 1e-6;
    s["cells"] = cells;
    s["generate_cells_per_s"] = double(cells) / genSeconds;
    s["generate_triangles_per_s"] = double(triangles) / genSeconds;
    s["build_cells_per_s"] = double(built) / buildSeconds;
    s["build_surfels_per_s"] = double(surfels) / buildSeconds;
    s["build_probes_per_s"] = double(probes) / buildSeconds;
    s["rss_first_row_mb"] = rssFirstRow;
    s["rss_max_during_generate_mb"] = rssMax;
    s["peak_rss_mb"] = rssMb("VmHWM:");
    s["surfel_area_max_rel_error"] = worstAreaErr;
    o.save();
    spdlog::info("build: {} cells in {:.1f} s ({:.2f} cells/s, {:.0f} surfels/s)", built, buildSeconds,
                 double(built) / buildSeconds, double(surfels) / buildSeconds);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
