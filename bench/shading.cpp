// Benchmark `shading`: image error of shading from light-field probes (bake/shading_view.h) against the
// path-traced reference, vs probe spacing and octahedral resolution, and the device time of the shading
// pass (error against cost). Scenes: the Cornell box (ceiling light only, midnight overcast sky) swept
// over probe grids and map resolutions; Sponza at noon at one coarse grid; the leak-test house of the
// default world (sealed / lit indirect ratio). Probe sources compared on the same view (error vs cost):
// the Cornell box at 2 x 2 x 2 and 4 x 4 x 4 from capture and from VIR (bake/probe_sources.h: GPU relight of
// surfels, 4 frames), and a synthetic-world cell (seed 3, 64 m world, 32 m cells, cell 1,0 and its
// neighbours' geometry) from capture, VIR and codec (the cell baked into a cell file first, then decoded).
//
// Columns: scene, grid (NX x NY x NZ), spacing_m (smallest axis), resolution (radiance/distance maps;
// irradiance maps are half of it, >= 4), probes, capture_s (seconds to produce the probes: capture, VIR
// frames, or decode; the bake of a codec cell is reported in the log and summary), shade_ms (probe shading
// pass, device timestamps, at the timing size), shade_ms_per_mpixel, gbuffer_ms, indirect_rel_rms,
// total_rel_rms, probe_source (capture | vir | codec), neighbour_state (world rows: absent = the cell's
// probes alone, full = the neighbour cells' probes too, fallback = the neighbours on their SH L1 streaming
// fallback, gpu/probe_shading_pass.h; "-" for scenes).
// --sources runs only the probe-source comparison (Cornell + world cell); --neighbours only the
// neighbours full vs fallback comparison: the same world-cell view, indirect rel RMS, shading ms per
// megapixel (and their ratio, same run), and the border jump: irradiance along a line crossing the
// x = 32 m border at mid probe height, 5 cm steps (largest step between neighbouring points / mean).
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>

#include "bake/embree_scene.h"
#include "bake/probe_sources.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "bake/world_bake.h"
#include "bench/bench_output.h"
#include "core/error.h"
#include "worlds/gltf_io.h"
#include "worlds/world_cells.h"

namespace {

using namespace lfgi;

struct Row {
  double indirect = 0.0, total = 0.0, shadeMsPerMpix = 0.0;
};

// Pixels shaded from probes or fallbacks, leaving out those where either image sees an emitter (direct >
// emitterLevel): at an emitter's edge the reference's jittered samples mix in its radiance, which the total
// would then compare against a pixel-centre G-buffer.
std::vector<uint8_t> surfaceMask(const Image& shaded, const Image& ref, float emitterLevel) {
  std::vector<uint8_t> m(size_t(shaded.width) * size_t(shaded.height), 0);
  const int w = shaded.channelIndex("weight"), f = shaded.channelIndex("fallback"),
            d = shaded.channelIndex("direct.G"), rd = ref.channelIndex("direct.G");
  for (int y = 0; y < shaded.height; ++y)
    for (int x = 0; x < shaded.width; ++x)
      m[size_t(y) * size_t(shaded.width) + size_t(x)] =
          (shaded.at(x, y, w) > 0.0f || shaded.at(x, y, f) > 0.0f) && shaded.at(x, y, d) < emitterLevel &&
          ref.at(x, y, rd) < emitterLevel;
  return m;
}

// The world-cell view (cell 1,0 of the 64 m world of 32 m cells, seed 3, seen from the south-west) and its
// path-traced reference settings.
bake::PinholeCamera worldCellCamera() {
  bake::PinholeCamera c;
  c.position = glm::vec3(20.0f, 25.0f, -5.0f);
  c.target = glm::vec3(40.0f, 0.0f, 20.0f);
  c.verticalFovDeg = 60.0f;
  return c;
}

// Capture / bake settings of that cell (map resolution, samples, bounces).
bake::WorldBakeSettings worldCellBakeSettings(bool quick) {
  bake::WorldBakeSettings bs;
  bs.resolution = quick ? 8 : 16;
  bs.spp = quick ? 8 : 16;
  bs.bounces = 4;
  return bs;
}

bake::RenderOptions worldCellReferenceOptions(bool quick, int bounces) {
  bake::RenderOptions ro;
  ro.width = quick ? 48 : 96;
  ro.height = ro.width * 9 / 16;
  ro.samplesPerPixel = quick ? 256 : 1024;
  ro.maxBounces = bounces;
  return ro;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"lfgi benchmark: shading from light-field probes vs path-traced reference"};
  std::string out = "out/bench/shading";
  bool quick = false;
  bool sourcesOnly = false;
  bool neighboursOnly = false;
  std::string scenesDir = worlds::defaultScenesDir().string();
  app.add_option("--out", out, "Output directory");
  app.add_option("--scenes-dir", scenesDir, "Folder of the scene presets")->capture_default_str();
  app.add_flag("--quick", quick, "Smaller images and sweeps");
  app.add_flag("--sources", sourcesOnly, "Only the probe-source comparison (capture / vir / codec)");
  app.add_flag("--neighbours", neighboursOnly,
               "Only the world-cell comparison of neighbours full vs on their SH L1 fallback");
  CLI11_PARSE(app, argc, argv);
  try {
    bench::BenchOutput o(out, quick);
    auto ctx = gpu::createContext();
    o.setDevice(ctx->info.name);
    o.setColumns({"scene", "grid", "spacing_m", "resolution", "probes", "capture_s", "shade_ms",
                  "shade_ms_per_mpixel", "gbuffer_ms", "indirect_rel_rms", "total_rel_rms", "probe_source",
                  "neighbour_state"});
    const int refSize = quick ? 32 : 64;
    const int refSpp = quick ? 2048 : 4096;  // the Cornell light is small: the reference needs many samples
    const int timeSize = quick ? 256 : 512;

    // One scene: reference once, then each (grid, resolution) configuration, from each probe source.
    auto sweep = [&](const std::string& name, const worlds::TriangleMesh& mesh, const worlds::SkyModel& sky,
                     const bake::PinholeCamera& cam, int refW, int refH, int spp,
                     const std::vector<std::pair<glm::ivec3, int>>& configs, int captureSpp,
                     float emitterLevel, const std::vector<std::string>& sources = {"capture"}) {
      const bake::EmbreeScene scene(mesh, name);
      bake::RenderOptions ro;
      ro.width = refW;
      ro.height = refH;
      ro.samplesPerPixel = spp;
      const auto t0 = std::chrono::steady_clock::now();
      const bake::RenderResult ref = bake::renderShadingReference(scene, sky, cam, ro);
      spdlog::info("{}: reference {}x{} at {} spp in {:.1f} s", name, refW, refH, spp,
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      bake::ShadingRenderer renderer(*ctx, mesh);
      std::vector<worlds::Surfel> surfels;
      const worlds::Aabb box = mesh.bounds();
      if (std::find(sources.begin(), sources.end(), "vir") != sources.end())
        surfels =
            worlds::sampleSurfels(bake::meshWithBackFaces(mesh), {glm::length(box.max - box.min) / 64.0f, 1});
      std::vector<Row> rows;
      for (const auto& [dims, res] : configs)
        for (const std::string& source : sources) {
          worlds::ScenePreset preset;
          preset.probeDims = dims;
          const ProbeGrid grid = worlds::presetProbeGrid(preset, mesh.bounds());
          bake::CaptureOptions co;
          co.resolution = res;
          co.irradianceResolution = std::max(4, res / 2);
          co.samplesPerTexel = captureSpp;
          const auto c0 = std::chrono::steady_clock::now();
          ProbeField f;
          if (source == "vir") {
            bake::VirProbeOptions vo;
            vo.resolution = res;
            vo.irradianceResolution = co.irradianceResolution;
            vo.maxRange = 2.0f * glm::length(box.max - box.min);
            f = bake::virProbeField(*ctx, surfels, grid, {}, {}, sky, vo);
          } else {
            f = bake::captureGridField(scene, sky, grid, {}, {}, co);
          }
          const double captureS =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
          const ProbeField* fields[] = {&f};
          renderer.setProbes(fields);
          const bake::ShadedView v = renderer.render(sky, cam, refW, refH);
          const std::vector<uint8_t> mask = surfaceMask(v.image, ref.image, emitterLevel);
          Row row;
          row.indirect = bake::layerRelativeRms(v.image, "indirect.", ref.image, "indirect.", &mask);
          row.total = bake::layerRelativeRms(v.image, "", ref.image, "", &mask);
          // Timing at a larger size (best of 3 runs, device timestamps).
          const int tw = timeSize, th = timeSize * refH / refW;
          double shadeMs = 1e30, gbufMs = 1e30;
          for (int k = 0; k < 3; ++k) {
            const bake::ShadedView t = renderer.render(sky, cam, tw, th);
            shadeMs = std::min(shadeMs, t.shadeMs);
            gbufMs = std::min(gbufMs, t.gbufferMs);
          }
          row.shadeMsPerMpix = shadeMs / (double(tw) * double(th) * 1e-6);
          const float spacing = std::min({grid.spacing.x, grid.spacing.y, grid.spacing.z});
          o.addRow({name, fmt::format("{}x{}x{}", dims.x, dims.y, dims.z), bench::num(spacing),
                    std::to_string(res), std::to_string(grid.probeCount()), bench::num(captureS),
                    bench::num(shadeMs), bench::num(row.shadeMsPerMpix), bench::num(gbufMs),
                    bench::num(row.indirect), bench::num(row.total), source, "-"});
          spdlog::info(
              "{} grid {}x{}x{} res {} {}: indirect rel RMS {:.4f}, total {:.4f}, probes in {:.2f} s, shade "
              "{:.2f} ms ({:.1f} ms/Mpixel)",
              name, dims.x, dims.y, dims.z, res, source, row.indirect, row.total, captureS, shadeMs,
              row.shadeMsPerMpix);
          rows.push_back(row);
        }
      return rows;
    };

    // The world cell with its neighbours full vs on their fallback (capture probes, noon).
    auto neighbours = [&] {
      const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
      const worlds::CellCoord cell{1, 0};
      bake::WorldBakeSettings bs = worldCellBakeSettings(quick);
      const bake::CellBakeInputs in = bake::prepareCellBake(world, cell, bs);
      const bake::EmbreeScene scene(in.sceneMesh, "world cell 1,0 + neighbours");
      const worlds::SkyModel noon = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
      bake::CaptureOptions co = bake::worldBakeCaptureOptions(world, bs);
      co.irradianceResolution = 8;
      // Every cell of the 2 x 2 world: all its probes outside solid captured; its fallback = the mean SH L1
      // of those (bake::fieldFallback, as the bake makes the cell file's, but without the sun).
      std::vector<worlds::CellCoord> coords{{0, 0}, {1, 0}, {0, 1}, {1, 1}};
      std::vector<ProbeField> fields;
      std::vector<ShL1> fallbacks;
      const auto c0 = std::chrono::steady_clock::now();
      for (const worlds::CellCoord cc : coords) {
        const worlds::BuiltCell b = worlds::buildCell(world, cc);
        std::vector<uint8_t> active(b.probes.flags.size());
        for (size_t i = 0; i < active.size(); ++i)
          active[i] = (b.probes.flags[i] & worlds::kProbeDisabledSolid) ? 0 : 1;
        fields.push_back(bake::captureGridField(scene, noon, b.probes.grid, b.probes.offsets, active, co));
        fallbacks.push_back(bake::fieldFallback(fields.back()));
      }
      const double captureS = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
      const bake::PinholeCamera wc = worldCellCamera();
      const bake::RenderOptions ro = worldCellReferenceOptions(quick, bs.bounces);
      const int w = ro.width, h = ro.height;
      const bake::RenderResult ref = bake::renderShadingReference(scene, noon, wc, ro);
      bake::ShadingRenderer renderer(*ctx, in.sceneMesh);
      const ProbeGrid& g = fields[1].grid;
      const float lineY = g.origin.y + 0.5f * float(g.dims.y - 1) * g.spacing.y, lineZ = 16.0f;
      gpu::GBufferHost line;
      for (int k = 0; k <= 320; ++k) {
        line.position.push_back(glm::vec4(24.0f + 0.05f * float(k), lineY, lineZ, 1.0f));
        line.normal.push_back(glm::vec4(0.0f, 1.0f, 0.0f, 1.0f));
        line.albedo.push_back(glm::vec4(glm::vec3(3.14159265f), 0.0f));  // diffuse = irradiance
        line.emission.push_back(glm::vec4(0.0f));
      }
      line.width = int(line.position.size());
      line.height = 1;
      double msFull = 0.0;
      std::vector<Image> images;
      for (const std::string state : {"full", "fallback"}) {
        std::vector<gpu::ShadingCellInput> cells;
        for (size_t k = 0; k < coords.size(); ++k) {
          gpu::ShadingCellInput c;
          c.fallback = fallbacks[k];
          if (k == 1 || state == "full") {
            c.field = &fields[k];
          } else {
            c.fallbackOnly = true;
            c.box = fields[k].grid;
          }
          cells.push_back(c);
        }
        renderer.setCells(cells);
        const bake::ShadedView v = renderer.render(noon, wc, w, h);
        images.push_back(v.image);
        const std::vector<uint8_t> mask = surfaceMask(v.image, ref.image, 1e30f);
        const double indirect = bake::layerRelativeRms(v.image, "indirect.", ref.image, "indirect.", &mask);
        const double total = bake::layerRelativeRms(v.image, "", ref.image, "", &mask);
        double shadeMs = 1e30, gbufMs = 1e30;
        const int tw = timeSize, th = timeSize * 9 / 16;
        for (int k = 0; k < 3; ++k) {
          const bake::ShadedView t = renderer.render(noon, wc, tw, th);
          shadeMs = std::min(shadeMs, t.shadeMs);
          gbufMs = std::min(gbufMs, t.gbufferMs);
        }
        const double msPerMpix = shadeMs / (double(tw) * double(th) * 1e-6);
        const gpu::ShadeOutputHost l = renderer.shadePoints(noon, line, wc.position, {});
        double jump = 0.0, mean = 0.0, borderStep = 0.0;
        for (size_t k = 0; k < l.diffuse.size(); ++k) {
          mean += double(l.diffuse[k].y) / double(l.diffuse.size());
          if (k > 0) jump = std::max(jump, double(std::abs(l.diffuse[k].y - l.diffuse[k - 1].y)));
          if (k > 0 && line.position[k - 1].x < 32.0f && line.position[k].x >= 32.0f)
            borderStep = std::abs(l.diffuse[k].y - l.diffuse[k - 1].y);
        }
        const float spacing = std::min({g.spacing.x, g.spacing.y, g.spacing.z});
        o.addRow({"world_cell", fmt::format("{}x{}x{}", g.dims.x, g.dims.y, g.dims.z), bench::num(spacing),
                  std::to_string(fields[1].resolution), std::to_string(g.probeCount()), bench::num(captureS),
                  bench::num(shadeMs), bench::num(msPerMpix), bench::num(gbufMs), bench::num(indirect),
                  bench::num(total), "capture", state});
        o.summary()["neighbours_" + state + "_indirect_rel_rms"] = indirect;
        o.summary()["neighbours_" + state + "_shade_ms_per_mpixel"] = msPerMpix;
        o.summary()["neighbours_" + state + "_line_max_step_rel"] = jump / std::max(mean, 1e-12);
        o.summary()["neighbours_" + state + "_line_border_step_rel"] = borderStep / std::max(mean, 1e-12);
        if (state == "full")
          msFull = msPerMpix;
        else
          o.summary()["neighbours_fallback_vs_full_shade_ms_ratio"] = msPerMpix / msFull;
        spdlog::info(
            "world cell 1,0, neighbours {}: indirect rel RMS {:.4f}, total {:.4f}, shade {:.1f} ms/Mpixel, "
            "line y = {:.1f} m: largest 5 cm step {:.4f} of the mean {:.3f}, at the border {:.4f}",
            state, indirect, total, msPerMpix, lineY, jump / mean, mean, borderStep / mean);
      }
      // The same comparison over the pixels the fallback run shades mostly from fallbacks (the neighbours).
      std::vector<uint8_t> onFallback = surfaceMask(images[1], ref.image, 1e30f);
      const int fc = images[1].channelIndex("fallback");
      size_t count = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          uint8_t& m = onFallback[size_t(y) * size_t(w) + size_t(x)];
          m = m && images[1].at(x, y, fc) > 0.5f;
          count += m;
        }
      if (count > 0) {
        const double full =
            bake::layerRelativeRms(images[0], "indirect.", ref.image, "indirect.", &onFallback);
        const double fb = bake::layerRelativeRms(images[1], "indirect.", ref.image, "indirect.", &onFallback);
        o.summary()["neighbours_pixels_on_fallback"] = double(count);
        o.summary()["neighbours_full_indirect_rel_rms_on_those_pixels"] = full;
        o.summary()["neighbours_fallback_indirect_rel_rms_on_those_pixels"] = fb;
        spdlog::info(
            "{} of {} pixels mostly on fallback: indirect rel RMS there {:.4f} (neighbours full) vs {:.4f} "
            "(on fallback)",
            count, w * h, full, fb);
      }
    };
    if (neighboursOnly) {
      neighbours();
      o.save();
      return 0;
    }

    // Cornell box.
    const worlds::ScenePreset& cornellPreset = worlds::findScenePreset("cornell");
    const worlds::TriangleMesh cornell = worlds::loadScenePreset(cornellPreset, scenesDir);
    const worlds::SkyModel night = worlds::makeSky(worlds::SkyState{0.0f, 45.0f, 172, 3.0f, 1.0f});
    bake::PinholeCamera cc;
    cc.position = glm::vec3(-0.278f, 0.274f, 1.0f);
    cc.target = glm::vec3(-0.278f, 0.274f, -0.28f);
    cc.verticalFovDeg = 40.0f;
    if (sourcesOnly) {
      const std::vector<Row> c =
          sweep("cornell", cornell, night, cc, refSize, refSize, refSpp,
                {{glm::ivec3(2), 16}, {glm::ivec3(4), 16}}, 64, 0.01f, {"capture", "vir"});
      o.summary()["cornell_indirect_rel_rms_capture_2x2x2"] = c[0].indirect;
      o.summary()["cornell_indirect_rel_rms_vir_2x2x2"] = c[1].indirect;
      o.summary()["cornell_indirect_rel_rms_capture_4x4x4"] = c[2].indirect;
      o.summary()["cornell_indirect_rel_rms_vir_4x4x4"] = c[3].indirect;
    }
    std::vector<std::pair<glm::ivec3, int>> configs;
    const std::vector<int> grids = quick ? std::vector<int>{2, 3, 4} : std::vector<int>{2, 3, 4, 6, 8};
    const std::vector<int> resolutions = quick ? std::vector<int>{8, 32} : std::vector<int>{8, 32, 64};
    for (int g : grids) configs.push_back({glm::ivec3(g), 16});
    for (int r : resolutions) configs.push_back({glm::ivec3(4), r});
    if (!sourcesOnly) {
      const std::vector<Row> c = sweep("cornell", cornell, night, cc, refSize, refSize, refSpp, configs, 64,
                                       0.01f, {"capture", "vir"});
      // Rows per configuration: capture, vir.
      o.summary()["cornell_indirect_rel_rms"] = c[0].indirect;  // the paper's 2 x 2 x 2 grid, 16 x 16 maps
      o.summary()["cornell_indirect_rel_rms_grid"] = "2x2x2, 16x16 maps";
      o.summary()["cornell_indirect_rel_rms_vir"] = c[1].indirect;
      o.summary()["shade_ms_per_mpixel"] = c[0].shadeMsPerMpix;
    }

    // A world cell from capture, VIR and codec probes.
    {
      const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
      const worlds::CellCoord cell{1, 0};
      bake::WorldBakeSettings bs = worldCellBakeSettings(quick);
      bs.keys = "12";
      bs.maxSteps = quick ? 300 : 1500;
      bake::CellBakeInputs in = bake::prepareCellBake(world, cell, bs);
      const worlds::BuiltCell built = in.built;
      worlds::TriangleMesh mesh = in.sceneMesh;
      const bake::EmbreeScene scene(mesh, "world cell 1,0 + neighbours");
      const auto b0 = std::chrono::steady_clock::now();
      const CellFile cf = bake::bakeCell(world, std::move(in), bs);
      const double bakeS = std::chrono::duration<double>(std::chrono::steady_clock::now() - b0).count();
      spdlog::info("world cell 1,0: baked ({}) in {:.1f} s, stored irradiance error {:.4f}", cf.stats.model,
                   bakeS, cf.stats.errorAchieved);
      o.summary()["world_cell_bake_s"] = bakeS;
      o.summary()["world_cell_model"] = cf.stats.model;
      const worlds::SkyModel noon = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
      const bake::PinholeCamera wc = worldCellCamera();
      const bake::RenderOptions ro = worldCellReferenceOptions(quick, bs.bounces);
      const int w = ro.width, h = ro.height;
      const bake::RenderResult ref = bake::renderShadingReference(scene, noon, wc, ro);
      bake::ShadingRenderer renderer(*ctx, mesh);
      const ProbeGrid& grid = built.probes.grid;
      std::vector<uint8_t> active(built.probes.flags.size());
      for (size_t i = 0; i < active.size(); ++i)
        active[i] = (built.probes.flags[i] & worlds::kProbeDisabledSolid) ? 0 : 1;
      for (const std::string source : {"capture", "vir", "codec"}) {
        const auto c0 = std::chrono::steady_clock::now();
        ProbeField f;
        if (source == "capture") {
          bake::CaptureOptions co = bake::worldBakeCaptureOptions(world, bs);
          co.irradianceResolution = 8;
          f = bake::captureGridField(scene, noon, grid, built.probes.offsets, active, co);
        } else if (source == "vir") {
          bake::VirProbeOptions vo;
          vo.resolution = bs.resolution;
          vo.maxRange = 32.0f;
          f = bake::virProbeField(*ctx, built.surfels, grid, built.probes.offsets, active, noon, vo);
        } else {
          f = bake::codecProbeField(cf, "cell 1,0", scene, noon, bs.resolution);
        }
        const double sourceS = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
        const ProbeField* fields[] = {&f};
        renderer.setProbes(fields);
        const bake::ShadedView v = renderer.render(noon, wc, w, h);
        const std::vector<uint8_t> mask = surfaceMask(v.image, ref.image, 1e30f);
        const double indirect = bake::layerRelativeRms(v.image, "indirect.", ref.image, "indirect.", &mask);
        const double total = bake::layerRelativeRms(v.image, "", ref.image, "", &mask);
        const float spacing = std::min({grid.spacing.x, grid.spacing.y, grid.spacing.z});
        o.addRow({"world_cell", fmt::format("{}x{}x{}", grid.dims.x, grid.dims.y, grid.dims.z),
                  bench::num(spacing), std::to_string(f.resolution), std::to_string(grid.probeCount()),
                  bench::num(sourceS), bench::num(v.shadeMs),
                  bench::num(v.shadeMs / (double(w) * double(h) * 1e-6)), bench::num(v.gbufferMs),
                  bench::num(indirect), bench::num(total), source, "absent"});
        o.summary()["world_cell_indirect_rel_rms_" + source] = indirect;
        spdlog::info("world cell 1,0 {}: indirect rel RMS {:.4f}, total {:.4f}, probes in {:.2f} s", source,
                     indirect, total, sourceS);
      }
    }
    if (sourcesOnly) {
      o.save();
      return 0;
    }
    neighbours();

    // Sponza at noon, one coarse grid (the paper's 18 x 7 x 11 is too slow to capture here with --quick).
    {
      const worlds::ScenePreset& sp = worlds::findScenePreset("sponza");
      const worlds::TriangleMesh sponza = worlds::loadScenePreset(sp, scenesDir);
      const worlds::SkyModel noon = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
      bake::PinholeCamera scam;
      scam.position = glm::vec3(-12.0f, 5.0f, -0.5f);
      scam.target = glm::vec3(12.0f, 7.0f, -0.5f);
      scam.verticalFovDeg = 60.0f;
      const glm::ivec3 dims = quick ? glm::ivec3(9, 4, 6) : glm::ivec3(18, 7, 11);
      const std::vector<Row> s = sweep("sponza", sponza, noon, scam, quick ? 64 : 128, quick ? 36 : 72,
                                       quick ? 64 : 256, {{dims, quick ? 8 : 16}}, quick ? 16 : 64, 1e30f);
      o.summary()["sponza_indirect_rel_rms"] = s[0].indirect;
      o.summary()["sponza_grid"] = fmt::format("{}x{}x{}", dims.x, dims.y, dims.z);
    }

    // Leak test house.
    {
      const worlds::SyntheticWorld world(worlds::WorldParams::smallDefault(1));
      const worlds::SkyModel noon = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
      bake::CaptureOptions co;
      co.samplesPerTexel = quick ? 16 : 64;
      co.maxBounces = 6;
      const bake::LeakTestResult l = bake::measureLeakTest(*ctx, world, {1, 1}, noon, co);
      o.summary()["leak_ratio"] = l.ratioOn();
      o.summary()["leak_ratio_without_chebyshev"] = l.ratioOff();
      spdlog::info("leak test: sealed / lit indirect {:.5f} with Chebyshev, {:.5f} without", l.ratioOn(),
                   l.ratioOff());
    }
    o.save();
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
