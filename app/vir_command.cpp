// `lfgi vir`: View-Independent Rasterization of one world cell with relighting (gpu/relight_pass.h):
// builds the cell (worlds::buildCell, deterministic: the same surfels and probes as `lfgi world generate`
// stores), relights its surfels for the time of day / weather over bounces + 1 frames (frame 1: sun and
// emission; every later frame adds one bounce and the probe-seen sky), splats them into every probe of
// the cell's grid, and writes into --out:
//   radiance.exr, distance.exr, normal.exr, albedo.exr   N x N tiles (the VIR channels, shared/vir.h)
//   irradiance.exr                                       M x M tiles (probe irradiance without the discs)
//   contact_sheet.png                                    radiance tiles of <= 256 active probes (listed in
//                                                        vir.json), 4x enlarged, auto-exposed
//   vir.json                                             layout, probes, sky, statistics
// Tiles: probe i (core/probe_grid.h linear index, disabled probes included and flagged in vir.json) sits
// at column i % cols, row i / cols, cols = ceil(sqrt(probes)). Only the cell's own surfels are splatted
// and cast shadows (neighbour cells are not loaded).
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "app/cli_args.h"
#include "app/commands.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/image.h"
#include "core/progress.h"
#include "gpu/relight_pass.h"
#include "shared/octahedral.h"
#include "worlds/sky.h"
#include "worlds/world_cells.h"

namespace lfgi::app {
namespace {

namespace fs = std::filesystem;

// Probe tiles of `channels` floats per texel (from get(texel) -> array) laid out cols x rows.
template <typename Get>
Image tileAtlas(int probes, int res, std::vector<std::string> channels, Get get) {
  const int cols = int(std::ceil(std::sqrt(double(probes))));
  const int rows = (probes + cols - 1) / cols;
  Image img(cols * res, rows * res, std::move(channels));
  const int c = img.channelCount();
  for (int p = 0; p < probes; ++p)
    for (int j = 0; j < res; ++j)
      for (int i = 0; i < res; ++i) {
        const size_t t = (size_t(p) * size_t(res) + size_t(j)) * size_t(res) + size_t(i);
        const glm::vec4 v = get(t);
        for (int ch = 0; ch < c; ++ch) img.at((p % cols) * res + i, (p / cols) * res + j, ch) = v[ch];
      }
  return img;
}

// What the stages of `lfgi vir` share: the cell, its probes, the sky, the lighting after the last frame
// and the contact sheet's probes and exposure.
struct VirRun {
  explicit VirRun(const VirCommandOptions& o) : opt(o) {}
  const VirCommandOptions& opt;
  worlds::CellCoord c;
  worlds::SkyModel sky;
  worlds::BuiltCell cell;
  gpu::RelightProbes probes;
  int64_t probeCount = 0;
  int frames = 0;
  gpu::CellLighting lighting;
  gpu::RelightResult last;
  nlohmann::json frameMs = nlohmann::json::array();  // per frame: wall and device ms of the parts
  std::vector<int> shown;                            // the contact sheet's probes
  float exposureEv = 0.0f;                           // the contact sheet's exposure
};

// Every probe of the cell's grid; disabled (solid) probes are inactive.
gpu::RelightProbes relightProbes(const worlds::BuiltCell& cell) {
  gpu::RelightProbes probes;
  probes.grid = cell.probes.grid;
  const int64_t probeCount = probes.grid.probeCount();
  for (int64_t i = 0; i < probeCount; ++i) {
    probes.positions.push_back(cell.probes.position(i));
    probes.active.push_back((cell.probes.flags[size_t(i)] & worlds::kProbeDisabledSolid) ? 0 : 1);
  }
  return probes;
}

// Relight + VIR over bounces + 1 frames, timing each; false when interrupted (nothing written).
bool relightFrames(VirRun& run, gpu::RelightPass& relight, gpu::VirPass& vir, double cellSizeM) {
  gpu::VirOptions virOptions;
  virOptions.resolution = run.opt.resolution;
  virOptions.maxRange = 2.0f * float(cellSizeM);
  gpu::RelightOptions relightOptions;
  gpu::CellLighting& lighting = run.lighting;
  const int frames = run.frames;
  Progress progress("relight + VIR", size_t(frames), "frames");
  for (int f = 0; f < frames; ++f) {
    if (InterruptGuard::interrupted()) {
      std::fprintf(stderr, "vir: interrupted after %d of %d frames; nothing written\n", f, frames);
      return false;
    }
    const auto f0 = std::chrono::steady_clock::now();
    run.last = gpu::relightFrame(relight, vir, run.cell.surfels, run.probes, run.sky.params, virOptions,
                                 relightOptions, lighting);
    run.frameMs.push_back(
        {{"frame", f + 1},
         {"wall", std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - f0).count()},
         {"shadow", run.last.shadowMs},
         {"emitter_shadow", run.last.emitterShadowMs},
         {"light", run.last.lightMs},
         {"vir", lighting.atlas.gpuMs},
         {"vir_splat_reused", lighting.atlas.splatReused},
         {"convolve", lighting.probes.gpuMs + lighting.reflected.gpuMs}});
    progress.update(size_t(f + 1));
  }
  progress.finish();
  return true;
}

// radiance.exr, distance.exr, normal.exr, albedo.exr and irradiance.exr.
void writeAtlases(const VirRun& run, const fs::path& out) {
  const gpu::ProbeAtlas& atlas = run.lighting.atlas;
  const gpu::CellLighting& lighting = run.lighting;
  const int n = atlas.resolution, m = lighting.probes.irradianceResolution, pc = int(run.probeCount);
  writeExr(out / "radiance.exr",
           tileAtlas(pc, n, {"R", "G", "B"}, [&](size_t t) { return atlas.radiance[t]; }));
  writeExr(out / "distance.exr",
           tileAtlas(pc, n, {"r", "r2"}, [&](size_t t) { return glm::vec4(atlas.distance[t], 0.0f, 0.0f); }));
  writeExr(out / "normal.exr",
           tileAtlas(pc, n, {"X", "Y", "Z", "coverage"}, [&](size_t t) { return atlas.normal[t]; }));
  writeExr(out / "albedo.exr", tileAtlas(pc, n, {"R", "G", "B"}, [&](size_t t) { return atlas.albedo[t]; }));
  writeExr(out / "irradiance.exr",
           tileAtlas(pc, m, {"R", "G", "B"}, [&](size_t t) { return lighting.probes.irradiance[t]; }));
}

// Contact sheet: radiance tiles of at most kSheetProbes active probes (every k-th in index order),
// enlarged 4x with a 1-pixel gap; sky texels (coverage 0) show the sky; exposure puts the median
// luminance of the shown texels at 0.18.
void writeContactSheet(VirRun& run, const fs::path& out) {
  const gpu::ProbeAtlas& atlas = run.lighting.atlas;
  const int n = atlas.resolution, pc = int(run.probeCount);
  constexpr size_t kSheetProbes = 256;
  std::vector<int>& shown = run.shown;
  for (int p = 0; p < pc; ++p)
    if (run.probes.active[size_t(p)]) shown.push_back(p);
  if (shown.size() > kSheetProbes) {
    std::vector<int> every;
    for (size_t k = 0; k < kSheetProbes; ++k) every.push_back(shown[k * shown.size() / kSheetProbes]);
    shown = std::move(every);
  }
  if (shown.empty()) shown.push_back(0);
  const int scale = 4, tile = n * scale + 1, sheetCount = int(shown.size());
  const int cols = int(std::ceil(std::sqrt(double(sheetCount)))), rows = (sheetCount + cols - 1) / cols;
  Image sheet(cols * tile + 1, rows * tile + 1, {"R", "G", "B"});
  std::vector<float> lums;
  for (int k = 0; k < sheetCount; ++k) {
    const int p = shown[size_t(k)];
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const size_t t = (size_t(p) * size_t(n) + size_t(j)) * size_t(n) + size_t(i);
        glm::vec3 v(atlas.radiance[t]);
        if (atlas.normal[t].w == 0.0f)
          v = worlds::skyRadiance(
              run.sky, shared::octTexelDirection(glm::uvec2(uint32_t(i), uint32_t(j)), uint32_t(n)));
        lums.push_back(0.2126f * v.x + 0.7152f * v.y + 0.0722f * v.z);
        for (int y = 0; y < scale; ++y)
          for (int x = 0; x < scale; ++x)
            for (int ch = 0; ch < 3; ++ch)
              sheet.at((k % cols) * tile + 1 + i * scale + x, (k / cols) * tile + 1 + j * scale + y, ch) =
                  v[ch];
      }
  }
  float exposureEv = 0.0f;
  if (!lums.empty()) {
    std::nth_element(lums.begin(), lums.begin() + std::ptrdiff_t(lums.size() / 2), lums.end());
    const float med = lums[lums.size() / 2];
    if (med > 0.0f && std::isfinite(med)) exposureEv = std::log2(0.18f / med);
  }
  run.exposureEv = exposureEv;
  writePng(out / "contact_sheet.png", sheet, exposureEv);
}

// vir.json: layout, probes, sky, statistics.
nlohmann::ordered_json virJson(const VirRun& run) {
  const VirCommandOptions& opt = run.opt;
  const gpu::ProbeAtlas& atlas = run.lighting.atlas;
  const gpu::RelightProbes& probes = run.probes;
  const worlds::SkyModel& sky = run.sky;
  const int pc = int(run.probeCount);
  nlohmann::ordered_json j;
  j["world"] = opt.world;
  j["cell"] = {run.c.x, run.c.z};
  j["time_of_day"] = opt.timeOfDay;
  j["overcast"] = opt.overcast;
  j["sun_direction"] = {sky.sun.direction.x, sky.sun.direction.y, sky.sun.direction.z};
  j["resolution"] = atlas.resolution;
  j["irradiance_resolution"] = run.lighting.probes.irradianceResolution;
  j["frames"] = run.frames;
  j["surfels"] = run.cell.surfels.size();
  j["probes"] = run.probeCount;
  j["probe_grid"] = {{"origin", {probes.grid.origin.x, probes.grid.origin.y, probes.grid.origin.z}},
                     {"spacing", {probes.grid.spacing.x, probes.grid.spacing.y, probes.grid.spacing.z}},
                     {"dims", {probes.grid.dims.x, probes.grid.dims.y, probes.grid.dims.z}}};
  j["tile_columns"] = int(std::ceil(std::sqrt(double(pc))));
  j["contact_sheet_probes"] = run.shown;
  nlohmann::json active = nlohmann::json::array();
  for (uint8_t a : probes.active) active.push_back(int(a));
  j["probe_active"] = active;
  j["hole_fraction_before_fill"] = atlas.holeFractionBeforeFill;
  j["hole_fraction_after_fill"] = atlas.holeFractionAfterFill;
  j["shadow_resolution"] = run.last.shadowResolution;
  j["shadow_texel_m"] = run.last.shadowTexelM;
  j["frame_ms"] = run.frameMs;
  j["contact_sheet_exposure_ev"] = run.exposureEv;
  return j;
}

}  // namespace

int runVir(const VirCommandOptions& opt) {
  const auto start = std::chrono::steady_clock::now();
  if (opt.world.empty()) fail("--world: give the world directory (made by `lfgi world generate`)");
  if (opt.outDir.empty()) fail("--out: give an output directory");
  const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.world));
  VirRun run(opt);
  run.c = parseCellArg(opt.cell, "--cell");
  const worlds::CellCoord c = run.c;
  if (!world.contains(c))
    fail("--cell {}: outside the world ({} x {} cells)", opt.cell, world.cellsX(), world.cellsZ());
  worlds::SkyState state;
  state.timeOfDayHours = opt.timeOfDay;
  state.overcast = opt.overcast;
  run.sky = worlds::makeSky(state);

  std::fprintf(stderr, "vir: building cell %d,%d of %s\n", c.x, c.z, opt.world.c_str());
  run.cell = worlds::buildCell(world, c);
  if (run.cell.surfels.empty()) fail("--cell {}: the cell has no surfels", opt.cell);
  run.probes = relightProbes(run.cell);
  run.probeCount = run.probes.grid.probeCount();
  const gpu::RelightProbes& probes = run.probes;
  std::fprintf(stderr, "vir: %zu surfels, %lld probes (%d x %d x %d, %.1f m), N=%d, %d frames\n",
               run.cell.surfels.size(), (long long)run.probeCount, probes.grid.dims.x, probes.grid.dims.y,
               probes.grid.dims.z, double(probes.grid.spacing.x), opt.resolution, opt.bounces + 1);

  auto ctx = gpu::createContext();
  gpu::RelightPass relight(*ctx);
  gpu::VirPass vir(*ctx);
  run.frames = opt.bounces + 1;
  InterruptGuard guard;
  if (!relightFrames(run, relight, vir, world.cellSizeM())) return 130;

  const gpu::ProbeAtlas& atlas = run.lighting.atlas;
  fs::create_directories(opt.outDir);
  const fs::path out(opt.outDir);
  writeAtlases(run, out);
  writeContactSheet(run, out);
  writeFileAtomic(out / "vir.json", virJson(run).dump(2) + "\n");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "vir: cell %d,%d: %zu surfels, %lld probes, N=%d, %d frames (first %.1f s, last %.1f s), holes %.4f -> "
      "%.4f; wrote %s (%.1f s)\n",
      c.x, c.z, run.cell.surfels.size(), (long long)run.probeCount, atlas.resolution, run.frames,
      run.frameMs.front()["wall"].get<double>() * 1e-3, run.frameMs.back()["wall"].get<double>() * 1e-3,
      atlas.holeFractionBeforeFill, atlas.holeFractionAfterFill, (out / "contact_sheet.png").string().c_str(),
      seconds);
  return 0;
}

}  // namespace lfgi::app
