// `lfgi demo`: the newest end-to-end path that exists, on the small embedded default world.
//  1. Sky probe: the Preetham sky + sun for the chosen time and weather in an octahedral radiance map;
//     irradiance by the GPU pass (exact solid angles), checked against the CPU integral, and the SH L1/L2
//     approximations (Ramamoorthi & Hanrahan 2001) measured against it.
//  2. World: the 256 m x 256 m default synthetic world, every cell built (mesh, probes placed and
//     classified, surfels + Draco), resumable.
//  3. Pictures: a top-down sunlit preview of the world, the sky map and its irradiance maps.
// Writes report.md / report.json, EXR + PNG images and a Chrome trace under --out.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "app/commands.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/image.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/sh.h"
#include "core/trace.h"
#include "gpu/context.h"
#include "gpu/irradiance_pass.h"
#include "worlds/sky.h"
#include "worlds/topdown_preview.h"
#include "worlds/world_cells.h"

namespace lfgi::app {
namespace {

Image mapImage(const std::vector<glm::vec3>& texels, int n) {
  Image img(n, n, {"R", "G", "B"});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = texels[size_t(j) * size_t(n) + size_t(i)][c];
  return img;
}

// Nearest-neighbour upscale of an n x n map into a size x size panel at (x0, 0) of `dst`, times `scale`.
void blitPanel(Image& dst, const std::vector<glm::vec3>& texels, int n, int x0, int size, float scale) {
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const glm::vec3& v = texels[size_t(y * n / size) * size_t(n) + size_t(x * n / size)];
      for (int c = 0; c < 3; ++c) dst.at(x0 + x, y, c) = v[c] * scale;
    }
}

struct ProbeDemo {
  double gpuMs = 0.0, gpuVsCpu = 0.0, l1Err = 0.0, l2Err = 0.0;
  int n = 0, m = 0;
};

ProbeDemo skyProbe(gpu::Context& ctx, const worlds::SkyModel& sky, int n, const std::filesystem::path& out,
                   TraceWriter& trace) {
  ProbeDemo r;
  r.n = n;
  r.m = std::max(4, n / 2);
  const int m = r.m;
  std::vector<float> flat = worlds::skyOctahedralMap(sky, n, true);
  std::vector<glm::vec3> radiance(size_t(n) * size_t(n));
  for (size_t i = 0; i < radiance.size(); ++i) radiance[i] = {flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]};
  std::vector<glm::vec3> irrGpu;
  {
    TraceScope s(&trace, "GPU irradiance convolution (incl. upload, readback)");
    gpu::IrradianceConvolution pass(ctx);
    irrGpu = pass.run(radiance, n, m, 1, &r.gpuMs);
  }
  std::vector<glm::vec3> irrCpu(size_t(m) * size_t(m)), irrL1(irrCpu.size()), irrL2(irrCpu.size());
  {
    TraceScope s(&trace, "CPU brute-force irradiance + SH L1/L2");
    std::vector<double> omega = octTexelSolidAngles(n);
    ShL1 l1 = shProject<4>(flat, n);
    ShL2 l2 = shProject<9>(flat, n);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        glm::vec3 normal = octTexelDirection(i, j, m);
        size_t k = size_t(j) * size_t(m) + size_t(i);
        irrCpu[k] = bruteForceIrradiance(flat, n, normal, omega);
        irrL1[k] = shIrradiance(l1, normal);
        irrL2[k] = shIrradiance(l2, normal);
      }
  }
  auto span = [](const std::vector<glm::vec3>& v) { return std::span<const float>(&v[0].x, v.size() * 3); };
  r.gpuVsCpu = relativeRms(span(irrGpu), span(irrCpu));
  r.l1Err = relativeRms(span(irrL1), span(irrCpu));
  r.l2Err = relativeRms(span(irrL2), span(irrCpu));

  TraceScope s(&trace, "write probe images");
  writeExr(out / "sky_radiance.exr", mapImage(radiance, n));
  writeExr(out / "irradiance_gpu.exr", mapImage(irrGpu, m));
  writeExr(out / "irradiance_sh_l2.exr", mapImage(irrL2, m));
  // Side by side: sky radiance | irradiance (GPU, exact) | SH L2 irradiance | L2 error.
  const int size = 256, gap = 8;
  Image panel(4 * size + 3 * gap, size, {"R", "G", "B"});
  double meanIrr = 0.0;
  for (const glm::vec3& v : irrCpu) meanIrr += (v.r + v.g + v.b) / 3.0;
  meanIrr /= double(irrCpu.size());
  const float scale = float(0.35 / meanIrr);
  std::vector<glm::vec3> skyOnly(radiance.size());  // the sun texels would saturate the picture
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      skyOnly[size_t(j) * size_t(n) + size_t(i)] = worlds::skyRadiance(sky, octTexelDirection(i, j, n));
  blitPanel(panel, skyOnly, n, 0, size, scale * std::numbers::pi_v<float> * 2.0f);
  blitPanel(panel, irrGpu, m, size + gap, size, scale);
  blitPanel(panel, irrL2, m, 2 * (size + gap), size, scale);
  std::vector<glm::vec3> relErr(irrCpu.size());
  for (size_t k = 0; k < relErr.size(); ++k)
    relErr[k] = glm::vec3(10.0f * glm::length(irrL2[k] - irrCpu[k]) / glm::length(irrCpu[k]));
  blitPanel(panel, relErr, m, 3 * (size + gap), size, 1.0f);
  writePng(out / "probe.png", panel, 0.0f, ToneMap::kReinhard);
  return r;
}

// 2. World: every cell built (resumable: cells already written are read back), totals summed from each
// cell's JSON. False when interrupted.
bool buildWorldCells(const worlds::SyntheticWorld& world, const std::filesystem::path& worldDir,
                     TraceWriter& trace, nlohmann::ordered_json& totals) {
  const size_t cellCount = size_t(world.cellsX()) * size_t(world.cellsZ());
  TraceScope s(&trace, "build world cells");
  InterruptGuard guard;
  Progress progress("world cells", cellCount, "cells");
  size_t done = 0;
  for (int z = 0; z < world.cellsZ(); ++z)
    for (int x = 0; x < world.cellsX(); ++x) {
      if (InterruptGuard::interrupted()) {
        progress.finish();
        spdlog::warn("interrupted; run the demo again to resume");
        return false;
      }
      if (!worlds::cellDone(worldDir, {x, z})) {
        TraceScope cs(&trace, fmt::format("cell {},{}", x, z), "cell");
        worlds::writeCell(worldDir, worlds::buildCell(world, {x, z}));
      }
      nlohmann::ordered_json j = worlds::readCellJson(worldDir, {x, z});
      totals["triangles"] = totals["triangles"].get<size_t>() + j["triangles"].get<size_t>();
      totals["surfels"] = totals["surfels"].get<size_t>() + j["surfels"]["count"].get<size_t>();
      totals["surfel_raw_bytes"] =
          totals["surfel_raw_bytes"].get<size_t>() + j["surfels"]["raw_bytes"].get<size_t>();
      totals["surfel_draco_bytes"] =
          totals["surfel_draco_bytes"].get<size_t>() + j["surfels"]["draco_bytes"].get<size_t>();
      for (const char* k : {"total", "active", "relocated", "disabled", "sky_only"}) {
        std::string key = std::string("probes") + (std::string(k) == "total" ? "" : std::string("_") + k);
        totals[key] = totals[key].get<size_t>() + j["probes"][k].get<size_t>();
      }
      progress.update(++done);
    }
  progress.finish();
  return true;
}

// 3. Top-down preview of the whole world (all cells' meshes in one BVH: fine at the default 256 m).
void writeTopDownPreview(const worlds::SyntheticWorld& world, const worlds::WorldParams& wp,
                         const worlds::SkyModel& sky, const std::filesystem::path& out, TraceWriter& trace) {
  TraceScope s(&trace, "top-down preview");
  worlds::TriangleMesh all;
  for (int z = 0; z < world.cellsZ(); ++z)
    for (int x = 0; x < world.cellsX(); ++x) all.append(world.generateCell({x, z}));
  worlds::TriangleBvh bvh(all);
  worlds::Aabb region = all.bounds();
  region.min.x = 0.0f;
  region.min.z = 0.0f;
  region.max.x = float(wp.sizeM);
  region.max.z = float(wp.sizeM);
  Image img = worlds::renderTopDown(all, bvh, sky, region);
  // Exposure: map the median pixel luminance to 0.18.
  std::vector<float> lum;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      lum.push_back(0.2126f * img.at(x, y, 0) + 0.7152f * img.at(x, y, 1) + 0.0722f * img.at(x, y, 2));
  std::nth_element(lum.begin(), lum.begin() + long(lum.size() / 2), lum.end());
  const float median = std::max(lum[lum.size() / 2], 1e-12f);
  writeExr(out / "world_topdown.exr", img);
  writePng(out / "world_topdown.png", img, std::log2(0.18f / median));
}

// What report.json and report.md describe.
struct DemoReport {
  const gpu::Context& ctx;
  const worlds::SkyState& state;
  const worlds::SkyModel& sky;
  const ProbeDemo& probe;
  const worlds::WorldParams& wp;
  const std::filesystem::path& worldDir;
  size_t cellCount;
  const nlohmann::ordered_json& totals;
};

nlohmann::ordered_json reportJson(const DemoReport& r) {
  const worlds::SkyState& state = r.state;
  const ProbeDemo& probe = r.probe;
  nlohmann::ordered_json report;
  report["device"] = r.ctx.info.name;
  report["device_type"] = r.ctx.info.type;
  report["sky"] = {{"time_of_day_h", state.timeOfDayHours},
                   {"latitude_deg", state.latitudeDeg},
                   {"day_of_year", state.dayOfYear},
                   {"turbidity", state.turbidity},
                   {"overcast", state.overcast},
                   {"sun_elevation_deg", r.sky.sunPosition.elevationDeg}};
  report["probe"] = {{"radiance_resolution", probe.n},   {"irradiance_resolution", probe.m},
                     {"gpu_irradiance_ms", probe.gpuMs}, {"gpu_vs_cpu_irr_rel_rms", probe.gpuVsCpu},
                     {"sh_l1_irr_rel_rms", probe.l1Err}, {"sh_l2_irr_rel_rms", probe.l2Err}};
  report["world"] = {{"size_m", r.wp.sizeM}, {"cell_m", r.wp.cellM}, {"seed", r.wp.seed}};
  report["world"].update(r.totals);
  report["validation_errors"] = r.ctx.validationErrors.load();
  return report;
}

std::string reportMarkdown(const DemoReport& r) {
  const worlds::SkyState& state = r.state;
  const ProbeDemo& probe = r.probe;
  const worlds::WorldParams& wp = r.wp;
  const nlohmann::ordered_json& totals = r.totals;
  const double ratio = double(totals["surfel_raw_bytes"].get<size_t>()) /
                       std::max<double>(1.0, double(totals["surfel_draco_bytes"].get<size_t>()));
  return fmt::format(
      "# lfgi demo\n\n"
      "Device: **{}** ({}). Sky: {:.1f} h, latitude {:.0f}, day {}, turbidity {:.1f}, overcast {:.2f} "
      "(sun elevation {:.1f} deg).\n\n"
      "## World ({:.0f} m x {:.0f} m, cells of {:.0f} m, seed {})\n\n"
      "![top-down preview: direct sun with shadows + sky, no bounces](world_topdown.png)\n\n"
      "| measure | value |\n|---|---|\n"
      "| cells | {} |\n| triangles | {} |\n| surfels | {} (Draco {:.1f} MB, {:.2f} x smaller than raw) |\n"
      "| probes | {} placed: {} active, {} relocated, {} disabled (in solid), {} sky-only |\n\n"
      "Cells, probes and surfels are in `world/` (`lfgi world info {}`; `lfgi world export-cell {} --cell "
      "1,1 "
      "--out cell.glb` writes a cell for any glTF viewer).\n\n"
      "## Sky probe\n\n"
      "![sky radiance | exact irradiance (GPU) | SH L2 irradiance | L2 relative error](probe.png)\n\n"
      "Panels: sky radiance (sun left out of the picture, not the maths) | exact irradiance (GPU) | SH L2 "
      "irradiance | L2 relative error (brighter = larger; x10, tone-mapped). Octahedral {}x{} radiance, "
      "{}x{} irradiance.\n\n"
      "| measure | value |\n|---|---|\n"
      "| GPU irradiance pass (device time) | {:.3f} ms |\n"
      "| GPU vs CPU exact irradiance, relative RMS | {:.2e} |\n"
      "| SH L1 irradiance vs exact, relative RMS | {:.1f} % |\n"
      "| SH L2 irradiance vs exact, relative RMS | {:.1f} % |\n\n"
      "Files: `*.exr` (linear float), `report.json`, `trace.json` (open in https://ui.perfetto.dev).\n",
      r.ctx.info.name, r.ctx.info.type, state.timeOfDayHours, state.latitudeDeg, state.dayOfYear,
      state.turbidity, state.overcast, r.sky.sunPosition.elevationDeg, wp.sizeM, wp.sizeM, wp.cellM, wp.seed,
      r.cellCount, totals["triangles"].get<size_t>(), totals["surfels"].get<size_t>(),
      double(totals["surfel_draco_bytes"].get<size_t>()) * 1e-6, ratio, totals["probes"].get<size_t>(),
      totals["probes_active"].get<size_t>(), totals["probes_relocated"].get<size_t>(),
      totals["probes_disabled"].get<size_t>(), totals["probes_sky_only"].get<size_t>(), r.worldDir.string(),
      r.worldDir.string(), probe.n, probe.n, probe.m, probe.m, probe.gpuMs, probe.gpuVsCpu,
      100.0 * probe.l1Err, 100.0 * probe.l2Err);
}

}  // namespace

int runDemo(const DemoOptions& opt) {
  const std::filesystem::path out = opt.outDir;
  TraceWriter trace;
  trace.setThreadName("main");

  std::unique_ptr<gpu::Context> ctx;
  {
    TraceScope s(&trace, "create Vulkan context");
    ctx = gpu::createContext();
  }
  spdlog::info("device: {} ({})", ctx->info.name, ctx->info.type);
  worlds::SkyState state;
  state.timeOfDayHours = opt.timeOfDay;
  state.overcast = opt.overcast;
  const worlds::SkyModel sky = worlds::makeSky(state);

  // 1. Sky probe.
  ProbeDemo probe = skyProbe(*ctx, sky, opt.resolution, out, trace);
  spdlog::info(
      "sky probe: GPU irradiance {:.3f} ms; GPU vs CPU rel RMS {:.2e}; SH L1 {:.1f} %, L2 {:.1f} % rel RMS",
      probe.gpuMs, probe.gpuVsCpu, 100.0 * probe.l1Err, 100.0 * probe.l2Err);
  if (probe.gpuVsCpu > 1e-4)
    fail("GPU and CPU irradiance disagree (relative RMS {:.2e} > 1e-4) on '{}'", probe.gpuVsCpu,
         ctx->info.name);

  // 2. World.
  worlds::WorldParams wp = worlds::WorldParams::smallDefault(opt.seed);
  wp.sizeM = opt.worldSizeM;
  worlds::SyntheticWorld world(wp);
  const std::filesystem::path worldDir = out / "world";
  worlds::writeWorldManifest(worldDir, wp);
  const size_t cellCount = size_t(world.cellsX()) * size_t(world.cellsZ());
  nlohmann::ordered_json totals = {{"cells", cellCount},    {"triangles", 0},          {"surfels", 0},
                                   {"surfel_raw_bytes", 0}, {"surfel_draco_bytes", 0}, {"probes", 0},
                                   {"probes_active", 0},    {"probes_relocated", 0},   {"probes_disabled", 0},
                                   {"probes_sky_only", 0}};
  if (!buildWorldCells(world, worldDir, trace, totals)) return 130;

  // 3. Top-down preview.
  writeTopDownPreview(world, wp, sky, out, trace);

  const DemoReport report{*ctx, state, sky, probe, wp, worldDir, cellCount, totals};
  writeFileAtomic(out / "report.json", reportJson(report).dump(2) + "\n");
  trace.save(out / "trace.json");
  writeFileAtomic(out / "report.md", reportMarkdown(report));
  spdlog::info("wrote {}", (out / "report.md").string());
  return 0;
}

}  // namespace lfgi::app
