// Benchmark `vir`: View-Independent Rasterization (gpu/vir_pass.h, surfels splatted into all probes at
// once; two methods: `vir_lod` = VirPass's default, a per-probe-block cut of the surfel LOD tree
// gpu/vir_lod.h, and `vir` = every surfel into every probe, VirOptions::lod = false) against the
// cubemap-rasterization baseline (gpu/cubemap_raster.h, 6 rasterized faces per probe
// resampled to octahedral) on the same device, the same cell and the same output resolution, in one run.
//
// Scene: one cell of the default synthetic world (worlds/world_cells.h): VIR gets the cell's surfels,
// the baseline the cell's triangles (material albedo/emission; textures ignored, the synthetic world
// has none). Probes: the cell's active probes; longer lists cycle through them (the per-probe work is
// the same kind). Sweep: octahedral N in {8, 16, 32, 64} x probe counts {64 ... 4096}; a configuration
// whose time, projected from the previous count at the same N, exceeds the budget is skipped and listed
// in summary.json ("skipped"): that happens on lavapipe, where the baseline rasterizes on the CPU.
//
// A fourth row per configuration, `vir_lod_relight`: the vir_lod splat kept (VirOptions::reuseSplat) and
// only node radiance, resolve and fill rerun with new surfel irradiance, i.e. what relighting a resident
// cell costs per frame; it generates nothing new, so it is reported beside the ratio (relight_*), not as it.
//
// Headline (summary.json): vir_lod vs cubemap; the full splat's ratio is vir_full_over_cubemap_probes_per_s;
// ratio_by_resolution_and_probes lists every (N, probes) both measured. --lod-stats prints the LOD tree's
// levels and one probe's CPU-replayed cut; --methods runs a subset; --repeat K times each configuration K
// times and keeps the fastest run (device time), for A/B comparisons on a noisy shared machine.
//
// Like the baseline (which rasterizes albedo and emission), vir_lod and vir get no surfel irradiance, so
// their radiance is the emission and the LOD path runs no node-radiance pass (VirPass: the tree's
// area-weighted emission); vir_lod_relight passes irradiance and times the pass.
//
// Accuracy, per method and N, on the first K probes: per texel against Embree's closest hit along the
// texel-centre ray (bake/embree_scene.h, one ray per texel): distance median relative error, normal
// median angle (front-face hits), hole fraction (texels whose ray hits geometry but the method has no
// value). This reference is deterministic (no Monte-Carlo noise), and it is exactly what both methods
// point-sample; bake/probe_capture.h texel means would add the intra-texel depth spread (and its
// sampling noise) to both methods' error alike, so they are the secondary columns "*_vs_capture"
// (4 samples per texel, direct light only: the distance and normal medians barely move with the sample
// count, unlike the radiance).
//
// Atomics: vir_lod counts its atomicMin calls on the device (ProbeAtlas::splatAtomics). vir: the
// splat's 64-bit atomicMin count is replayed on the CPU (the same footprint test as
// vir_splat.comp) for the accuracy probes and scaled to the probe count; achieved atomics/s = count /
// VIR's whole device time (a lower bound for the splat's own rate), against the ceiling measured in this run
// by shaders/atomic_min64.comp with the parameters of bench/ceilings.cpp.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <tuple>

#include "bake/embree_scene.h"
#include "bake/path_trace.h"
#include "bake/probe_capture.h"
#include "bench/bench_output.h"
#include "core/error.h"
#include "core/progress.h"
#include "gpu/cubemap_raster.h"
#include "gpu/program.h"
#include "gpu/timing.h"
#include "gpu/vir_lod.h"
#include "gpu/vir_pass.h"
#include "shared/ceilings.h"
#include "shared/octahedral.h"
#include "worlds/sky.h"
#include "worlds/world_cells.h"

namespace lfgi::bench {
namespace {

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

gpu::CubemapScene toCubemapScene(const worlds::TriangleMesh& mesh) {
  gpu::CubemapScene scene;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const worlds::Material& m = mesh.materials[mesh.triangleMaterial[t]];
    scene.addTriangle(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), m.albedo, m.emission);
  }
  return scene;
}

// CPU replay of vir_splat.comp's loop: the number of atomicMin calls for one probe.
uint64_t splatAtomics(std::span<const shared::Surfel> surfels, glm::vec3 o, const gpu::VirOptions& opt) {
  uint64_t count = 0;
  const int n = opt.resolution;
  for (const shared::Surfel& s : surfels) {
    const glm::vec3 p(s.positionRadius), nrm(s.normal);
    const glm::vec3 toS = p - o;
    const float d = glm::length(toS);
    if (d > opt.maxRange || d < 1e-6f) continue;
    const float facing = -glm::dot(nrm, toS);
    if (facing <= 0.0f) continue;
    const float r = s.positionRadius.w * opt.footprintScale;
    const int k = std::min(opt.maxFootprintRadius, int(std::ceil(std::atan2(r, d) * float(n) * 0.5f)));
    const glm::ivec2 c(shared::octDirectionTexel(toS / d, uint32_t(n)));
    for (int dy = -k; dy <= k; ++dy)
      for (int dx = -k; dx <= k; ++dx) {
        const glm::ivec2 t = shared::octWrap(c + glm::ivec2(dx, dy), n);
        const glm::vec3 td = shared::octTexelDirection(glm::uvec2(t), uint32_t(n));
        const float denom = -glm::dot(nrm, td);
        if (denom <= 1e-6f) continue;
        const glm::vec3 h = o + (facing / denom) * td - p;
        if (glm::dot(h, h) <= r * r) ++count;
      }
  }
  return count;
}

// The device's 64-bit atomicMin rate: shaders/atomic_min64.comp with bench/ceilings.cpp's parameters.
double atomicCeilingPerSecond(gpu::Context& ctx) {
  gpu::Program p(ctx, "atomic_min64");
  const uint32_t slots = 1u << 20, threads = 1u << 16, updates = 16;
  gpu::Buffer buf = gpu::createStorageBuffer(ctx, size_t(slots) * 8);
  gpu::fillBuffer(ctx, buf, 0xffffffffu);
  shared::AtomicParams params{slots, updates, threads, 7};
  gpu::GpuTimer timer(ctx, 2);
  double best = 1e30;
  for (int r = 0; r < 3; ++r) {
    gpu::submitAndWait(ctx, [&](VkCommandBuffer cmd) {
      timer.reset(cmd);
      timer.stamp(cmd, 0);
      gpu::dispatch(ctx, cmd, p, {&buf}, params, {threads, 1, 1});
      timer.stamp(cmd, 1);
    });
    best = std::min(best, timer.elapsedMs(0, 1));
  }
  return double(threads) * updates / (best * 1e-3);
}

struct Accuracy {
  double distMedianRel = 0.0, distP90Rel = 0.0, fracOff5pct = 0.0, normalMedianDeg = 0.0, normalP90Deg = 0.0;
  double holeFractionOfHits = 0.0;
  // Texels whose ray sees the sky (no Embree hit) but the method stores geometry: a disc overhanging a
  // silhouette or the cell's edge (covered: the accuracy probes are the first in grid order, on the cell's
  // border, and look out past its last surfels) or the hole fill growing a silhouette (filled).
  double skyCoveredFraction = 0.0, skyFilledFraction = 0.0;
  double captureDistMedianRel = 0.0, captureNormalMedianDeg = 0.0;  // vs bake/probe_capture.h texel means
  // Albedo of the stored texel vs the hit triangle's (bake::detail::hitAlbedo): the mean of the largest
  // channel's absolute difference, and the texels off by > 0.05 in any channel. Merged LOD nodes store
  // the area mean of their surfels, so a coarse cut blurs albedo (and emission) where its depths are exact.
  double albedoMeanAbs = 0.0, albedoFracOff = 0.0;
  size_t compared = 0;
};

// Per texel of the first `probes` maps vs the Embree closest hit along the texel-centre ray.
Accuracy accuracy(const gpu::ProbeAtlas& atlas,
                  const std::vector<std::vector<std::optional<bake::RayHit>>>& ref, size_t probes,
                  const worlds::TriangleMesh& mesh) {
  const size_t n2 = size_t(atlas.resolution) * size_t(atlas.resolution);
  std::vector<double> rel, angle;
  double albedoSum = 0.0;
  size_t albedoOff = 0;
  size_t hits = 0, holes = 0, sky = 0, skyCovered = 0, skyFilled = 0;
  for (size_t p = 0; p < probes; ++p)
    for (size_t t = 0; t < n2; ++t) {
      const auto& hit = ref[p][t];
      const size_t i = p * n2 + t;
      if (!hit) {
        ++sky;
        skyCovered += atlas.normal[i].w == LFGI_VIR_COVERED ? 1 : 0;
        skyFilled += atlas.normal[i].w > LFGI_VIR_COVERED ? 1 : 0;
        continue;
      }
      ++hits;
      if (atlas.normal[i].w == 0.0f) {
        ++holes;
        continue;
      }
      rel.push_back(std::abs(double(atlas.distance[i].x) - hit->t) / double(hit->t));
      const worlds::Material& material = mesh.materials[mesh.triangleMaterial[hit->triangle]];
      const glm::vec3 da =
          glm::abs(glm::vec3(atlas.albedo[i]) - bake::detail::hitAlbedo(mesh, material, *hit));
      const float worst = std::max({da.x, da.y, da.z});
      albedoSum += double(worst);
      albedoOff += worst > 0.05f ? 1 : 0;
      if (!hit->backface) {
        const float c = std::clamp(glm::dot(glm::vec3(atlas.normal[i]), hit->normal), -1.0f, 1.0f);
        angle.push_back(double(std::acos(c)) * 180.0 / std::numbers::pi);
      }
    }
  Accuracy a;
  a.distMedianRel = quantile(rel, 0.5);
  a.distP90Rel = quantile(rel, 0.9);
  a.normalMedianDeg = quantile(angle, 0.5);
  a.normalP90Deg = quantile(angle, 0.9);
  a.fracOff5pct = rel.empty()
                      ? 0.0
                      : double(std::count_if(rel.begin(), rel.end(), [](double e) { return e > 0.05; })) /
                            double(rel.size());
  a.holeFractionOfHits = hits ? double(holes) / double(hits) : 0.0;
  a.skyCoveredFraction = sky ? double(skyCovered) / double(sky) : 0.0;
  a.skyFilledFraction = sky ? double(skyFilled) / double(sky) : 0.0;
  a.compared = rel.size();
  a.albedoMeanAbs = rel.empty() ? 0.0 : albedoSum / double(rel.size());
  a.albedoFracOff = rel.empty() ? 0.0 : double(albedoOff) / double(rel.size());
  return a;
}

// Against probe_capture texel means (distance: mean r of the texel's samples; normal: mean normal) of
// the first probes; texels where any sample missed (mean r near maxDistance) are left out.
void accuracyVsCapture(const gpu::ProbeAtlas& atlas, const bake::CaptureResult& cap, float maxDistance,
                       Accuracy& a) {
  const size_t n2 = size_t(atlas.resolution) * size_t(atlas.resolution);
  std::vector<double> rel, angle;
  for (size_t p = 0; p < cap.probes.size(); ++p)
    for (size_t t = 0; t < n2; ++t) {
      const size_t i = p * n2 + t;
      const float r = cap.probes[p].distance[2 * t];
      if (atlas.normal[i].w == 0.0f || !(r > 0.0f && r < 0.01f * maxDistance)) continue;
      rel.push_back(std::abs(double(atlas.distance[i].x) - r) / double(r));
      const glm::vec3 cn(cap.probes[p].normal[3 * t], cap.probes[p].normal[3 * t + 1],
                         cap.probes[p].normal[3 * t + 2]);
      if (glm::length(cn) > 0.5f) {
        const float c = std::clamp(glm::dot(glm::vec3(atlas.normal[i]), glm::normalize(cn)), -1.0f, 1.0f);
        angle.push_back(double(std::acos(c)) * 180.0 / std::numbers::pi);
      }
    }
  a.captureDistMedianRel = quantile(rel, 0.5);
  a.captureNormalMedianDeg = quantile(angle, 0.5);
}

// Command-line options; budgetS and accuracyProbes at 0 get the mode's defaults (setDefaults).
struct Options {
  std::string out = "out/bench/vir";
  std::string cellArg = "2,1";
  bool quick = false;
  double budgetS = 0.0;
  size_t accuracyProbes = 0;
  float lodTexels = gpu::VirOptions{}.lodTexels;
  float lodElongation = gpu::VirOptions{}.lodElongation;
  int lodBlockProbes = gpu::VirOptions{}.lodBlockProbes;
  float lodOcclusionRange = gpu::VirOptions{}.lodOcclusionRange;
  float fillNearMiss = gpu::VirOptions{}.fillNearMiss;
  std::string methodsArg = "all";
  bool lodStats = false;
  float statCone = gpu::VirLodBuildOptions{}.coherentConeDeg;
  bool keepBuried = false;
  int repeat = 1;
};

void addOptions(CLI::App& app, Options& opt) {
  app.add_option("--out", opt.out, "Output directory");
  app.add_flag("--quick", opt.quick,
               "Probe counts up to 1024 and a 12 s budget per configuration (lavapipe: minutes)");
  app.add_option("--cell", opt.cellArg, "Cell X,Z of the default world (2,1: the arcade block)");
  app.add_option("--budget-s", opt.budgetS,
                 "Skip a configuration projected to take longer (default 12 quick, 90 full)");
  app.add_option("--accuracy-probes", opt.accuracyProbes,
                 "Probes compared with Embree (default 8 quick, 16 full)");
  app.add_option("--lod-elongation", opt.lodElongation,
                 "vir_lod: VirOptions::lodElongation (1: width test only)");
  app.add_option("--lod-texels", opt.lodTexels, "vir_lod: VirOptions::lodTexels");
  app.add_option("--lod-block-probes", opt.lodBlockProbes, "vir_lod: VirOptions::lodBlockProbes");
  app.add_option("--lod-occlusion-range", opt.lodOcclusionRange,
                 "vir_lod: VirOptions::lodOcclusionRange (m; 0: off)");
  app.add_option("--fill-near-miss", opt.fillNearMiss,
                 "VirOptions::fillNearMiss for every VIR method (disc radii; 0: fill every enclosed hole)");
  app.add_option("--lod-stats-cone", opt.statCone, "--lod-stats: VirLodBuildOptions::coherentConeDeg");
  app.add_flag("--keep-buried", opt.keepBuried,
               "Keep the cell's buried triangles and surfels (worlds::CellBuildOptions::dropBuried = false)");
  app.add_flag("--lod-stats", opt.lodStats,
               "Print the surfel LOD tree's statistics and one probe's cut, then exit");
  app.add_option("--methods", opt.methodsArg,
                 "Comma-separated subset of vir_lod,vir_lod_relight,vir,cubemap (default all; the "
                 "summary's ratios need vir_lod and cubemap)");
  app.add_option("--repeat", opt.repeat,
                 "Run each configuration this many times and keep the fastest (device time; shared machines "
                 "are noisy)")
      ->check(CLI::Range(1, 20));
}

// Fills the mode's defaults and parses --cell into cx, cz.
void setDefaults(Options& opt, int& cx, int& cz) {
  if (opt.budgetS <= 0.0) opt.budgetS = opt.quick ? 12.0 : 90.0;
  if (opt.accuracyProbes == 0) opt.accuracyProbes = opt.quick ? 8 : 16;
  if (std::sscanf(opt.cellArg.c_str(), "%d,%d", &cx, &cz) != 2)
    fail("--cell '{}': expected X,Z", opt.cellArg);
}

// The benchmark's cell (surfels for VIR, triangles for the baseline), its probe list and the sweep's axes.
struct Cell {
  int cx = 0, cz = 0;
  worlds::BuiltCell built;
  gpu::CubemapScene scene;
  std::vector<glm::vec3> active;
  std::vector<int> resolutions;
  std::vector<size_t> counts;
  std::vector<glm::vec3> probes;
};

// Builds cell (cx, cz) of the default world; clamps opt.accuracyProbes to its probes.
Cell loadCell(Options& opt, int cx, int cz, const gpu::Context& ctx) {
  const worlds::SyntheticWorld world(worlds::WorldParams::smallDefault(1));
  if (!world.contains({cx, cz})) fail("--cell {},{} outside the default world", cx, cz);
  worlds::CellBuildOptions buildOptions;
  buildOptions.dropBuried = !opt.keepBuried;
  Cell cell{.cx = cx, .cz = cz, .built = worlds::buildCell(world, {cx, cz}, buildOptions)};
  const worlds::BuiltCell& built = cell.built;
  cell.scene = toCubemapScene(built.mesh);
  std::vector<glm::vec3>& active = cell.active;
  for (int64_t i = 0; i < built.probes.grid.probeCount(); ++i)
    if (!(built.probes.flags[size_t(i)] & worlds::kProbeDisabledSolid))
      active.push_back(built.probes.position(i));
  if (active.empty()) fail("cell {},{} has no active probes", cx, cz);
  cell.resolutions = {8, 16, 32, 64};
  cell.counts = opt.quick ? std::vector<size_t>{64, 256, 1024} : std::vector<size_t>{64, 256, 1024, 4096};
  std::vector<glm::vec3>& probes = cell.probes;
  probes.resize(cell.counts.back());
  for (size_t i = 0; i < probes.size(); ++i) probes[i] = active[i % active.size()];
  opt.accuracyProbes = std::min({opt.accuracyProbes, active.size(), cell.counts.front()});
  spdlog::info(
      "vir bench on {} ({}): cell {},{}: {} surfels, {} triangles, {} active probes; budget {} s/config",
      ctx.info.name, opt.quick ? "quick" : "full", cx, cz, built.surfels.size(), cell.scene.triangleCount(),
      active.size(), opt.budgetS);
  return cell;
}

// --lod-stats: the tree's diagnostics, per depth-from-leaves level how many nodes may be splatted, and
// one probe's cut at N = 8 and 16 (CPU replay of vir_lod_cut.comp, block = the probe).
void printLodStats(const Options& opt, const Cell& cell) {
  gpu::VirLodBuildOptions bo;
  bo.coherentConeDeg = opt.statCone;
  const gpu::VirLodTree tree = gpu::buildVirLodTree(cell.built.surfels, bo);
  std::vector<int> height(tree.nodes.size(), 0);
  std::map<int, std::array<double, 3>> byHeight;  // nodes, coherent, sum footprint radius
  for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
    for (uint32_t c = 0; c < tree.links[i].childCount; ++c)
      height[i] = std::max(height[i], height[tree.children[tree.links[i].firstChild + c]] + 1);
    auto& h = byHeight[height[i]];
    h[0] += 1;
    h[1] += (tree.links[i].flags & LFGI_VIR_LOD_COHERENT) ? 1 : 0;
    h[2] += tree.nodes[i].positionRadius.w * 1.5;
  }
  for (const auto& [hgt, h] : byHeight)
    spdlog::info("height {}: {} nodes, {:.1f} % coherent, mean footprint radius {:.2f} m", hgt, h[0],
                 100.0 * h[1] / h[0], h[2] / h[0]);
  const glm::vec3 eye = cell.active[cell.active.size() / 2];
  for (int n : {8, 16}) {
    gpu::VirOptions so;
    so.resolution = n;
    so.maxRange = 1000.0f;
    so.lodTexels = opt.lodTexels;
    so.lodElongation = opt.lodElongation;
    const shared::VirLodParams lp = gpu::virLodClassifyParams(so);
    size_t leaves = 0, inner = 0, leavesUnderIncoherent = 0;
    // Why each cut node's parent was refined (incoherent, too thick, else too wide: the footprint
    // test), and the node's width in texels (the classify's r N / d): sub-texel nodes rarely cover a
    // texel centre.
    std::array<size_t, 3> parentWhy{};
    std::array<size_t, 4> width{};  // < 0.5, < 1, < 2, >= 2 texels
    for (const uint32_t i : gpu::virLodCut(tree, gpu::virLodBlock(std::span(&eye, 1)), lp)) {
      const shared::Surfel& node = tree.nodes[i];
      const float d = glm::length(glm::vec3(node.positionRadius) - eye);
      const float w = node.positionRadius.w * lp.footprintScale * float(n) / std::max(d, 1e-6f);
      ++width[w < 0.5f ? 0 : w < 1.0f ? 1 : w < 2.0f ? 2 : 3];
      if (const uint32_t par = tree.up[i].x; par != ~0u) {
        const shared::Surfel& pn = tree.nodes[par];
        const float pd = glm::length(glm::vec3(pn.positionRadius) - eye);
        ++parentWhy[!(tree.links[par].flags & LFGI_VIR_LOD_COHERENT) ? 0
                    : pn.emission.w > lp.depthTolerance * pd         ? 2
                                                                     : 1];
      }
      if (i >= tree.leafCount) {
        ++inner;
        continue;
      }
      ++leaves;
      leavesUnderIncoherent +=
          (tree.up[i].x != ~0u && !(tree.links[tree.up[i].x].flags & LFGI_VIR_LOD_COHERENT));
    }
    spdlog::info("N={} cut for one probe: {} leaves ({} with an incoherent parent), {} merged nodes", n,
                 leaves, leavesUnderIncoherent, inner);
    spdlog::info(
        "N={} cut nodes by width: {} < 0.5 texel, {} < 1, {} < 2, {} >= 2; parent refined as incoherent "
        "{}, too wide {}, too thick {}",
        n, width[0], width[1], width[2], width[3], parentWhy[0], parentWhy[1], parentWhy[2]);
  }
}

worlds::SkyModel benchSky() {
  worlds::SkyState skyState;
  skyState.timeOfDayHours = 15.5f;
  return worlds::makeSky(skyState);
}

// What every configuration shares: the Embree scene and sky of the accuracy references, the two passes
// with their options, and the LOD tree's build figures from the warm-up.
struct Passes {
  Passes(gpu::Context& ctx, const worlds::TriangleMesh& mesh)
      : embree(mesh, "vir benchmark cell"), sky(benchSky()), vir(ctx), cubemap(ctx) {}
  bake::EmbreeScene embree;
  const worlds::SkyModel sky;
  gpu::VirPass vir;
  gpu::CubemapRaster cubemap;
  gpu::VirOptions vo, vlod;
  gpu::CubemapRasterOptions co;
  std::vector<glm::vec4> relightIrradiance;
  double lodBuildMs = 0.0;
  uint64_t lodNodes = 0;
};

// Sets the methods' options and runs each pass once.
void warmUp(Passes& p, const Options& opt, const Cell& cell) {
  const worlds::BuiltCell& built = cell.built;
  const std::vector<glm::vec3>& probes = cell.probes;
  gpu::VirOptions& vo = p.vo;
  gpu::VirOptions& vlod = p.vlod;
  vo.maxRange = 1000.0f;  // the whole cell, as the baseline renders it
  vo.fillNearMiss = opt.fillNearMiss;
  vlod = vo;
  vlod.lod = true;
  vlod.lodTexels = opt.lodTexels;
  vlod.lodElongation = opt.lodElongation;
  vlod.lodBlockProbes = opt.lodBlockProbes;
  vlod.lodOcclusionRange = opt.lodOcclusionRange;
  vlod.reuseSplat = false;  // vir_lod measures the splat; vir_lod_relight reuses it
  vo.lod = false;
  vo.reuseSplat = false;
  // vir_lod_relight: the same LOD splat's winners kept (VirOptions::reuseSplat), new surfel irradiance:
  // what relighting a resident cell (time of day, weather, bounces) costs per frame.
  std::vector<glm::vec4>& relightIrradiance = p.relightIrradiance;
  relightIrradiance.resize(built.surfels.size());
  for (size_t i = 0; i < relightIrradiance.size(); ++i)
    relightIrradiance[i] = glm::vec4(1.0f + float(i % 7), 2.0f, 1.0f + float(i % 3), 0.0f);
  {  // warm-up: lavapipe compiles each pipeline at its first use
    vo.resolution = p.co.resolution = 8;
    p.vir.run(built.surfels, std::span(probes).first(1), vo);
    vlod.resolution = 8;
    const gpu::ProbeAtlas first = p.vir.run(built.surfels, std::span(probes).first(1), vlod);
    p.lodBuildMs = first.lodBuildMs;
    p.lodNodes = first.lodNodes;
    spdlog::info("surfel LOD tree: {} nodes for {} surfels, built + uploaded in {:.0f} ms (once per cell)",
                 p.lodNodes, built.surfels.size(), p.lodBuildMs);
    p.cubemap.run(cell.scene, std::span(probes).first(1), p.co);
  }
}

void setColumns(BenchOutput& o) {
  o.setColumns({"method",
                "resolution",
                "probes",
                "surfels",
                "triangles",
                "gpu_ms",
                "ms_per_probe",
                "probes_per_s",
                "surfel_probes_per_s",
                "splat_or_raster_ms",
                "resolve_or_resample_ms",
                "wall_ms",
                "atomics_per_s",
                "dist_median_rel_error",
                "dist_p90_rel_error",
                "dist_frac_off_5pct",
                "normal_median_deg",
                "normal_p90_deg",
                "hole_fraction",
                "dist_median_rel_error_vs_capture",
                "normal_median_deg_vs_capture",
                "splat_pairs_per_s",
                "lod_nodes",
                "lod_build_ms",
                "splat_pairs_per_probe",
                "texel_tests_per_probe",
                "atomics_per_probe",
                "window_pair_fraction",
                "sky_covered_fraction",
                "sky_filled_fraction",
                "albedo_mean_abs_error",
                "albedo_frac_off_0_05"});
}

struct Measured {
  double probesPerS = 0.0, msPerProbe = 0.0;
  size_t probes = 0;
  Accuracy acc;
  double atomicsPerS = 0.0, splatPairsPerS = 0.0;
};

// The sweep's results the summary reads, and the device figures it reports beside them.
struct Results {
  nlohmann::ordered_json skipped = nlohmann::ordered_json::array();
  std::map<std::pair<std::string, int>, Measured> best;  // (method, N) -> largest probe count measured
  std::map<std::tuple<std::string, int, size_t>, double> perCount;  // (method, N, probes) -> probes/s
  double ceiling = 0.0;
  bool cpuDevice = false;
};

std::vector<std::string> selectMethods(const std::string& methodsArg) {
  std::vector<std::string> methods;
  for (const std::string m : {"vir_lod", "vir_lod_relight", "vir", "cubemap"})
    if (methodsArg.find(m + ",") != std::string::npos || methodsArg.ends_with(m) || methodsArg == "all")
      methods.push_back(m);
  return methods;
}

// The accuracy references at one N for the accuracy probes.
struct Reference {
  std::vector<std::vector<std::optional<bake::RayHit>>> ref;  // Embree hits along the texel-centre rays
  double atomicsPerProbe = 0.0;                               // vir's splat, CPU-replayed
  bake::CaptureOptions copt;
  bake::CaptureResult capture;
};

// Needs passes.vo at resolution n.
Reference makeReference(const Passes& passes, const Cell& cell, size_t accuracyProbes, int n) {
  const std::vector<glm::vec3>& probes = cell.probes;
  Reference r;
  // Reference rays for the accuracy probes at this N.
  std::vector<std::vector<std::optional<bake::RayHit>>>& ref = r.ref;
  ref.resize(accuracyProbes);
  for (size_t p = 0; p < accuracyProbes; ++p)
    for (uint32_t j = 0; j < uint32_t(n); ++j)
      for (uint32_t i = 0; i < uint32_t(n); ++i)
        ref[p].push_back(
            passes.embree.intersect(probes[p], shared::octTexelDirection(glm::uvec2(i, j), uint32_t(n))));
  uint64_t atomicsSubset = 0;
  for (size_t p = 0; p < accuracyProbes; ++p)
    atomicsSubset += splatAtomics(cell.built.surfels, probes[p], passes.vo);
  r.atomicsPerProbe = double(atomicsSubset) / double(accuracyProbes);
  // Embree capture of the accuracy probes at low spp, direct only: its distance and normal maps are
  // texel means, so it measures texel-mean vs point-sample differences as well as method error.
  bake::CaptureOptions& copt = r.copt;
  copt.resolution = n;
  copt.irradianceResolution = 4;
  copt.samplesPerTexel = 4;
  copt.maxBounces = 0;
  r.capture = bake::captureProbes(passes.embree, passes.sky, std::span(probes).first(accuracyProbes), copt);
  return r;
}

// One (method, N, probe count) configuration of the sweep.
struct Config {
  const std::string& method;
  int n = 0;
  size_t count = 0;
};

// One timed run of the method: its atlas, splat (or raster) and resolve device ms, wall ms.
struct Run {
  gpu::ProbeAtlas atlas;
  double splat = 0.0, resolve = 0.0, wallMs = 0.0;
};

Run runOnce(Passes& passes, const Cell& cell, const Config& cfg, std::span<const glm::vec3> ps) {
  const std::string& method = cfg.method;
  const worlds::BuiltCell& built = cell.built;
  Run r;
  auto t0 = std::chrono::steady_clock::now();
  if (method == "vir_lod") {
    r.atlas = passes.vir.run(built.surfels, ps, passes.vlod);
  } else if (method == "vir_lod_relight") {
    gpu::VirOptions reuse = passes.vlod;
    reuse.reuseSplat = true;
    passes.vir.run(built.surfels, ps, reuse);  // the splat to keep (untimed)
    t0 = std::chrono::steady_clock::now();
    r.atlas = passes.vir.run(built.surfels, ps, reuse, passes.relightIrradiance);
    if (!r.atlas.splatReused)
      fail("vir_lod_relight N={} probes={}: the splat was not reused", cfg.n, cfg.count);
  } else if (method == "vir") {
    r.atlas = passes.vir.run(built.surfels, ps, passes.vo);
  } else {
    gpu::CubemapCapture c = passes.cubemap.run(cell.scene, ps, passes.co);
    r.splat = c.rasterMs;
    r.resolve = c.copyMs + c.resampleMs;
    r.atlas = std::move(c.atlas);
  }
  if (method != "cubemap") {
    r.splat = r.atlas.splatMs;
    r.resolve = r.atlas.resolveMs + r.atlas.fillMs;
  }
  r.wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

// True (logged and listed in results.skipped) when the time projected from the previous probe count at
// the same N exceeds the budget, or the maps would exceed 2 GB.
bool skipConfig(const Config& cfg, double lastMsPerProbe, double budgetS, Results& results) {
  const std::string& method = cfg.method;
  const int n = cfg.n;
  const size_t count = cfg.count;
  const double projectedS = lastMsPerProbe * double(count) * 1e-3;
  const double texelBytes = double(count) * n * n * 64.0;
  if (projectedS > budgetS || texelBytes > 2.0e9) {
    spdlog::info("skip {} N={} probes={}: projected {:.0f} s (budget {} s), {:.1f} GB of maps", method, n,
                 count, projectedS, budgetS, texelBytes * 1e-9);
    results.skipped.push_back(
        {{"method", method}, {"resolution", n}, {"probes", count}, {"projected_s", projectedS}});
    return true;
  }
  return false;
}

// vir_lod's per-probe cut and splat counters and its stage times.
void logLodCounters(const gpu::ProbeAtlas& atlas, int n, size_t count, const gpu::VirOptions& vlod) {
  const auto perProbe = [&](uint64_t total) { return double(total) / double(count); };
  spdlog::info(
      "vir_lod N={} probes={}: per probe {:.0f} cut pairs ({:.0f} dropped as occluded, {:.1f} "
      "nodes per block culled), {:.0f} texel tests, {:.0f} atomics; "
      "{:.1f} % of pairs through the wrapped window; device ms: node radiance {:.1f}, cut + "
      "splat {:.1f}, resolve {:.1f}, fill {:.1f}",
      n, count, perProbe(atlas.splatPairs), perProbe(atlas.occludedPairs),
      double(atlas.occludedNodes) * double(vlod.lodBlockProbes) / double(count),
      perProbe(atlas.splatTexelTests), perProbe(atlas.splatAtomics),
      atlas.splatPairs ? 100.0 * double(atlas.splatWindowPairs) / double(atlas.splatPairs) : 0.0,
      atlas.lodRadianceMs, atlas.splatMs, atlas.resolveMs, atlas.fillMs);
}

void logConfig(const Config& cfg, const Run& fastest, const Measured& m, const Accuracy& acc) {
  const gpu::ProbeAtlas& atlas = fastest.atlas;
  spdlog::info(
      "{} N={} probes={}: {:.1f} ms device, {:.1f} ms wall ({:.3f} ms/probe, {:.0f} probes/s); dist "
      "median {:.2e} p90 {:.4f} off>5% {:.4f}, normal median {:.2f} p90 {:.2f} deg, holes {:.4f}, "
      "sky texels "
      "covered {:.4f} filled {:.4f}, albedo mean abs {:.4f} off>0.05 {:.4f}{}",
      cfg.method, cfg.n, cfg.count, atlas.gpuMs, fastest.wallMs, m.msPerProbe, m.probesPerS,
      acc.distMedianRel, acc.distP90Rel, acc.fracOff5pct, acc.normalMedianDeg, acc.normalP90Deg,
      acc.holeFractionOfHits, acc.skyCoveredFraction, acc.skyFilledFraction, acc.albedoMeanAbs,
      acc.albedoFracOff, m.atomicsPerS > 0 ? fmt::format(", {:.1f} M atomics/s", m.atomicsPerS * 1e-6) : "");
}

void addConfigRow(BenchOutput& o, const Config& cfg, const Cell& cell, const Passes& passes,
                  const Run& fastest, const Measured& m, const Accuracy& acc) {
  const std::string& method = cfg.method;
  const size_t count = cfg.count;
  const gpu::ProbeAtlas& atlas = fastest.atlas;
  const auto perProbe = [&](uint64_t total) { return double(total) / double(count); };
  o.addRow({method,
            std::to_string(cfg.n),
            std::to_string(count),
            std::to_string(cell.built.surfels.size()),
            std::to_string(cell.scene.triangleCount()),
            bench::num(atlas.gpuMs),
            bench::num(m.msPerProbe),
            bench::num(m.probesPerS),
            bench::num(m.probesPerS * double(cell.built.surfels.size())),
            bench::num(fastest.splat),
            bench::num(fastest.resolve),
            bench::num(fastest.wallMs),
            bench::num(m.atomicsPerS),
            bench::num(acc.distMedianRel),
            bench::num(acc.distP90Rel),
            bench::num(acc.fracOff5pct),
            bench::num(acc.normalMedianDeg),
            bench::num(acc.normalP90Deg),
            bench::num(acc.holeFractionOfHits),
            bench::num(acc.captureDistMedianRel),
            bench::num(acc.captureNormalMedianDeg),
            method == "cubemap" ? "0" : bench::num(m.splatPairsPerS),
            method.starts_with("vir_lod") ? std::to_string(passes.lodNodes) : "0",
            method.starts_with("vir_lod") ? bench::num(passes.lodBuildMs) : "0",
            bench::num(perProbe(atlas.splatPairs)),
            bench::num(perProbe(atlas.splatTexelTests)),
            bench::num(perProbe(atlas.splatAtomics)),
            bench::num(atlas.splatPairs ? double(atlas.splatWindowPairs) / double(atlas.splatPairs) : 0.0),
            bench::num(acc.skyCoveredFraction),
            bench::num(acc.skyFilledFraction),
            bench::num(acc.albedoMeanAbs),
            bench::num(acc.albedoFracOff)});
}

// Times one configuration (the fastest of --repeat runs); the method's accuracy is taken at its first
// measured probe count (`acc`), lastMsPerProbe feeds the next count's projection.
void measureConfig(Passes& passes, const Cell& cell, const Options& opt, const Reference& reference,
                   const Config& cfg, std::optional<Accuracy>& acc, double& lastMsPerProbe, BenchOutput& o,
                   Results& results) {
  const std::string& method = cfg.method;
  const int n = cfg.n;
  const size_t count = cfg.count;
  const std::span<const glm::vec3> ps = std::span(cell.probes).first(count);
  Run fastest = runOnce(passes, cell, cfg, ps);
  for (int rep = 1; rep < opt.repeat; ++rep) {  // --repeat: keep the fastest (device time)
    Run r = runOnce(passes, cell, cfg, ps);
    if (r.atlas.gpuMs < fastest.atlas.gpuMs) fastest = std::move(r);
  }
  const gpu::ProbeAtlas& atlas = fastest.atlas;
  if (!acc) {
    acc = accuracy(atlas, reference.ref, opt.accuracyProbes, cell.built.mesh);
    accuracyVsCapture(atlas, reference.capture, reference.copt.maxDistance, *acc);
  }
  Measured m;
  m.probes = count;
  m.msPerProbe = lastMsPerProbe = atlas.gpuMs / double(count);
  m.probesPerS = double(count) / (atlas.gpuMs * 1e-3);
  m.acc = *acc;
  // Over VIR's whole device time, not the splat's stamps: on lavapipe the splat's work shows up in
  // later timestamp intervals (its own interval reads ~0), so only the total is trustworthy there.
  const bool relit = method == "vir_lod_relight";  // splat counters are the kept splat's
  m.atomicsPerS = method == "vir"       ? reference.atomicsPerProbe * double(count) / (atlas.gpuMs * 1e-3)
                  : method == "vir_lod" ? double(atlas.splatAtomics) / (atlas.gpuMs * 1e-3)
                                        : 0.0;
  m.splatPairsPerS = relit ? 0.0 : double(atlas.splatPairs) / (atlas.gpuMs * 1e-3);
  results.best[{method, n}] = m;
  if (method == "vir_lod") logLodCounters(atlas, n, count, passes.vlod);
  logConfig(cfg, fastest, m, *acc);
  addConfigRow(o, cfg, cell, passes, fastest, m, *acc);
  results.perCount[{method, n, count}] = m.probesPerS;
}

// Every selected method at every N and probe count, each count's time projected from the previous one.
void runSweep(Passes& passes, const Cell& cell, const Options& opt, BenchOutput& o, Results& results) {
  const std::vector<std::string> methods = selectMethods(opt.methodsArg);
  Progress progress("vir bench configurations", cell.resolutions.size() * cell.counts.size() * methods.size(),
                    "configs");
  size_t done = 0;
  for (int n : cell.resolutions) {
    passes.vo.resolution = passes.co.resolution = passes.vlod.resolution = n;
    const Reference reference = makeReference(passes, cell, opt.accuracyProbes, n);
    for (const std::string& method : methods) {
      double lastMsPerProbe = 0.0;
      std::optional<Accuracy> acc;
      for (size_t count : cell.counts) {
        if (InterruptGuard::interrupted()) fail("interrupted");
        progress.update(++done);
        const Config cfg{method, n, count};
        if (skipConfig(cfg, lastMsPerProbe, opt.budgetS, results)) continue;
        measureConfig(passes, cell, opt, reference, cfg, acc, lastMsPerProbe, o, results);
      }
    }
  }
  progress.finish();
}

using Best = std::map<std::pair<std::string, int>, Measured>;

// The headline keys: N = 16, vir_lod vs cubemap (v16, c16), then the full splat's vir_full_* and the
// relight figures where measured.
void writeHeadline(nlohmann::ordered_json& s, const Results& results, Best::const_iterator v16,
                   Best::const_iterator c16, const Options& opt, const Cell& cell, const Passes& passes) {
  const Best& best = results.best;
  const double ceiling = results.ceiling;
  const auto f16 = best.find({"vir", 16});
  s["vir_over_cubemap_probes_per_s"] = v16->second.probesPerS / c16->second.probesPerS;
  s["vir_probes_per_s"] = v16->second.probesPerS;
  s["cubemap_probes_per_s"] = c16->second.probesPerS;
  s["hole_fraction"] = v16->second.acc.holeFractionOfHits;
  s["distance_median_rel_error"] = v16->second.acc.distMedianRel;
  s["normal_median_deg"] = v16->second.acc.normalMedianDeg;
  s["atomics_fraction_of_ceiling"] = ceiling > 0.0 ? v16->second.atomicsPerS / ceiling : 0.0;
  s["headline_resolution"] = 16;
  s["vir_probes"] = v16->second.probes;
  s["cubemap_probes"] = c16->second.probes;
  s["cubemap_distance_median_rel_error"] = c16->second.acc.distMedianRel;
  s["cubemap_normal_median_deg"] = c16->second.acc.normalMedianDeg;
  s["cubemap_hole_fraction"] = c16->second.acc.holeFractionOfHits;
  s["sky_covered_fraction"] = v16->second.acc.skyCoveredFraction;
  s["sky_filled_fraction"] = v16->second.acc.skyFilledFraction;
  s["cubemap_sky_covered_fraction"] = c16->second.acc.skyCoveredFraction;
  s["distance_p90_rel_error"] = v16->second.acc.distP90Rel;
  s["cubemap_distance_p90_rel_error"] = c16->second.acc.distP90Rel;
  s["distance_frac_off_5pct"] = v16->second.acc.fracOff5pct;
  s["distance_median_rel_error_vs_capture"] = v16->second.acc.captureDistMedianRel;
  s["cubemap_distance_median_rel_error_vs_capture"] = c16->second.acc.captureDistMedianRel;
  s["normal_median_deg_vs_capture"] = v16->second.acc.captureNormalMedianDeg;
  s["cubemap_normal_median_deg_vs_capture"] = c16->second.acc.captureNormalMedianDeg;
  s["cubemap_distance_frac_off_5pct"] = c16->second.acc.fracOff5pct;
  s["albedo_frac_off_0_05"] = v16->second.acc.albedoFracOff;
  s["cubemap_albedo_frac_off_0_05"] = c16->second.acc.albedoFracOff;
  s["vir_atomics_per_s"] = v16->second.atomicsPerS;
  s["vir_splat_pairs_per_s"] = v16->second.splatPairsPerS;
  s["vir_surfel_probes_per_s"] = v16->second.probesPerS * double(cell.built.surfels.size());
  s["lod_texels"] = opt.lodTexels;
  s["lod_elongation"] = opt.lodElongation;
  s["lod_occlusion_range_m"] = opt.lodOcclusionRange;
  s["fill_near_miss"] = opt.fillNearMiss;
  s["lod_block_probes"] = opt.lodBlockProbes;
  s["repeat"] = opt.repeat;
  s["lod_nodes"] = passes.lodNodes;
  s["lod_build_ms"] = passes.lodBuildMs;
  const auto r16 = best.find({"vir_lod_relight", 16});
  if (r16 != best.end()) {
    // Relighting keeps the winners, so it is not a generation rate: reported beside, not as the ratio.
    s["relight_probes_per_s"] = r16->second.probesPerS;
    s["relight_probes"] = r16->second.probes;
    s["relight_over_vir_lod"] = r16->second.probesPerS / v16->second.probesPerS;
    s["relight_over_cubemap_probes_per_s"] = r16->second.probesPerS / c16->second.probesPerS;
  }
  if (f16 != best.end()) {
    s["vir_full_over_cubemap_probes_per_s"] = f16->second.probesPerS / c16->second.probesPerS;
    s["vir_full_probes_per_s"] = f16->second.probesPerS;
    s["vir_full_distance_p90_rel_error"] = f16->second.acc.distP90Rel;
    s["vir_full_atomics_fraction_of_ceiling"] = ceiling > 0.0 ? f16->second.atomicsPerS / ceiling : 0.0;
  }
  s["atomics64_ceiling_per_s"] = ceiling;
}

// ratio_by_resolution (each method at its largest measured count per N) and
// ratio_by_resolution_and_probes (every (N, probes) both vir_lod and cubemap measured).
void writeByResolution(nlohmann::ordered_json& s, const Results& results, const Cell& cell) {
  const Best& best = results.best;
  const auto& perCount = results.perCount;
  const double ceiling = results.ceiling;
  nlohmann::ordered_json table = nlohmann::ordered_json::array();
  nlohmann::ordered_json byRes = nlohmann::ordered_json::object();
  for (int n : cell.resolutions) {
    const auto v = best.find({"vir_lod", n}), c = best.find({"cubemap", n}), f = best.find({"vir", n});
    if (v != best.end() && c != best.end()) {
      byRes[std::to_string(n)] = {
          {"ratio", v->second.probesPerS / c->second.probesPerS},
          {"vir_probes_per_s", v->second.probesPerS},
          {"cubemap_probes_per_s", c->second.probesPerS},
          {"vir_probes", v->second.probes},
          {"cubemap_probes", c->second.probes},
          {"vir_dist_p90_rel_error", v->second.acc.distP90Rel},
          {"cubemap_dist_p90_rel_error", c->second.acc.distP90Rel},
          {"vir_hole_fraction", v->second.acc.holeFractionOfHits},
          {"vir_atomics_fraction_of_ceiling", ceiling > 0.0 ? v->second.atomicsPerS / ceiling : 0.0}};
      if (f != best.end())
        byRes[std::to_string(n)]["vir_full_ratio"] = f->second.probesPerS / c->second.probesPerS;
      const auto r = best.find({"vir_lod_relight", n});
      if (r != best.end()) {
        byRes[std::to_string(n)]["relight_probes_per_s"] = r->second.probesPerS;
        byRes[std::to_string(n)]["relight_over_cubemap"] = r->second.probesPerS / c->second.probesPerS;
      }
    }
    for (size_t count : cell.counts) {
      const auto vc = perCount.find({"vir_lod", n, count}), cc = perCount.find({"cubemap", n, count});
      if (vc != perCount.end() && cc != perCount.end())
        table.push_back({{"resolution", n},
                         {"probes", count},
                         {"vir_probes_per_s", vc->second},
                         {"cubemap_probes_per_s", cc->second},
                         {"ratio", vc->second / cc->second}});
    }
  }
  s["ratio_by_resolution_and_probes"] = table;
  s["ratio_by_resolution"] = byRes;
}

// summary.json; false (no summary) when N = 16 was not measured for both vir_lod and cubemap.
bool writeSummary(nlohmann::ordered_json& s, const Results& results, const Options& opt, const Cell& cell,
                  const Passes& passes) {
  const Best& best = results.best;
  const auto v16 = best.find({"vir_lod", 16}), c16 = best.find({"cubemap", 16});
  if (v16 == best.end() || c16 == best.end()) {
    spdlog::warn("N = 16 was not measured for both vir_lod and cubemap: no summary");
    return false;
  }
  writeHeadline(s, results, v16, c16, opt, cell, passes);
  writeByResolution(s, results, cell);
  s["cell"] = {cell.cx, cell.cz};
  s["surfels"] = cell.built.surfels.size();
  s["triangles"] = cell.scene.triangleCount();
  s["buried_dropped"] = {{"triangles", cell.built.stats.trianglesBuried},
                         {"surfels", cell.built.stats.surfelsBuried}};
  s["accuracy_probes"] = opt.accuracyProbes;
  s["accuracy_reference"] = "Embree closest hit along each texel-centre ray (deterministic)";
  s["budget_s_per_config"] = opt.budgetS;
  s["cpu_device"] = results.cpuDevice;
  s["skipped"] = results.skipped;
  return true;
}

void logHeadline(nlohmann::ordered_json& s, const Results& results) {
  const auto v16 = results.best.find({"vir_lod", 16}), c16 = results.best.find({"cubemap", 16});
  spdlog::info("VIR / cubemap at N=16: {:.1f}x ({:.0f} vs {:.0f} probes/s); {} configurations skipped",
               s["vir_over_cubemap_probes_per_s"].get<double>(), v16->second.probesPerS,
               c16->second.probesPerS, results.skipped.size());
}

}  // namespace
}  // namespace lfgi::bench

int main(int argc, char** argv) {
  using namespace lfgi;
  CLI::App app{"lfgi benchmark: VIR vs cubemap rasterization (probe generation)"};
  bench::Options opt;
  bench::addOptions(app, opt);
  CLI11_PARSE(app, argc, argv);
  try {
    int cx = 0, cz = 0;
    bench::setDefaults(opt, cx, cz);
    bench::BenchOutput o(opt.out, opt.quick);
    auto ctx = gpu::createContext();
    o.setDevice(ctx->info.name);
    bench::Results results;
    results.cpuDevice = ctx->info.type == "cpu";
    const bench::Cell cell = bench::loadCell(opt, cx, cz, *ctx);
    if (opt.lodStats) {
      bench::printLodStats(opt, cell);
      return 0;
    }
    results.ceiling = bench::atomicCeilingPerSecond(*ctx);
    spdlog::info("atomicMin64 ceiling: {:.1f} M/s", results.ceiling * 1e-6);
    bench::Passes passes(*ctx, cell.built.mesh);
    bench::warmUp(passes, opt, cell);
    bench::setColumns(o);
    InterruptGuard guard;  // alive through the summary: a signal after the sweep still lets it be saved
    bench::runSweep(passes, cell, opt, o, results);
    const bool headline = bench::writeSummary(o.summary(), results, opt, cell, passes);
    o.save();
    if (headline) bench::logHeadline(o.summary(), results);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
