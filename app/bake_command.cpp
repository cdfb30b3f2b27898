// `lfgi capture` and `lfgi reference`: the ground truth (bake/) on a world's cells or a test scene.
//
// capture output, per cell (cell_X_Z) or scene (its preset name or file stem), in --out:
//   <name>_radiance.exr    atlas of the probes' n x n maps: probe k at tile (k % columns, k / columns),
//                          texel (i, j) at pixel (column * n + i, row * n + j); channels radiance.R/G/B,
//                          radiance_std_error.R/G/B, distance.mean, distance.sq, normal.X/Y/Z, albedo.R/G/B;
//                          columns = ceil(sqrt(probes)); unused tiles are 0
//   <name>_irradiance.exr  the same layout of the m x m irradiance maps, channels R/G/B
//   <name>.json            summary (probes, rays, rays/s, mean relative std error, seconds) and, per probe,
//                          its grid index, position and tile; written last, so its presence marks a
//                          finished cell and a rerun skips it. Every file is written atomically.
// World mode captures the ACTIVE probes of worlds::buildCell (kProbeDisabledSolid skipped) in the cell's
// mesh plus its 8 neighbours'; scene mode captures presetProbeGrid (or --probes) over the scene bounds.
// reference: the camera's cell and its 8 neighbours (world) or the scene; aborted runs write nothing.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>

#include "app/cli_args.h"
#include "app/commands.h"
#include "bake/probe_capture.h"
#include "bake/reference_render.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/image.h"
#include "core/progress.h"
#include "worlds/gltf_io.h"
#include "worlds/world_cells.h"

namespace lfgi::app {
namespace {

namespace fs = std::filesystem;

worlds::SkyModel skyFor(float timeOfDay, float overcast) {
  worlds::SkyState s;
  s.timeOfDayHours = timeOfDay;
  s.overcast = overcast;
  return worlds::makeSky(s);
}

struct SceneInput {
  worlds::TriangleMesh mesh;
  worlds::ScenePreset preset;  // name, scale, probe grid size
};

// --scene NAME_OR_FILE: a path ending in .gltf / .glb (or an existing file) is imported with --scale,
// anything else is a preset name looked up in --scenes-dir.
SceneInput loadScene(const std::string& scene, const std::string& scenesDir, float scale,
                     const std::string& probes) {
  SceneInput in;
  const fs::path p(scene);
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".gltf" || ext == ".glb" || fs::is_regular_file(p)) {
    if (!fs::is_regular_file(p)) fail("--scene {}: no such file", scene);
    in.preset.name = p.stem().string();
    in.preset.relativePath = p.string();
    in.preset.scale = scale;
    in.preset.probeDims = glm::ivec3(2);
    worlds::GltfImportOptions io;
    io.scale = scale;
    in.mesh = worlds::importGltf(p, io);
  } else {
    try {
      in.preset = worlds::findScenePreset(scene);
    } catch (const Error& e) {
      fail("--scene {}: {}", scene, e.what());
    }
    in.mesh = worlds::loadScenePreset(in.preset, scenesDir);
  }
  if (!probes.empty()) {
    const std::vector<float> d = parseNumbers("--probes", probes, 3, "NX,NY,NZ");
    for (int k = 0; k < 3; ++k) {
      if (d[size_t(k)] < 1.0f || d[size_t(k)] > 256.0f || d[size_t(k)] != std::floor(d[size_t(k)]))
        fail("--probes '{}': each count must be a whole number in [1, 256]", probes);
      in.preset.probeDims[k] = int(d[size_t(k)]);
    }
  }
  return in;
}

nlohmann::ordered_json vec3Json(glm::vec3 v) {
  return nlohmann::ordered_json::array({v.x, v.y, v.z});
}

nlohmann::ordered_json skyJson(const worlds::SkyModel& sky) {
  return {{"time_of_day_h", sky.state.timeOfDayHours},
          {"latitude_deg", sky.state.latitudeDeg},
          {"day_of_year", sky.state.dayOfYear},
          {"turbidity", sky.state.turbidity},
          {"overcast", sky.state.overcast},
          {"sun_elevation_deg", sky.sunPosition.elevationDeg}};
}

// Writes the two atlases and then the JSON (see the file comment).
void writeCapture(const fs::path& out, const std::string& name, const std::string& source,
                  const worlds::SkyModel& sky, const bake::CaptureOptions& co, const bake::CaptureResult& r,
                  const std::vector<int64_t>& gridIndex, size_t probesTotal, const ProbeGrid& grid) {
  const size_t P = r.probes.size();
  const int cols = P ? int(std::ceil(std::sqrt(double(P)))) : 0;
  const int rows = P ? int((P + size_t(cols) - 1) / size_t(cols)) : 0;
  const int n = co.resolution;
  const int m = co.irradianceResolution;
  const fs::path radPath = out / (name + "_radiance.exr");
  const fs::path irrPath = out / (name + "_irradiance.exr");
  if (P > 0) {
    Image atlas(cols * n, rows * n,
                {"radiance.R", "radiance.G", "radiance.B", "radiance_std_error.R", "radiance_std_error.G",
                 "radiance_std_error.B", "distance.mean", "distance.sq", "normal.X", "normal.Y", "normal.Z",
                 "albedo.R", "albedo.G", "albedo.B"});
    Image irr(cols * m, rows * m, {"R", "G", "B"});
    for (size_t k = 0; k < P; ++k) {
      const bake::ProbeCapture& c = r.probes[k];
      const int x0 = int(k % size_t(cols)), y0 = int(k / size_t(cols));
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          const size_t t = size_t(j) * size_t(n) + size_t(i);
          std::span<float> px = atlas.pixel(x0 * n + i, y0 * n + j);
          for (size_t ch = 0; ch < 3; ++ch) {
            px[ch] = c.radiance[t * 3 + ch];
            px[3 + ch] = c.radianceStdError[t * 3 + ch];
            px[8 + ch] = c.normal[t * 3 + ch];
            px[11 + ch] = c.albedo[t * 3 + ch];
          }
          px[6] = c.distance[t * 2];
          px[7] = c.distance[t * 2 + 1];
        }
      }
      for (int j = 0; j < m; ++j) {
        for (int i = 0; i < m; ++i) {
          const size_t t = size_t(j) * size_t(m) + size_t(i);
          std::span<float> px = irr.pixel(x0 * m + i, y0 * m + j);
          for (size_t ch = 0; ch < 3; ++ch) px[ch] = c.irradiance[t * 3 + ch];
        }
      }
    }
    writeExr(radPath, atlas);
    writeExr(irrPath, irr);
  }
  double rel = 0.0;
  nlohmann::ordered_json probes = nlohmann::ordered_json::array();
  for (size_t k = 0; k < P; ++k) {
    rel += r.probes[k].meanRelativeStdError;
    probes.push_back({{"grid_index", gridIndex[k]},
                      {"position", vec3Json(r.probes[k].position)},
                      {"tile", {int(k % size_t(cols)), int(k / size_t(cols))}}});
  }
  nlohmann::ordered_json j;
  j["format"] = "lfgi-capture";
  j["version"] = 1;
  j["source"] = source;
  j["sky"] = skyJson(sky);
  j["resolution"] = n;
  j["irradiance_resolution"] = m;
  j["samples_per_texel"] = co.samplesPerTexel;
  j["max_bounces"] = co.maxBounces;
  j["seed"] = co.seed;
  j["probes_total"] = probesTotal;
  j["probes_captured"] = P;
  j["rays"] = r.rays;
  j["rays_per_second"] = r.raysPerSecond();
  j["seconds"] = r.seconds;
  j["mean_relative_std_error"] = P ? rel / double(P) : 0.0;
  j["grid"] = {{"origin", vec3Json(grid.origin)},
               {"spacing", vec3Json(grid.spacing)},
               {"dims", {grid.dims.x, grid.dims.y, grid.dims.z}}};
  j["atlas"] = {{"columns", cols},
                {"rows", rows},
                {"radiance_exr", P ? radPath.filename().string() : ""},
                {"irradiance_exr", P ? irrPath.filename().string() : ""}};
  j["probes"] = std::move(probes);
  writeFileAtomic(out / (name + ".json"), j.dump(2) + "\n");
}

void requireOneSource(const std::string& world, const std::string& scene) {
  if (world.empty() == scene.empty()) fail("give exactly one of --world DIR or --scene NAME_OR_FILE");
}

// One unit of capture work: a name, its mesh (BVH built on demand) and its probes.
int captureOne(const fs::path& out, const std::string& name, const std::string& source,
               worlds::TriangleMesh mesh, const std::vector<glm::vec3>& positions,
               const std::vector<int64_t>& gridIndex, size_t probesTotal, const ProbeGrid& grid,
               const worlds::SkyModel& sky, const bake::CaptureOptions& co) {
  const size_t triangles = mesh.triangleCount();
  const bake::EmbreeScene scene(std::move(mesh), name);
  spdlog::info("{}: {} triangles, {} of {} probes active", name, triangles, positions.size(), probesTotal);
  const bake::CaptureResult r = bake::captureProbes(scene, sky, positions, co, /*showProgress=*/true);
  if (r.interrupted) return 130;
  writeCapture(out, name, source, sky, co, r, gridIndex, probesTotal, grid);
  spdlog::info("{}: {} probes, {:.3f} s, {:.2f} M rays/s -> {}", name, positions.size(), r.seconds,
               r.raysPerSecond() * 1e-6, (out / (name + ".json")).string());
  return 0;
}

}  // namespace

int runCapture(const CaptureCommandOptions& opt) {
  requireOneSource(opt.world, opt.scene);
  if (opt.world.empty() && !opt.cells.empty()) fail("--cells needs --world");
  if (!opt.world.empty() && opt.cells.empty())
    fail("--world {}: give the cells to capture with --cells X,Z ...", opt.world);
  bake::CaptureOptions co;
  co.resolution = opt.resolution;
  co.samplesPerTexel = opt.spp;
  co.maxBounces = opt.bounces;
  co.seed = opt.seed;
  bake::validateCaptureOptions(co);
  const worlds::SkyModel sky = skyFor(opt.timeOfDay, opt.overcast);
  const fs::path out(opt.outDir);
  const auto limit = threadLimit(opt.threads);
  InterruptGuard guard;
  auto interrupted = [] {
    std::fprintf(stderr, "lfgi: interrupted; rerun to resume\n");
    return 130;
  };

  if (!opt.scene.empty()) {
    SceneInput in = loadScene(opt.scene, opt.scenesDir, opt.scale, opt.probes);
    const std::string name = in.preset.name;
    if (fs::exists(out / (name + ".json"))) {
      spdlog::info("{}: already captured ({}); delete it to capture again", name,
                   (out / (name + ".json")).string());
      return 0;
    }
    const ProbeGrid grid = worlds::presetProbeGrid(in.preset, in.mesh.bounds());
    std::vector<glm::vec3> positions;
    std::vector<int64_t> index;
    for (int64_t i = 0; i < grid.probeCount(); ++i) {
      positions.push_back(grid.probePosition(grid.probeCoord(i)));
      index.push_back(i);
    }
    const int code = captureOne(out, name, "scene " + opt.scene, std::move(in.mesh), positions, index,
                                positions.size(), grid, sky, co);
    return code == 130 ? interrupted() : code;
  }

  const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.world));
  std::vector<worlds::CellCoord> cells;
  for (const std::string& c : opt.cells) {
    const worlds::CellCoord cc = parseCellArg(c, "--cells");
    if (!world.contains(cc))
      fail("--cells {}: outside the world ({} x {} cells)", c, world.cellsX(), world.cellsZ());
    cells.push_back(cc);
  }
  size_t skipped = 0;
  for (const worlds::CellCoord c : cells) {
    if (InterruptGuard::interrupted()) return interrupted();
    const std::string name = fmt::format("cell_{}_{}", c.x, c.z);
    if (fs::exists(out / (name + ".json"))) {
      ++skipped;
      continue;
    }
    // Probes exactly as the world's cell files place them; the capture sees the cell and its 8
    // neighbours, so border probes see what is next door.
    worlds::BuiltCell cell = worlds::buildCell(world, c);
    worlds::TriangleMesh mesh = std::move(cell.mesh);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx)
        if ((dx || dz) && world.contains({c.x + dx, c.z + dz}))
          mesh.append(world.generateCell({c.x + dx, c.z + dz}));
    std::vector<glm::vec3> positions;
    std::vector<int64_t> index;
    for (size_t i = 0; i < cell.probes.flags.size(); ++i) {
      if (cell.probes.flags[i] & worlds::kProbeDisabledSolid) continue;
      positions.push_back(cell.probes.position(int64_t(i)));
      index.push_back(int64_t(i));
    }
    const int code =
        captureOne(out, name, fmt::format("world {} cell {},{}", opt.world, c.x, c.z), std::move(mesh),
                   positions, index, cell.probes.flags.size(), cell.probes.grid, sky, co);
    if (code == 130) return interrupted();
  }
  if (skipped > 0) spdlog::info("resumed: {} of {} cells were already captured", skipped, cells.size());
  spdlog::info("done: {} cells in {}", cells.size(), out.string());
  return 0;
}

int runReference(const ReferenceCommandOptions& opt) {
  requireOneSource(opt.world, opt.scene);
  const std::vector<float> cam = parseNumbers("--camera", opt.camera, 6, "px,py,pz,tx,ty,tz");
  bake::PinholeCamera camera;
  camera.position = glm::vec3(cam[0], cam[1], cam[2]);
  camera.target = glm::vec3(cam[3], cam[4], cam[5]);
  camera.verticalFovDeg = opt.fov;
  try {
    bake::validateCamera(camera);
  } catch (const Error& e) {
    fail("--camera {} / --fov {}: {}", opt.camera, opt.fov, e.what());
  }
  bake::RenderOptions ro;
  {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(opt.size.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x' || w < 1 || h < 1 ||
        w > 16384 || h > 16384)
      fail("--size '{}': expected WIDTHxHEIGHT, each in [1, 16384]", opt.size);
    ro.width = w;
    ro.height = h;
  }
  ro.samplesPerPixel = opt.spp;
  ro.maxBounces = opt.bounces;
  ro.seed = opt.seed;
  bake::validateRenderOptions(ro);
  if (fs::path(opt.out).extension() != ".exr") fail("--out {}: expected a .exr file name", opt.out);
  const worlds::SkyModel sky = skyFor(opt.timeOfDay, opt.overcast);

  worlds::TriangleMesh mesh;
  std::string what;
  if (!opt.scene.empty()) {
    mesh = loadScene(opt.scene, opt.scenesDir, opt.scale, "").mesh;
    what = opt.scene;
  } else {
    const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.world));
    const double cellM = world.cellSizeM();
    const worlds::CellCoord c{int(std::floor(double(camera.position.x) / cellM)),
                              int(std::floor(double(camera.position.z) / cellM))};
    if (!world.contains(c))
      fail("--camera {}: position is outside the world (0..{} m in x and z)", opt.camera,
           world.params().sizeM);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx)
        if (world.contains({c.x + dx, c.z + dz})) mesh.append(world.generateCell({c.x + dx, c.z + dz}));
    what = fmt::format("world {} cells around {},{}", opt.world, c.x, c.z);
  }
  const worlds::Aabb b = mesh.bounds();
  spdlog::info("{}: {} triangles, bounds ({:.3g}, {:.3g}, {:.3g}) .. ({:.3g}, {:.3g}, {:.3g})", what,
               mesh.triangleCount(), b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z);
  const bake::EmbreeScene scene(std::move(mesh), what);
  const auto limit = threadLimit(opt.threads);
  InterruptGuard guard;
  const bake::RenderResult r = bake::renderReference(scene, sky, camera, ro, /*showProgress=*/true);
  if (r.interrupted) {
    std::fprintf(stderr, "lfgi: interrupted after %zu of %zu tiles; nothing written\n", r.tilesDone, r.tiles);
    return 130;
  }
  const fs::path exr(opt.out);
  fs::path png = exr;
  png.replace_extension(".png");
  writeExr(exr, r.image);
  const float median = medianLuminance(r.image);
  writePng(png, r.image, std::log2(0.18f / median));
  spdlog::info("reference {}x{}, {} spp: {:.3f} s, {:.2f} M rays/s, median luminance {:.4g} -> {}, {}",
               ro.width, ro.height, ro.samplesPerPixel, r.seconds, r.raysPerSecond() * 1e-6, median,
               exr.string(), png.string());
  return 0;
}

}  // namespace lfgi::app
