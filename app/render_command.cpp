// `lfgi render`: one view shaded from light-field probes (bake/shading_view.h: G-buffer ray cast +
// probe shading on the Vulkan device), written as a layered EXR + tone-mapped PNG; with --compare also
// the path-traced reference split the same way (bake::renderShadingReference), an error heat map, and
// the relative RMS of the total and of the indirect light.
//
// Probe sources: --probes capture (Embree capture at render time: scene presets over the preset's or
// --grid probe grid; world cells over the cells' own placed probes, for the cell --cell and its 8
// neighbours so borders shade from both sides: only the probes around surfaces the camera sees, or with
// --probe-radius R those within R m of the camera).
// --probes vir: the same probes (scene grid, or the world cells' probes chosen as above) from GPU relight +
// VIR of the surfels (bake/probe_sources.h virProbeField, --vir-frames frames; scenes: surfels sampled
// from the mesh at --surfel-spacing, world cells: the 3 x 3 cells' own surfels).
// --probes codec (world cells only): probes decoded from the baked cell files (bake/probe_sources.h
// codecProbeField): --cell-file for the centre cell (default WORLD/baked/cells/cell_X_Z.vdb, as `lfgi bake`
// writes), the neighbours' files from the same folder when present.
// --exposure EV fixes the PNG exposure (time-of-day sweeps); default: the median luminance maps to 0.18.
// --ao-radius R: ray-traced ambient occlusion from the G-buffer (bake/shading_view.h) on indirect diffuse.
// --neighbours-fallback (world cells): the 8 neighbours are not resident, as in streaming before they
// arrive: only their SH L1 fallback (bake::fieldFallback of a sparse capture / VIR of their probes, or of
// their decoded cell file; no sun: the pass adds it), so the border shows the fallback blend of
// gpu/probe_shading_pass.h. --cell-fade F (world cells): the centre cell's cross-fade weight (1 full, 0
// its fallback alone). Either one gives every cell its fallback.
//
// Output (--out X.exr): X.exr (R/G/B, direct, indirect_diffuse, indirect_specular, indirect, weight, ao),
// X.png; with --compare: X_reference.exr (R/G/B, direct, indirect), X_reference.png,
// X_indirect.png and X_reference_indirect.png (same exposure), X_error.png (indirect heat map).
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>

#include "app/cli_args.h"
#include "app/commands.h"
#include "bake/embree_scene.h"
#include "bake/probe_sources.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "core/cell_file.h"
#include "core/error.h"
#include "core/image.h"
#include "core/progress.h"
#include "core/shared_model.h"
#include "gpu/context.h"
#include "worlds/gltf_io.h"
#include "worlds/surfels.h"
#include "worlds/world_cells.h"

namespace lfgi::app {
namespace {

namespace fs = std::filesystem;

float medianLuminance(const Image& img, const std::string& layer) {
  const int r = img.channelIndex(layer + "R"), g = img.channelIndex(layer + "G"),
            b = img.channelIndex(layer + "B");
  std::vector<float> lum;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      lum.push_back(0.2126f * img.at(x, y, r) + 0.7152f * img.at(x, y, g) + 0.0722f * img.at(x, y, b));
  std::nth_element(lum.begin(), lum.begin() + long(lum.size() / 2), lum.end());
  return std::max(lum[lum.size() / 2], 1e-12f);
}

fs::path withSuffix(const fs::path& exr, const std::string& suffix, const std::string& ext) {
  fs::path p = exr;
  p.replace_filename(exr.stem().string() + suffix + ext);
  return p;
}

}  // namespace

int runRender(const RenderCommandOptions& opt) {
  if (opt.world.empty() == opt.scene.empty())
    fail("give exactly one of --world DIR (with --cell) or --scene NAME_OR_FILE");
  if ((opt.neighboursFallback || opt.cellFade != 1.0f) && opt.world.empty())
    fail(
        "--neighbours-fallback / --cell-fade: streaming fallbacks are per world cell (give --world DIR "
        "--cell X,Z)");
  if (!(opt.cellFade >= 0.0f && opt.cellFade <= 1.0f))
    fail("--cell-fade {}: expected a value in [0, 1]", opt.cellFade);
  if (opt.probes != "capture" && opt.probes != "vir" && opt.probes != "codec")
    fail("--probes '{}': expected capture, vir or codec", opt.probes);
  if (opt.probes == "codec" && opt.world.empty())
    fail("--probes codec: cell files exist for world cells only (give --world DIR --cell X,Z)");
  if (!opt.cellFile.empty() && opt.probes != "codec") fail("--cell-file is for --probes codec");
  if (fs::path(opt.out).extension() != ".exr") fail("--out {}: expected a .exr file name", opt.out);
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
  int width = 0, height = 0;
  {
    char x = 0, extra = 0;
    if (std::sscanf(opt.size.c_str(), "%d%c%d%c", &width, &x, &height, &extra) != 3 || x != 'x' ||
        width < 1 || height < 1 || width > 8192 || height > 8192)
      fail("--size '{}': expected WIDTHxHEIGHT, each in [1, 8192]", opt.size);
  }
  worlds::SkyState ss;
  ss.timeOfDayHours = opt.timeOfDay;
  ss.overcast = opt.overcast;
  const worlds::SkyModel sky = worlds::makeSky(ss);
  bake::CaptureOptions co;
  co.resolution = opt.resolution;
  co.samplesPerTexel = opt.spp;
  co.maxBounces = opt.bounces;
  co.seed = opt.seed;
  bake::validateCaptureOptions(co);
  std::optional<tbb::global_control> limit;
  if (opt.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(opt.threads));
  InterruptGuard guard;

  auto ctx = gpu::createContext();
  bake::VirProbeOptions vo;
  vo.resolution = opt.resolution;
  vo.frames = opt.virFrames;
  auto reportVir = [&](const bake::VirProbeStats& st, const std::string& where) {
    spdlog::info("{}: VIR probes: {} probes from {} surfels, {} frames, {:.2f} s ({:.1f} ms device)", where,
                 st.probes, st.surfels, vo.frames, st.seconds, st.gpuMs);
  };
  worlds::TriangleMesh mesh;
  std::vector<ProbeField> fields;
  std::vector<gpu::ShadingCellInput> cellInputs;  // world cells: every cell's state (full / fallback-only)
  std::string what;
  if (!opt.scene.empty()) {
    worlds::ScenePreset preset;
    const fs::path p(opt.scene);
    std::string ext = p.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".gltf" || ext == ".glb" || fs::is_regular_file(p)) {
      if (!fs::is_regular_file(p)) fail("--scene {}: no such file", opt.scene);
      preset.name = p.stem().string();
      preset.scale = opt.scale;
      preset.probeDims = glm::ivec3(4);
      worlds::GltfImportOptions io;
      io.scale = opt.scale;
      mesh = worlds::importGltf(p, io);
    } else {
      try {
        preset = worlds::findScenePreset(opt.scene);
      } catch (const Error& e) {
        fail("--scene {}: {}", opt.scene, e.what());
      }
      mesh = worlds::loadScenePreset(preset, opt.scenesDir);
    }
    if (!opt.grid.empty()) {
      const std::vector<float> d = parseNumbers("--grid", opt.grid, 3, "NX,NY,NZ");
      for (int k = 0; k < 3; ++k) {
        if (d[size_t(k)] < 1.0f || d[size_t(k)] > 64.0f || d[size_t(k)] != std::floor(d[size_t(k)]))
          fail("--grid '{}': each count must be a whole number in [1, 64]", opt.grid);
        preset.probeDims[k] = int(d[size_t(k)]);
      }
    }
    const ProbeGrid grid = worlds::presetProbeGrid(preset, mesh.bounds());
    if (opt.probes == "vir") {
      const worlds::Aabb box = mesh.bounds();
      const float spacing = opt.surfelSpacing > 0.0f
                                ? opt.surfelSpacing
                                : std::max(glm::length(box.max - box.min) / 64.0f, 1e-3f);
      const std::vector<worlds::Surfel> surfels =
          worlds::sampleSurfels(bake::meshWithBackFaces(mesh), {spacing, opt.seed});
      vo.maxRange = 2.0f * glm::length(box.max - box.min);
      spdlog::info("{}: {} triangles, VIR of {} surfels ({:.3f} m) into {}x{}x{} probes ({}x{} maps)",
                   preset.name, mesh.triangleCount(), surfels.size(), spacing, grid.dims.x, grid.dims.y,
                   grid.dims.z, vo.resolution, vo.resolution);
      bake::VirProbeStats st;
      fields.push_back(bake::virProbeField(*ctx, surfels, grid, {}, {}, sky, vo, &st));
      reportVir(st, preset.name);
    } else {
      const bake::EmbreeScene scene(mesh, preset.name);
      spdlog::info("{}: {} triangles, capturing {}x{}x{} probes ({}x{} maps, {} spp)", preset.name,
                   mesh.triangleCount(), grid.dims.x, grid.dims.y, grid.dims.z, co.resolution, co.resolution,
                   co.samplesPerTexel);
      fields.push_back(bake::captureGridField(scene, sky, grid, {}, {}, co, true));
    }
    what = preset.name;
  } else {
    if (opt.cell.empty()) fail("--world {}: give the cell with --cell X,Z", opt.world);
    const worlds::SyntheticWorld world(worlds::readWorldManifest(opt.world));
    const worlds::CellCoord c = parseCellArg(opt.cell, "--cell");
    if (!world.contains(c))
      fail("--cell {}: outside the world ({} x {} cells)", opt.cell, world.cellsX(), world.cellsZ());
    std::vector<worlds::CellCoord> cells;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx)
        if (world.contains({c.x + dx, c.z + dz})) cells.push_back({c.x + dx, c.z + dz});
    std::vector<worlds::BuiltCell> built;
    for (const worlds::CellCoord cc : cells) {
      built.push_back(worlds::buildCell(world, cc));
      mesh.append(built.back().mesh);
    }
    // Embree sees the 3 x 3 cells, so probes near the border capture what is next door.
    const bake::EmbreeScene scene(mesh, "world cells");
    // Which probes to capture: with --probe-radius those that close to the camera, else (default) the
    // lattice probes around every surface point the camera sees (pixel-centre rays), i.e. exactly the
    // probes the shading pass will read, including the neighbouring cells' first layers.
    std::vector<std::vector<uint8_t>> active(built.size());
    for (size_t k = 0; k < built.size(); ++k) active[k].assign(built[k].probes.flags.size(), 0);
    auto isCentre = [&](size_t k) { return built[k].layout.cell.x == c.x && built[k].layout.cell.z == c.z; };
    if (opt.probeRadius > 0.0f) {
      for (size_t k = 0; k < built.size(); ++k)
        for (size_t i = 0; i < active[k].size() && (isCentre(k) || !opt.neighboursFallback); ++i)
          active[k][i] =
              glm::length(built[k].probes.position(int64_t(i)) - camera.position) <= opt.probeRadius;
    } else {
      for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
          const glm::vec3 d =
              bake::cameraRayDirection(camera, width, height, float(x) + 0.5f, float(y) + 0.5f);
          const std::optional<bake::RayHit> hit = scene.intersect(camera.position, d);
          if (!hit) continue;
          const glm::vec3 p = camera.position + hit->t * d;
          for (size_t k = 0; k < built.size(); ++k) {
            if (opt.neighboursFallback && (built[k].layout.cell.x != c.x || built[k].layout.cell.z != c.z))
              continue;
            const ProbeGrid& g = built[k].probes.grid;
            const glm::vec3 local = (p - g.origin) / g.spacing;
            if (glm::any(glm::lessThan(local, glm::vec3(-1.0f))) ||
                glm::any(glm::greaterThan(local, glm::vec3(g.dims))))
              continue;
            const glm::ivec3 base = glm::ivec3(glm::floor(local));
            for (int c8 = 0; c8 < 8; ++c8) {
              const glm::ivec3 q = base + glm::ivec3(c8 & 1, (c8 >> 1) & 1, (c8 >> 2) & 1);
              const glm::ivec3 qc = glm::clamp(q, glm::ivec3(0), g.dims - 1);
              if (glm::any(glm::notEqual(q, qc)) && glm::all(glm::greaterThanEqual(local, glm::vec3(0.0f))) &&
                  glm::all(glm::lessThan(local, glm::vec3(g.dims))))
                active[k][size_t(g.linearIndex(qc))] = 1;  // clamped corner of the owning grid
              else if (glm::all(glm::equal(q, qc)))
                active[k][size_t(g.linearIndex(q))] = 1;
            }
          }
        }
    }
    std::vector<worlds::Surfel> surfels;
    if (opt.probes == "vir")
      for (const worlds::BuiltCell& b : built)
        surfels.insert(surfels.end(), b.surfels.begin(), b.surfels.end());
    vo.maxRange = float(world.cellSizeM());
    std::vector<size_t> fieldCell;  // built index of fields[j]
    const bool wantFallbacks = opt.neighboursFallback || opt.cellFade != 1.0f;
    std::vector<std::optional<ShL1>> fallbacks(built.size());
    if (opt.probes == "codec") {
      // Every cell whose file exists (the centre's must); all fields share one map size: the first network
      // model's, else --resolution (SH L1 cells take any size).
      std::vector<std::pair<size_t, CellFile>> files;
      std::vector<fs::path> paths;
      for (size_t k = 0; k < built.size(); ++k) {
        const worlds::CellCoord cc = built[k].layout.cell;
        const bool centre = cc.x == c.x && cc.z == c.z;
        const fs::path path = centre && !opt.cellFile.empty() ? fs::path(opt.cellFile)
                                                              : fs::path(opt.world) / "baked" / "cells" /
                                                                    fmt::format("cell_{}_{}.vdb", cc.x, cc.z);
        if (!fs::is_regular_file(path)) {
          if (centre)
            fail(
                "--probes codec: no cell file {} (bake it with `lfgi bake --world {} --cells {},{}` or give "
                "--cell-file)",
                path.string(), opt.world, cc.x, cc.z);
          spdlog::info("cell {},{}: no cell file {}, its probes are not used", cc.x, cc.z, path.string());
          continue;
        }
        CellFile cf = readCellFile(path);
        if (cf.cellX != cc.x || cf.cellZ != cc.z || cf.grid.dims != built[k].probes.grid.dims)
          fail("{}: holds cell {},{} ({}x{}x{} probes), expected cell {},{} ({}x{}x{})", path.string(),
               cf.cellX, cf.cellZ, cf.grid.dims.x, cf.grid.dims.y, cf.grid.dims.z, cc.x, cc.z,
               built[k].probes.grid.dims.x, built[k].probes.grid.dims.y, built[k].probes.grid.dims.z);
        files.emplace_back(k, std::move(cf));
        paths.push_back(path);
      }
      int res = opt.resolution;
      for (const auto& [k, cf] : files)
        if (cf.generator) {
          res = cf.generator->weights.arch.outputResolution();
          break;
        }
      std::optional<ResolvedSharedModel> shared;
      for (size_t j = 0; j < files.size(); ++j) {
        const CellFile& cf = files[j].second;
        if (cf.generator && cf.generator->weights.arch.outputResolution() != res)
          fail("{}: decodes {}x{} maps but another cell file decodes {}x{}", paths[j].string(),
               cf.generator->weights.arch.outputResolution(), cf.generator->weights.arch.outputResolution(),
               res, res);
        // A shared-model cell: the world's shared model beside its cells/ directory, read once.
        if (cf.generator && cf.generator->shared && !shared)
          shared = loadSharedModel(sharedModelPath(paths[j].parent_path().parent_path()));
        ProbeField decoded = bake::codecProbeField(cf, paths[j].string(), scene, sky, res, 8, 1.0e4f,
                                                   shared ? &*shared : nullptr);
        const size_t k = files[j].first;
        if (wantFallbacks) fallbacks[k] = bake::fieldFallback(decoded);
        spdlog::info("cell {},{}: decoded {} probes from {} ({}){}", cf.cellX, cf.cellZ,
                     cf.activeProbeCount(), paths[j].string(), cf.stats.model,
                     opt.neighboursFallback && !isCentre(k) ? ": its SH L1 fallback only" : "");
        if (opt.neighboursFallback && !isCentre(k)) continue;
        fields.push_back(std::move(decoded));
        fieldCell.push_back(k);
      }
    } else if (wantFallbacks) {
      // Each cell's fallback from a sparse set of its own probes (fallbackProbeMask), by the same source.
      for (size_t k = 0; k < built.size(); ++k) {
        const worlds::BuiltCell& b = built[k];
        std::vector<uint8_t> disabled(b.probes.flags.size());
        for (size_t i = 0; i < disabled.size(); ++i)
          disabled[i] = (b.probes.flags[i] & worlds::kProbeDisabledSolid) != 0;
        const std::vector<uint8_t> mask = bake::fallbackProbeMask(b.probes.grid, disabled);
        size_t n = 0;
        for (uint8_t m : mask) n += m;
        if (n == 0) {
          spdlog::info("cell {},{}: no probe outside solid for its fallback: it stays dark", b.layout.cell.x,
                       b.layout.cell.z);
          fallbacks[k] = ShL1{};
          continue;
        }
        spdlog::info("cell {},{}: SH L1 fallback from {} probes ({})", b.layout.cell.x, b.layout.cell.z, n,
                     opt.probes);
        const ProbeField f =
            opt.probes == "vir"
                ? bake::virProbeField(*ctx, surfels, b.probes.grid, b.probes.offsets, mask, sky, vo)
                : bake::captureGridField(scene, sky, b.probes.grid, b.probes.offsets, mask, co, false);
        fallbacks[k] = bake::fieldFallback(f);
      }
    }
    for (size_t k = 0; k < built.size() && opt.probes != "codec"; ++k) {
      if (opt.neighboursFallback && !isCentre(k)) continue;
      worlds::BuiltCell& b = built[k];
      size_t n = 0;
      for (size_t i = 0; i < active[k].size(); ++i) {
        if (b.probes.flags[i] & worlds::kProbeDisabledSolid) active[k][i] = 0;
        n += active[k][i];
      }
      if (n == 0) continue;
      if (opt.probes == "vir") {
        spdlog::info("cell {},{}: VIR of {} of {} probes", b.layout.cell.x, b.layout.cell.z, n,
                     active[k].size());
        bake::VirProbeStats st;
        fields.push_back(
            bake::virProbeField(*ctx, surfels, b.probes.grid, b.probes.offsets, active[k], sky, vo, &st));
        fieldCell.push_back(k);
        reportVir(st, fmt::format("cell {},{}", b.layout.cell.x, b.layout.cell.z));
        continue;
      }
      spdlog::info("cell {},{}: capturing {} of {} probes", b.layout.cell.x, b.layout.cell.z, n,
                   active[k].size());
      fields.push_back(
          bake::captureGridField(scene, sky, b.probes.grid, b.probes.offsets, active[k], co, true));
      fieldCell.push_back(k);
    }
    if (fields.empty() && !wantFallbacks)
      fail("--cell {}: no probe of the cell or its neighbours is near what the camera sees", opt.cell);
    // Every cell's streaming state: full (its field; the centre with --cell-fade) or, with
    // --neighbours-fallback, fallback-only; cells with neither are left out (the pass clamps there).
    for (size_t k = 0; k < built.size(); ++k) {
      const auto j = std::find(fieldCell.begin(), fieldCell.end(), k);
      gpu::ShadingCellInput in;
      if (fallbacks[k]) in.fallback = *fallbacks[k];
      if (j != fieldCell.end()) {
        in.field = &fields[size_t(j - fieldCell.begin())];
        in.fade = isCentre(k) ? opt.cellFade : 1.0f;
      } else if (fallbacks[k]) {
        in.fallbackOnly = true;
        in.box = built[k].probes.grid;
      } else {
        continue;
      }
      cellInputs.push_back(in);
    }
    what = fmt::format("world {} cells around {}", opt.world, opt.cell);
  }

  bake::ShadingRenderer renderer(*ctx, mesh);
  if (!cellInputs.empty()) {
    renderer.setCells(cellInputs, opt.specularLevels);
  } else {
    std::vector<const ProbeField*> ptrs;
    for (const ProbeField& f : fields) ptrs.push_back(&f);
    renderer.setProbes(ptrs, opt.specularLevels);
  }
  gpu::ShadingOptions so;
  so.chebyshev = !opt.noChebyshev;
  so.aoRadius = opt.aoRadius;
  const bake::ShadedView view = renderer.render(sky, camera, width, height, so);
  const fs::path exr(opt.out);
  if (!exr.parent_path().empty()) fs::create_directories(exr.parent_path());
  writeExr(exr, view.image);
  const float exposure =
      std::isnan(opt.exposure) ? std::log2(0.18f / medianLuminance(view.image, "")) : opt.exposure;
  writePng(withSuffix(exr, "", ".png"), view.image, exposure);
  spdlog::info("PNG exposure {:.3f} EV ({})", exposure, std::isnan(opt.exposure) ? "auto" : "--exposure");
  spdlog::info("render {}x{} of {} on {}: G-buffer {:.2f} ms, shading {:.2f} ms -> {}", width, height, what,
               ctx->info.name, view.gbufferMs, view.shadeMs, exr.string());
  if (!opt.compare) return 0;

  bake::RenderOptions ro;
  ro.width = width;
  ro.height = height;
  ro.samplesPerPixel = opt.referenceSpp;
  ro.maxBounces = opt.bounces;
  ro.seed = opt.seed;
  const bake::EmbreeScene scene(mesh, what);
  const bake::RenderResult ref = bake::renderShadingReference(scene, sky, camera, ro, true);
  if (ref.interrupted) {
    std::fprintf(stderr, "lfgi: interrupted; reference not written\n");
    return 130;
  }
  writeExr(withSuffix(exr, "_reference", ".exr"), ref.image);
  writePng(withSuffix(exr, "_reference", ".png"), ref.image, exposure);
  const float indirectExposure = std::log2(0.18f / medianLuminance(ref.image, "indirect."));
  writePng(withSuffix(exr, "_indirect", ".png"), view.image, indirectExposure, ToneMap::kAcesFitted,
           "indirect.");
  writePng(withSuffix(exr, "_reference_indirect", ".png"), ref.image, indirectExposure, ToneMap::kAcesFitted,
           "indirect.");
  writePng(withSuffix(exr, "_error", ".png"),
           bake::errorHeatMap(view.image, "indirect.", ref.image, "indirect."), 1.0f);
  // Error over pixels that probes shade (surfaces), so sky pixels (exact in both) do not dilute it.
  std::vector<uint8_t> mask(size_t(width) * size_t(height), 0);
  const int wc = view.image.channelIndex("weight"), fc = view.image.channelIndex("fallback");
  double fallbackShare = 0.0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      mask[size_t(y) * size_t(width) + size_t(x)] =
          view.image.at(x, y, wc) > 0.0f || view.image.at(x, y, fc) > 0.0f;
      fallbackShare += view.image.at(x, y, fc);
    }
  size_t shaded = 0;
  for (uint8_t m : mask) shaded += m;
  if (shaded == 0) {
    std::printf(
        "no pixel is shaded from probes (none captured near what the camera sees; move the camera over "
        "--cell)\n");
    return 0;
  }
  const double total = bake::layerRelativeRms(view.image, "", ref.image, "", &mask);
  const double indirect = bake::layerRelativeRms(view.image, "indirect.", ref.image, "indirect.", &mask);
  std::printf(
      "relative RMS vs path-traced reference (%d spp, %zu pixels shaded from %s probes): total %.4f, "
      "indirect %.4f\n",
      opt.referenceSpp, shaded, opt.probes.c_str(), total, indirect);
  if (!cellInputs.empty())
    std::printf(
        "fallback share of the indirect light: %.4f (mean over shaded pixels; neighbours %s, cell fade "
        "%.3f)\n",
        fallbackShare / double(shaded), opt.neighboursFallback ? "on their SH L1 fallback" : "full",
        double(opt.cellFade));
  spdlog::info("reference {:.2f} s -> {}, error map {}", ref.seconds,
               withSuffix(exr, "_reference", ".exr").string(), withSuffix(exr, "_error", ".png").string());
  return 0;
}

}  // namespace lfgi::app
