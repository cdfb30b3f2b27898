// Benchmark `stability`: where the methods fail, measured.
//
// Sections (column `section` of results.csv; one row = one measured figure, `metric` names it with its
// unit, `value` holds it):
//   leak        a sunlit room | wall of thickness wall_m | sealed dark room (worlds/leak_scene.h).
//               leak_ratio = mean indirect diffuse luminance of 6 x 6 floor points in the dark room / the
//               same in the sunlit room, shaded by the probe shading pass
//               (bake::ShadingRenderer::shadePoints) from probes of each method: raw_fp16 (capture through
//               the raw FP16 codec), sh_l2 (SH L2 irradiance), generator (the per-cell network trained on
//               this cell, --leak-steps steps; the shipped path: its radiance and irradiance with distance
//               moments VIR regenerates from the surfels, bake::regenerateVirMoments), and stage by stage
//               generator_decoded_moments (the network's own moments) and generator_captured_moments
//               (Embree's), vir_relight (gpu
//               relight -> VIR -> convolution, 6 frames, at the product's N = 16; its own moments),
//               vir_relight_dense (surfels at half the spacing, no sky in fill-only texels). raw_fp16 and
//               sh_l2 keep the captured distance moments (the baseline codecs store radiance only). Chebyshev
//               on and off. probe_setup: "straddle+relocation" (lattice planes at x = +-s/2 around the wall,
//               worlds::placeProbes: what a bake ships; every method), "in_wall+relocation" and "in_wall" (a
//               lattice plane in the wall's mid-plane, relocation on / off; baselines only).
//   unseen      the generator trained on keys {8, 12, 17.5} h decoded at other times and overcast 1.0,
//               against captures at those times (irradiance relative RMS, bake::codecError); baselines: the
//               nearest training key's capture and a linear blend of the two adjacent keys. The dark room
//               holds a ceiling panel ~1e-5 of the sun's irradiance: FP16 round trip of that field and
//               the count of non-finite decoded values.
//   fallback    a cell whose generator misses its target (tiny max-steps) and a diverging one (huge learning
//               rate): what chooseCellModel picks and reports.
//   flicker     a static view during a time-of-day sweep: mean |I_k - I_k-1| / mean I over pixels, per step,
//               for capture truth, decode-only (generator at each time) and VIR relight refresh (one
//               relight frame per step, state kept).
//   streaming   StreamingManager.sample at visible points: largest frame-to-frame change when a cell arrives
//               (fade 0.5 s vs 0) and the jump across a cell border (neighbour resident vs not); burst: the
//               camera teleports every frame for N frames, then flies; frames until fallback < 1 %.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <numeric>
#include <random>

#include "bake/embree_scene.h"
#include "bake/generator_training.h"
#include "bake/probe_sources.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "bench/bench_output.h"
#include "core/error.h"
#include "core/generator.h"
#include "core/octahedral.h"
#include "core/probe_codecs.h"
#include "gpu/relight_pass.h"
#include "gpu/vir_probe_field.h"
#include "streaming/flythrough.h"
#include "streaming/streaming_manager.h"
#include "worlds/leak_scene.h"
#include "worlds/probe_placement.h"
#include "worlds/surfels.h"
#include "worlds/triangle_bvh.h"

namespace {

using namespace lfgi;
using worlds::Aabb;
using worlds::leakProbeGrid;
using worlds::LeakScene;
using worlds::makeLeakScene;

double lum(glm::vec3 c) {
  return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}
double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct Placement {
  std::vector<glm::vec3> offsets;
  std::vector<uint8_t> active;
  size_t relocated = 0, disabled = 0, inSolid = 0;
};

Placement place(const LeakScene& s, const ProbeGrid& grid, bool relocate) {
  Placement p;
  const size_t count = size_t(grid.probeCount());
  if (relocate) {
    const worlds::TriangleBvh bvh(s.mesh);
    const worlds::PlacedProbes pp = worlds::placeProbes(s.mesh, bvh, grid);
    p.offsets = pp.offsets;
    p.active.resize(count);
    for (size_t i = 0; i < count; ++i) p.active[i] = (pp.flags[i] & worlds::kProbeDisabledSolid) ? 0 : 1;
    p.relocated = pp.relocated;
    p.disabled = pp.disabled;
  } else {
    p.offsets.assign(count, glm::vec3(0.0f));
    p.active.assign(count, 1);
  }
  return p;
}

// ---------------------------------------------------------------------------------------------------------
// Probe fields of the methods.

ProbeField codecRoundTrip(const ProbeField& f, const ProbeCodec& codec) {
  ProbeField out = f;
  codec.decode(codec.encode(f), out);
  if (!codec.decodesIrradiance()) deriveIrradiance(out);
  // Inactive probes are zero in the captured field; keep them so (the codecs decode every probe).
  return out;
}

std::vector<int64_t> activeIndex(const ProbeField& f) {
  std::vector<int64_t> idx;
  for (int64_t i = 0; i < f.probeCount(); ++i)
    if (f.isActive(i)) idx.push_back(i);
  return idx;
}

// The field's active probes as one lighting key of a training set (positions normalised to the grid box).
bake::LightingKey keyFromField(const ProbeField& f, const std::vector<int64_t>& idx, float tod,
                               float weather) {
  bake::LightingKey k;
  k.timeOfDayHours = tod;
  k.weather = weather;
  const size_t n2 = size_t(f.resolution) * size_t(f.resolution),
               m2 = size_t(f.irradianceResolution) * size_t(f.irradianceResolution);
  for (int64_t i : idx) {
    bake::ProbeCapture c;
    c.position = f.probePosition(i);
    c.resolution = f.resolution;
    c.irradianceResolution = f.irradianceResolution;
    auto slice = [&](const std::vector<float>& v, size_t per) {
      if (v.empty()) return std::vector<float>(per, 0.0f);
      return std::vector<float>(v.begin() + std::ptrdiff_t(size_t(i) * per),
                                v.begin() + std::ptrdiff_t(size_t(i + 1) * per));
    };
    c.radiance = slice(f.radiance, n2 * 3);
    c.radianceStdError.assign(n2 * 3, 0.0f);
    c.distance = slice(f.distance, n2 * 2);
    c.normal = slice(f.normal, n2 * 3);
    c.albedo = slice(f.albedo, n2 * 3);
    c.irradiance = slice(f.irradiance, m2 * 3);
    k.probes.push_back(std::move(c));
  }
  return k;
}

std::vector<glm::vec3> positions01(const ProbeField& f, const std::vector<int64_t>& idx) {
  std::vector<glm::vec3> p;
  const glm::vec3 lo = f.grid.origin, hi = f.grid.boxMax();
  for (int64_t i : idx) p.push_back(glm::clamp((f.probePosition(i) - lo) / (hi - lo), 0.0f, 1.0f));
  return p;
}

bake::GeneratorTrainingOptions generatorOptions(int resolution, int steps) {
  bake::GeneratorTrainingOptions o;
  o.arch.latentDim = 8;
  o.arch.convChannels.clear();
  int c = 32;
  for (int r = 4; r < resolution; r *= 2, c = std::max(8, c / 2)) o.arch.convChannels.push_back(c);
  o.arch.convChannels.push_back(kGeneratorChannels);
  o.maxSteps = steps;
  o.evalEvery = std::max(20, steps / 5);
  o.irradianceErrorTarget = 0.0;  // run every step: the point is what few steps give
  o.threads = 1;
  return o;
}

// Decodes the generator at (tod, weather) into f's radiance and distance for probes idx (training order),
// then derives irradiance. Returns the number of non-finite decoded values (radiance, distance).
size_t decodeGenerator(const bake::TrainedGenerator& g, const bake::GeneratorTrainingSet& set,
                       const std::vector<int64_t>& idx, float tod, float weather, ProbeField& f) {
  const GeneratorArch& a = g.weights.arch;
  const int n = a.outputResolution();
  if (n != f.resolution) fail("generator resolution {} != field resolution {}", n, f.resolution);
  const std::vector<float> z = g.decoderLatents(set);
  const auto c = conditioningVector(tod, weather);
  const size_t P = idx.size(), per = size_t(kGeneratorChannels) * size_t(n) * size_t(n),
               n2 = size_t(n) * size_t(n);
  std::vector<float> raw(P * per);
  generatorForward(g.weights, z, std::span<const float>(c.data(), size_t(a.condDim)), P, raw);
  size_t bad = 0;
  for (size_t p = 0; p < P; ++p) {
    const size_t i = size_t(idx[p]);
    std::span<float> rad(f.radiance.data() + i * n2 * 3, n2 * 3),
        dist(f.distance.data() + i * n2 * 2, n2 * 2);
    decodeChannels(std::span<const float>(raw.data() + p * per, per), n, g.scale, rad, dist, {}, {});
    for (float v : rad) bad += !std::isfinite(v);
    for (float v : dist) bad += !std::isfinite(v);
  }
  deriveIrradiance(f);
  return bad;
}

// VIR relight: F frames of relight -> VIR -> convolution on the scene's surfels, as a ProbeField (irradiance
// and distance moments from the relight, radiance = the last relit VIR radiance).
struct VirRelight {
  gpu::RelightPass relight;
  gpu::VirPass vir;
  std::vector<worlds::Surfel> surfels;
  gpu::RelightProbes probes;
  gpu::VirOptions virOptions;
  gpu::RelightOptions options;
  gpu::CellLighting state;
  // surfelScale: surfel spacing relative to worlds' default for the probe spacing; filledSeeSky:
  // RelightOptions::filledTexelsSeeSky; resolution: N of the VIR maps (0: the field's), irradiance maps N
  // / 2.
  VirRelight(gpu::Context& ctx, const worlds::TriangleMesh& mesh, const ProbeField& f,
             float surfelScale = 1.0f, bool filledSeeSky = gpu::RelightOptions{}.filledTexelsSeeSky,
             int resolution = 0)
      : relight(ctx), vir(ctx) {
    worlds::SurfelOptions so;
    so.spacing = surfelScale * worlds::surfelSpacingForProbeSpacing(f.grid.spacing.x);
    options.filledTexelsSeeSky = filledSeeSky;
    surfels = worlds::sampleSurfels(mesh, so);
    probes.grid = f.grid;
    for (int64_t i = 0; i < f.probeCount(); ++i) probes.positions.push_back(f.probePosition(i));
    probes.active = f.active;
    virOptions.resolution = resolution > 0 ? resolution : f.resolution;
    virOptions.maxRange = 32.0f;
    options.irradianceResolution = resolution > 0 ? std::max(4, resolution / 2) : f.irradianceResolution;
  }
  void frames(const worlds::SkyModel& sky, int count) {
    for (int k = 0; k < count; ++k)
      gpu::relightFrame(relight, vir, surfels, probes, sky.params, virOptions, options, state);
  }
  // The relit field on like's probes, at the VIR resolution.
  ProbeField field(const ProbeField& like) const {
    ProbeField f;
    f.grid = like.grid;
    f.offsets = like.offsets;
    f.active = like.active;
    f.resolution = virOptions.resolution;
    f.irradianceResolution = options.irradianceResolution;
    const size_t count = size_t(f.probeCount());
    f.irradiance.resize(count * size_t(f.irradianceResolution * f.irradianceResolution) * 3);
    f.distance.resize(count * size_t(f.resolution * f.resolution) * 2);
    f.radiance.resize(count * size_t(f.resolution * f.resolution) * 3);
    const size_t n2 = size_t(f.resolution) * size_t(f.resolution),
                 m2 = size_t(f.irradianceResolution) * size_t(f.irradianceResolution);
    for (int64_t i = 0; i < f.probeCount(); ++i) {
      const bool on = f.isActive(i);
      for (size_t t = 0; t < m2; ++t)
        for (int ch = 0; ch < 3; ++ch)
          f.irradiance[(size_t(i) * m2 + t) * 3 + size_t(ch)] =
              on ? state.probes.irradiance[size_t(i) * m2 + t][ch] : 0.0f;
      for (size_t t = 0; t < n2; ++t) {
        for (int ch = 0; ch < 2; ++ch)
          f.distance[(size_t(i) * n2 + t) * 2 + size_t(ch)] =
              on ? state.probes.moments[size_t(i) * n2 + t][ch] : 0.0f;
        for (int ch = 0; ch < 3; ++ch)
          f.radiance[(size_t(i) * n2 + t) * 3 + size_t(ch)] =
              on ? state.atlas.radiance[size_t(i) * n2 + t][ch] : 0.0f;
      }
    }
    return f;
  }
};

size_t nonFinite(const std::vector<float>& v) {
  return size_t(std::count_if(v.begin(), v.end(), [](float x) { return !std::isfinite(x); }));
}

struct Ctx {
  bench::BenchOutput& o;
  gpu::Context& gpu;
  bool quick;
  int resolution, spp;
  int leakSteps = 0;  // generator training steps in the leak section (0: 150 in --quick, else 500)
  void row(const std::string& section, const std::string& method, double wall, double spacing,
           const std::string& reloc, const std::string& cheb, double tod, double overcast,
           const std::string& metric, double value) {
    o.addRow({section, method, bench::num(wall), bench::num(spacing), reloc, cheb, bench::num(tod),
              bench::num(overcast), metric, bench::num(value)});
  }
  bake::CaptureOptions capture() const {
    bake::CaptureOptions co;
    co.resolution = resolution;
    co.irradianceResolution = std::max(4, resolution / 2);
    co.samplesPerTexel = spp;
    co.maxBounces = 4;
    return co;
  }
};

// ---------------------------------------------------------------------------------------------------------
// 1. Light leaks.
struct LeakSummary {
  // Per method: worst leak ratio over walls and spacings (straddling lattice + relocation), Chebyshev on/off.
  std::map<std::string, double> worst, worstOff;
};

LeakSummary leakSection(Ctx& c, const std::vector<float>& walls, const std::vector<float>& spacings) {
  LeakSummary sum;
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
  auto raw = makeRawFp16Codec();
  auto sh2 = makeShCodec(2);
  auto shipped = makeShL1Q8Codec();
  for (float t : walls) {
    const LeakScene s = makeLeakScene(t);
    const bake::EmbreeScene scene(s.mesh, "leak scene");
    bake::ShadingRenderer renderer(c.gpu, s.mesh);
    for (float sp : spacings) {
      // (lattice, relocation): straddling + relocation is the shipped set-up (every method); the in-wall
      // lattice with relocation on and off isolates what relocation does (baselines only).
      for (const auto& [inWall, relocate] :
           {std::pair{false, true}, std::pair{true, true}, std::pair{true, false}}) {
        const ProbeGrid grid = leakProbeGrid(s, sp, inWall);
        const std::string lattice = inWall ? "in_wall" : "straddle";
        const auto t0 = std::chrono::steady_clock::now();
        const Placement pl = place(s, grid, relocate);
        const ProbeField cap = bake::captureGridField(scene, sky, grid, pl.offsets, pl.active, c.capture());
        const double capS = seconds(t0);
        const std::string reloc = lattice + (relocate ? "+relocation" : "");
        std::vector<std::pair<std::string, ProbeField>> fields;
        fields.emplace_back("raw_fp16", codecRoundTrip(cap, *raw));
        fields.emplace_back("sh_l2", codecRoundTrip(cap, *sh2));
        worlds::SurfelOptions so;
        so.spacing = worlds::surfelSpacingForProbeSpacing(cap.grid.spacing.x);
        const std::vector<worlds::Surfel> surfels = worlds::sampleSurfels(s.mesh, so);
        if (!inWall) {
          // The shipped codec (`lfgi bake`'s default sh-l1: SH L1 in the int8 APV split) with its
          // visibility regenerated by VIR from the cell's surfels at load (bake::regenerateVirMoments,
          // docs/ARCHITECTURE.md "Where visibility comes from").
          ProbeField f = codecRoundTrip(cap, *shipped);
          bake::regenerateVirMoments(c.gpu, surfels, cap.offsets, f, 32.0f);
          fields.emplace_back("sh_l1_int8", std::move(f));
        }
        // The network and VIR rows: relocation on only (what the bake ships), and in --quick at 1 m only.
        const bool heavy = !inWall && (!c.quick || sp == 1.0f);
        double genErr = 0.0;
        if (heavy) {
          const std::vector<int64_t> idx = activeIndex(cap);
          bake::GeneratorTrainingSet set;
          set.positions01 = positions01(cap, idx);
          set.keys.push_back(keyFromField(cap, idx, 12.0f, 0.0f));
          const bake::TrainedGenerator g =
              bake::trainGenerator(set, generatorOptions(cap.resolution, c.leakSteps > 0 ? c.leakSteps
                                                                         : c.quick       ? 150
                                                                                         : 500));
          genErr = g.report.irradianceRelativeRms;
          ProbeField decoded = cap;
          decodeGenerator(g, set, idx, 12.0f, 0.0f, decoded);
          // The generator codec (`--codec per-cell`) carries radiance; its visibility comes from the
          // cell's surfels at load as for every codec. Stage by stage beside it: the decoder's own
          // moments, and the captured (Embree) moments.
          ProbeField withVir = decoded, withCaptured = decoded;
          withCaptured.distance = cap.distance;
          bake::regenerateVirMoments(c.gpu, surfels, cap.offsets, withVir, 32.0f);
          fields.emplace_back("generator", std::move(withVir));
          fields.emplace_back("generator_decoded_moments", std::move(decoded));
          fields.emplace_back("generator_captured_moments", std::move(withCaptured));
          // At the product's VIR resolution (gpu::VirOptions, bake/probe_sources.h: N = 16).
          VirRelight vr(c.gpu, s.mesh, cap, 1.0f, gpu::RelightOptions{}.filledTexelsSeeSky,
                        gpu::VirOptions{}.resolution);
          vr.frames(sky, 6);
          fields.emplace_back("vir_relight", vr.field(cap));
          c.row("leak", "vir_relight", t, sp, reloc, "-", 12.0, 0.0, "vir_hole_fraction",
                vr.state.atlas.holeFractionAfterFill);
          // Surfels are a porous wall: a texel ray through a gap between a thin wall's discs reaches the
          // sunlit room (its back-facing side is culled) or, through the ceiling, the sky. Denser surfels
          // and no sky in fill-only texels narrow the gaps.
          VirRelight dense(c.gpu, s.mesh, cap, 0.5f, false, gpu::VirOptions{}.resolution);
          dense.frames(sky, 6);
          fields.emplace_back("vir_relight_dense", dense.field(cap));
        }
        for (auto& [method, f] : fields) {
          const ProbeField* fp[] = {&f};
          renderer.setProbes(fp, 1);
          for (bool cheb : {true, false}) {
            const double lit = bake::roomFloorIndirect(renderer, sky, s.litAir, cheb),
                         dark = bake::roomFloorIndirect(renderer, sky, s.darkAir, cheb);
            const double ratio = lit > 0.0 ? dark / lit : 0.0;
            c.row("leak", method, t, sp, reloc, cheb ? "on" : "off", 12.0, 0.0, "leak_ratio", ratio);
            c.row("leak", method, t, sp, reloc, cheb ? "on" : "off", 12.0, 0.0, "lit_room_indirect", lit);
            c.row("leak", method, t, sp, reloc, cheb ? "on" : "off", 12.0, 0.0, "dark_room_indirect", dark);
            if (!inWall && cheb) sum.worst[method] = std::max(sum.worst[method], ratio);
            if (!inWall && !cheb) sum.worstOff[method] = std::max(sum.worstOff[method], ratio);
            spdlog::info(
                "leak t {:.2f} m, spacing {} m, relocation {}, {} Chebyshev {}: lit {:.4g} dark {:.4g} ratio "
                "{:.3g}",
                t, sp, reloc, method, cheb ? "on" : "off", lit, dark, ratio);
          }
        }
        c.row("leak", "capture", t, sp, reloc, "-", 12.0, 0.0, "probes_active",
              double(std::count(pl.active.begin(), pl.active.end(), 1)));
        c.row("leak", "capture", t, sp, reloc, "-", 12.0, 0.0, "probes_relocated", double(pl.relocated));
        c.row("leak", "capture", t, sp, reloc, "-", 12.0, 0.0, "probes_disabled", double(pl.disabled));
        c.row("leak", "capture", t, sp, reloc, "-", 12.0, 0.0, "capture_s", capS);
        if (heavy) c.row("leak", "generator", t, sp, reloc, "-", 12.0, 0.0, "irr_rel_rms", genErr);
      }
    }
  }
  return sum;
}

// ---------------------------------------------------------------------------------------------------------
// 2. Unseen lighting (+ the dark room's 1e-5 panel), 3. generator failure, 4. flicker: one cell (t = 0.2 m,
// 1 m spacing, relocation on) shared by the three.
struct CellSetup {
  LeakScene scene;
  ProbeGrid grid;
  Placement placement;
  std::vector<int64_t> idx;
  std::vector<glm::vec3> positions;
  bake::GeneratorTrainingSet train;  // keys 8, 12, 17.5 h
  bake::TrainedGenerator model;
};

struct UnseenSummary {
  double betweenRelRms = 0.0;               // mean over 10 h and 15 h (between the keys: interpolation)
  std::map<std::string, double> generator;  // per evaluation ("10h", "6h", "12h_overcast1", ...)
  std::map<std::string, double> vir;        // VIR relight (the streaming relight) per evaluation
  size_t nonFiniteValues = 0;
};

// A capture field of probes idx from a training-set key (captureTrainingSet holds no directly seen discs,
// as shading fields do not).
ProbeField fieldFromKey(const CellSetup& cs, const bake::LightingKey& key) {
  bake::CaptureResult r;
  r.probes = key.probes;
  r.done.assign(key.probes.size(), 1);
  r.probesDone = key.probes.size();
  return bake::probeFieldFromCapture(cs.grid, r, cs.idx);
}

// A zeroed field of the cell's grid at the capture's resolutions: what decodeGenerator writes into.
ProbeField decodeTarget(const CellSetup& cs, const bake::CaptureOptions& co) {
  ProbeField f;
  f.grid = cs.grid;
  f.resolution = co.resolution;
  f.irradianceResolution = co.irradianceResolution;
  const size_t P = size_t(cs.grid.probeCount()), n2 = size_t(co.resolution * co.resolution);
  f.radiance.assign(P * n2 * 3, 0.0f);
  f.distance.assign(P * n2 * 2, 0.0f);
  return f;
}

// The streaming manager's VIR relight (gpu::VirFieldRelighter as streaming::VirRelightSource runs it
// from a codec field: 3 frames, no seed, no discs, as the training captures hold none) of the cell's
// surfels at (tod, weather): radiance maps of probes cs.idx in the capture layout.
std::vector<float> virRelightRadiance(Ctx& c, CellSetup& cs, const bake::CaptureOptions& co, float tod,
                                      float weather, double* ms) {
  worlds::SurfelOptions so;
  so.spacing = worlds::surfelSpacingForProbeSpacing(cs.grid.spacing.x);
  const std::vector<worlds::Surfel> surfels = worlds::sampleSurfels(cs.scene.mesh, so);
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{tod, 45.0f, 172, 3.0f, weather});
  gpu::VirFieldOptions vo;
  vo.resolution = co.resolution;
  vo.irradianceResolution = co.irradianceResolution;
  vo.frames = 3;
  vo.maxRange = 32.0f;
  gpu::VirFieldRelighter relighter(c.gpu);
  ProbeField f;
  gpu::VirFieldStats st;
  const auto t0 = std::chrono::steady_clock::now();
  relighter.run(surfels, cs.grid, cs.placement.offsets, cs.placement.active, sky.params, vo, f, nullptr, &st);
  if (ms) *ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const size_t n2 = size_t(co.resolution) * size_t(co.resolution);
  std::vector<float> out;
  for (int64_t i : cs.idx)
    out.insert(out.end(), f.radiance.begin() + std::ptrdiff_t(size_t(i) * n2 * 3),
               f.radiance.begin() + std::ptrdiff_t(size_t(i + 1) * n2 * 3));
  return out;
}

// One lighting condition of the unseen section.
struct UnseenEval {
  float tod, weather;
  std::string kind;
};

// One evaluation: the generator decoded at ev (key e of all) against the capture there, beside the nearest
// training key, the blend of the adjacent keys and the VIR relight; adds to sum and the between-keys mean.
void unseenEval(Ctx& c, CellSetup& cs, const bake::CaptureOptions& co, const bake::GeneratorTrainingSet& all,
                size_t e, const UnseenEval& ev, UnseenSummary& sum, double& betweenSum, int& betweenN) {
  const float trainT[] = {8.0f, 12.0f, 17.5f};
  bake::GeneratorTrainingSet one;
  one.positions01 = all.positions01;
  one.keys = {all.keys[e]};
  // Generator decoded at this key (through the same decode the runtime uses).
  ProbeField f = decodeTarget(cs, co);
  f.offsets = cs.placement.offsets;
  f.active = cs.placement.active;
  const size_t bad = decodeGenerator(cs.model, cs.train, cs.idx, ev.tod, ev.weather, f);
  sum.nonFiniteValues += bad + nonFinite(f.irradiance);
  std::vector<std::vector<float>> decoded(1);
  const size_t n2 = size_t(f.resolution) * size_t(f.resolution);
  for (int64_t i : cs.idx)
    decoded[0].insert(decoded[0].end(), f.radiance.begin() + std::ptrdiff_t(size_t(i) * n2 * 3),
                      f.radiance.begin() + std::ptrdiff_t(size_t(i + 1) * n2 * 3));
  const double gen = bake::codecError(one, decoded).irradianceRelativeRms;
  // Baselines: nearest training key's capture; linear blend of the two adjacent keys (clamped outside).
  size_t nearest = 0;
  for (size_t k = 1; k < 3; ++k)
    if (std::abs(trainT[k] - ev.tod) < std::abs(trainT[nearest] - ev.tod)) nearest = k;
  auto keyRadiance = [&](size_t k) {
    std::vector<float> v;
    for (const bake::ProbeCapture& p : cs.train.keys[k].probes)
      v.insert(v.end(), p.radiance.begin(), p.radiance.end());
    return v;
  };
  std::vector<std::vector<float>> near = {keyRadiance(nearest)};
  const double nearestErr = bake::codecError(one, near).irradianceRelativeRms;
  size_t a = 0;
  while (a + 2 < 3 && ev.tod > trainT[a + 1]) ++a;
  const float w = std::clamp((ev.tod - trainT[a]) / (trainT[a + 1] - trainT[a]), 0.0f, 1.0f);
  std::vector<float> ra = keyRadiance(a), rb = keyRadiance(a + 1);
  for (size_t i = 0; i < ra.size(); ++i) ra[i] = (1.0f - w) * ra[i] + w * rb[i];
  std::vector<std::vector<float>> blend = {ra};
  const double blendErr = bake::codecError(one, blend).irradianceRelativeRms;
  double virMs = 0.0;
  std::vector<std::vector<float>> virMaps = {virRelightRadiance(c, cs, co, ev.tod, ev.weather, &virMs)};
  const double virErr = bake::codecError(one, virMaps).irradianceRelativeRms;
  c.row("unseen", "vir_relight", 0.2, 1.0, ev.kind, "-", ev.tod, ev.weather, "irr_rel_rms", virErr);
  c.row("unseen", "vir_relight", 0.2, 1.0, ev.kind, "-", ev.tod, ev.weather, "relight_ms", virMs);
  c.row("unseen", "generator", 0.2, 1.0, ev.kind, "-", ev.tod, ev.weather, "irr_rel_rms", gen);
  c.row("unseen", "nearest_key", 0.2, 1.0, ev.kind, "-", ev.tod, ev.weather, "irr_rel_rms", nearestErr);
  c.row("unseen", "key_blend", 0.2, 1.0, ev.kind, "-", ev.tod, ev.weather, "irr_rel_rms", blendErr);
  c.row("unseen", "generator", 0.2, 1.0, ev.kind, "-", ev.tod, ev.weather, "nonfinite_values", double(bad));
  spdlog::info(
      "unseen {} h overcast {} ({}): generator irr rel RMS {:.4f}, nearest key {:.4f}, key blend {:.4f}, "
      "VIR relight {:.4f} ({:.0f} ms), {} non-finite",
      ev.tod, ev.weather, ev.kind, gen, nearestErr, blendErr, virErr, virMs, bad);
  if (ev.kind != "trained") {
    sum.generator[fmt::format("{}h{}", ev.tod, ev.weather > 0.0f ? "_overcast1" : "")] = gen;
    sum.vir[fmt::format("{}h{}", ev.tod, ev.weather > 0.0f ? "_overcast1" : "")] = virErr;
    if (ev.kind == "between") {
      betweenSum += gen;
      ++betweenN;
    }
  }
}

// Extremes of the conditioning the codec never saw: every decoded value finite.
void unseenExtremes(Ctx& c, const CellSetup& cs, const bake::CaptureOptions& co, UnseenSummary& sum) {
  for (const auto& [tod, weather] :
       std::vector<std::pair<float, float>>{{0.0f, 0.0f}, {24.0f, 1.0f}, {3.0f, 1.0f}, {12.0f, 1.0f}}) {
    ProbeField f = decodeTarget(cs, co);
    const size_t bad = decodeGenerator(cs.model, cs.train, cs.idx, tod, weather, f) + nonFinite(f.irradiance);
    sum.nonFiniteValues += bad;
    c.row("unseen", "generator", 0.2, 1.0, "extreme", "-", tod, weather, "nonfinite_values", double(bad));
  }
}

// The 1e-5 interior light through FP16 and the generator: dark-room probes' irradiance error.
void interiorPanel(Ctx& c, const CellSetup& cs, UnseenSummary& sum) {
  const ProbeField f = fieldFromKey(cs, cs.train.keys[1]);
  auto raw = makeRawFp16Codec();
  const ProbeField r = codecRoundTrip(f, *raw);
  const size_t bad = nonFinite(r.radiance) + nonFinite(r.irradiance);
  sum.nonFiniteValues += bad;
  const int m2 = f.irradianceResolution * f.irradianceResolution;
  double litE = 0.0, darkE = 0.0, se = 0.0, sg = 0.0;
  size_t litN = 0, darkN = 0;
  for (int64_t i : cs.idx) {
    const glm::vec3 p = f.probePosition(i);
    const bool dark = glm::all(glm::greaterThan(p, cs.scene.darkAir.min)) &&
                      glm::all(glm::lessThan(p, cs.scene.darkAir.max));
    const bool lit =
        glm::all(glm::greaterThan(p, cs.scene.litAir.min)) && glm::all(glm::lessThan(p, cs.scene.litAir.max));
    for (int t = 0; t < m2; ++t) {
      const size_t o = (size_t(i) * size_t(m2) + size_t(t)) * 3;
      const glm::vec3 e(f.irradiance[o], f.irradiance[o + 1], f.irradiance[o + 2]);
      const glm::vec3 d(r.irradiance[o], r.irradiance[o + 1], r.irradiance[o + 2]);
      if (dark) {
        darkE += lum(e);
        ++darkN;
        se += double(glm::dot(d - e, d - e));
        sg += double(glm::dot(e, e));
      }
      if (lit) {
        litE += lum(e);
        ++litN;
      }
    }
  }
  const double ratio = darkN && litN && darkE > 0.0 ? (litE / double(litN)) / (darkE / double(darkN)) : 0.0;
  const double relRms = sg > 0.0 ? std::sqrt(se / sg) : 0.0;
  c.row("unseen", "raw_fp16", 0.2, 1.0, "panel_1e-5", "-", 12.0, 0.0, "lit_over_dark_irradiance", ratio);
  c.row("unseen", "raw_fp16", 0.2, 1.0, "panel_1e-5", "-", 12.0, 0.0, "dark_irr_rel_rms", relRms);
  c.row("unseen", "raw_fp16", 0.2, 1.0, "panel_1e-5", "-", 12.0, 0.0, "nonfinite_values", double(bad));
  spdlog::info(
      "interior panel: lit/dark probe irradiance {:.3g}; FP16 dark-room irradiance rel RMS {:.3g}, {} "
      "non-finite",
      ratio, relRms, bad);
}

UnseenSummary unseenSection(Ctx& c, CellSetup& cs, const bake::EmbreeScene& scene) {
  UnseenSummary sum;
  const bake::CaptureOptions co = c.capture();
  const glm::vec3 lo = cs.grid.origin, hi = cs.grid.boxMax();
  const std::vector<UnseenEval> evals = {{8.0f, 0.0f, "trained"},  {12.0f, 0.0f, "trained"},
                                         {17.5f, 0.0f, "trained"}, {10.0f, 0.0f, "between"},
                                         {15.0f, 0.0f, "between"}, {6.0f, 0.0f, "outside"},
                                         {20.0f, 0.0f, "outside"}, {12.0f, 1.0f, "overcast"}};
  std::vector<bake::LightingKeySpec> specs;
  for (const UnseenEval& e : evals) specs.push_back({e.tod, e.weather});
  const bake::GeneratorTrainingSet all = bake::captureTrainingSet(scene, cs.positions, lo, hi, specs, co);
  double betweenSum = 0.0;
  int betweenN = 0;
  for (size_t e = 0; e < evals.size(); ++e)
    unseenEval(c, cs, co, all, e, evals[e], sum, betweenSum, betweenN);
  sum.betweenRelRms = betweenN ? betweenSum / betweenN : 0.0;
  unseenExtremes(c, cs, co, sum);
  interiorPanel(c, cs, sum);
  return sum;
}

void fallbackSection(Ctx& c, const CellSetup& cs) {
  // A target the network cannot reach in 20 steps; the bake's rule: SH L1 stored beside it.
  struct Case {
    std::string name;
    int steps;
    float lr;
  };
  // tiny_steps misses the target; lr 1e3 kills the outputs (all radiance 0: error exactly 1, finite, so
  // not a divergence: rejected on error); lr 1e6 (weights and latents) overflows: detected as divergence.
  for (const Case& k :
       {Case{"tiny_steps", 20, 3e-3f}, Case{"collapse_lr1e3", 60, 1e3f}, Case{"diverge_lr1e6", 60, 1e6f}}) {
    bake::ModelSizingOptions so;
    so.irradianceErrorTarget = 0.01;
    so.noNetworkKinds = {bake::CellModelKind::kShL1};
    so.training = generatorOptions(cs.train.resolution(), k.steps);
    so.training.learningRate = k.lr;
    if (k.lr > 1.0f) so.training.latentLearningRate = k.lr;
    so.candidates = {so.training.arch};
    const bake::CellModelChoice ch = bake::chooseCellModel(cs.train, {}, so);
    const double genErr = ch.attempts.back().irradianceRelativeRms;
    c.row("fallback", k.name, 0.2, 1.0, std::string(bake::cellModelKindName(ch.kind)), "-", 0.0, 0.0,
          "chosen_irr_rel_rms", ch.error.irradianceRelativeRms);
    c.row("fallback", k.name, 0.2, 1.0, "generator", "-", 0.0, 0.0, "generator_irr_rel_rms", genErr);
    c.row("fallback", k.name, 0.2, 1.0, "sh-l1", "-", 0.0, 0.0, "sh_l1_irr_rel_rms",
          ch.attempts.front().irradianceRelativeRms);
    c.row("fallback", k.name, 0.2, 1.0, std::string(bake::cellModelKindName(ch.kind)), "-", 0.0, 0.0,
          "reached_target", ch.reachedTarget ? 1.0 : 0.0);
    // The candidate alone (chooseCellModel keeps only the chosen model): did training detect divergence?
    const bake::TrainedGenerator g = bake::trainGenerator(cs.train, so.training);
    c.row("fallback", k.name, 0.2, 1.0, "generator", "-", 0.0, 0.0, "generator_diverged",
          g.report.diverged ? 1.0 : 0.0);
    c.row("fallback", k.name, 0.2, 1.0, "generator", "-", 0.0, 0.0, "generator_steps",
          double(g.report.steps));
    c.row("fallback", k.name, 0.2, 1.0, std::string(bake::cellModelKindName(ch.kind)), "-", 0.0, 0.0,
          "chose_network", ch.kind == bake::CellModelKind::kGenerator ? 1.0 : 0.0);
    spdlog::info("fallback {}: chose {} (reached target {}), error {:.4g}; generator {:.4g}, SH L1 {:.4g}",
                 k.name, ch.describe(), ch.reachedTarget, ch.error.irradianceRelativeRms, genErr,
                 ch.attempts.front().irradianceRelativeRms);
  }
}

// Flicker of a static view over a time-of-day sweep.
double flickerSection(Ctx& c, CellSetup& cs, const bake::EmbreeScene& scene,
                      bake::ShadingRenderer& renderer) {
  const float t0 = c.quick ? 11.0f : 9.0f, t1 = c.quick ? 12.0f : 15.0f, dt = c.quick ? 0.1f : 0.1f;
  const int steps = int(std::lround((t1 - t0) / dt)) + 1;
  bake::PinholeCamera cam;
  cam.position = glm::vec3(-3.6f, 1.6f, -1.6f);
  cam.target = glm::vec3(-0.1f, 0.6f, 1.2f);
  cam.verticalFovDeg = 70.0f;
  const int W = c.quick ? 40 : 64, H = c.quick ? 30 : 48;
  const bake::CaptureOptions co = c.capture();
  ProbeField like;
  {
    const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{t0, 45.0f, 172, 3.0f, 0.0f});
    like = bake::captureGridField(scene, sky, cs.grid, cs.placement.offsets, cs.placement.active, co);
  }
  VirRelight vr(c.gpu, cs.scene.mesh, like);
  vr.frames(worlds::makeSky(worlds::SkyState{t0, 45.0f, 172, 3.0f, 0.0f}), 6);  // converged before the sweep
  std::vector<std::vector<float>> prev(3);
  const char* names[] = {"capture_truth", "decode_only", "vir_relight"};
  std::vector<double> mean(3, 0.0), maxv(3, 0.0);
  for (int k = 0; k < steps; ++k) {
    const float tod = t0 + float(k) * dt;
    const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{tod, 45.0f, 172, 3.0f, 0.0f});
    std::vector<ProbeField> fields;
    fields.push_back(
        bake::captureGridField(scene, sky, cs.grid, cs.placement.offsets, cs.placement.active, co));
    ProbeField g = like;
    decodeGenerator(cs.model, cs.train, cs.idx, tod, 0.0f, g);
    fields.push_back(std::move(g));
    if (k > 0) vr.frames(sky, 1);
    fields.push_back(vr.field(like));
    for (int m = 0; m < 3; ++m) {
      const ProbeField* fp[] = {&fields[size_t(m)]};
      renderer.setProbes(fp, 1);
      gpu::ShadingOptions so;
      so.specular = false;
      const bake::ShadedView v = renderer.render(sky, cam, W, H, so);
      const int ch[3] = {v.image.channelIndex("indirect.R"), v.image.channelIndex("indirect.G"),
                         v.image.channelIndex("indirect.B")};
      const int wi = v.image.channelIndex("weight");
      std::vector<float> L(size_t(W) * size_t(H), -1.0f);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          if (v.image.at(x, y, wi) > 0.0f)
            L[size_t(y) * size_t(W) + size_t(x)] = float(
                lum(glm::vec3(v.image.at(x, y, ch[0]), v.image.at(x, y, ch[1]), v.image.at(x, y, ch[2]))));
      if (k > 0) {
        double d = 0.0, s = 0.0;
        size_t n = 0;
        for (size_t p = 0; p < L.size(); ++p)
          if (L[p] >= 0.0f && prev[size_t(m)][p] >= 0.0f) {
            d += std::abs(double(L[p]) - double(prev[size_t(m)][p]));
            s += double(L[p]);
            ++n;
          }
        const double f = s > 0.0 ? d / s : 0.0;
        mean[size_t(m)] += f / double(steps - 1);
        maxv[size_t(m)] = std::max(maxv[size_t(m)], f);
        c.row("flicker", names[m], 0.2, 1.0, "on", "on", tod, 0.0, "flicker_rel", f);
      }
      prev[size_t(m)] = std::move(L);
    }
    spdlog::info("flicker step {}/{} ({:.2f} h)", k + 1, steps, tod);
  }
  for (int m = 0; m < 3; ++m) {
    c.row("flicker", names[m], 0.2, 1.0, "on", "on", -1.0, 0.0, "mean_flicker_rel", mean[size_t(m)]);
    c.row("flicker", names[m], 0.2, 1.0, "on", "on", -1.0, 0.0, "max_flicker_rel", maxv[size_t(m)]);
    spdlog::info("flicker {}: mean {:.4g}, max {:.4g} per {:.2f} h step", names[m], mean[size_t(m)],
                 maxv[size_t(m)], dt);
    c.o.summary()[std::string("flicker_mean_") + names[m]] = mean[size_t(m)];
    c.o.summary()[std::string("flicker_max_") + names[m]] = maxv[size_t(m)];
  }
  c.o.summary()["flicker_step_hours"] = dt;
  return std::max(maxv[1], maxv[2]);
}

// ---------------------------------------------------------------------------------------------------------
// 5. Streaming pops and seams, 6. burst load (synthetic cells: analytic fields with a known answer).
streaming::SyntheticSourceOptions streamWorld() {
  streaming::SyntheticSourceOptions o;
  o.layout = {{0.0f, 0.0f}, 64.0f, {32, 32}};
  o.probeSpacing = 8.0f;
  o.layers = 2;
  o.irradianceResolution = 8;
  return o;
}

streaming::StreamingConfig streamConfig(size_t cellBytes, float fade) {
  streaming::StreamingConfig c;
  c.decodeRadius = 100.0f;
  c.keepRadius = 140.0f;
  c.ioThreads = 0;
  c.maxInlineLoadsPerFrame = 4;
  c.maxActivationsPerFrame = 4;
  c.activateBudgetMs = 1e9;
  c.fadeSeconds = fade;
  c.memoryBudgetBytes = 40 * cellBytes;
  return c;
}

struct StreamSummary {
  double popFade = 0.0, popNoFade = 0.0, seamResident = 0.0, seamFallback = 0.0;
  int burstRecoveryFrames = -1;
  bool budgetHeld = true;
  int missing = 0;
};

// Pops: the camera appears at a point, a probe-lit cell arrives; largest relative change of the sampled
// irradiance at visible points between consecutive frames.
void streamingPops(Ctx& c, StreamSummary& sum) {
  for (float fade : {0.5f, 0.0f}) {
    streaming::SyntheticCellSource src(streamWorld());
    streaming::StreamingManager m(src, streamConfig(src.maxCellBytes(), fade));
    std::vector<glm::vec3> pts;
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 8; ++i)
        pts.push_back(glm::vec3(1000.0f + 7.9f * float(i), 0.0f, 1000.0f + 7.9f * float(j)));
    std::vector<glm::vec3> prev;  // before the first update: every point lit by its cell's fallback
    for (const glm::vec3& p : pts) prev.push_back(m.sample(p, glm::vec3(0, 1, 0)).irradiance);
    double worst = 0.0;
    for (int f = 0; f < 120; ++f) {
      streaming::FrameInput in;
      in.position = glm::vec3(1030.0f, 20.0f, 1030.0f);
      in.dtSeconds = 1.0f / 60.0f;
      m.update(in);
      std::vector<glm::vec3> cur;
      for (const glm::vec3& p : pts) cur.push_back(m.sample(p, glm::vec3(0, 1, 0)).irradiance);
      if (!prev.empty())
        for (size_t i = 0; i < cur.size(); ++i)
          worst = std::max(worst, std::abs(lum(cur[i]) - lum(prev[i])) / std::max(1e-9, lum(cur[i])));
      prev = std::move(cur);
    }
    (fade > 0.0f ? sum.popFade : sum.popNoFade) = worst;
    c.row("streaming", fade > 0.0f ? "fade_0.5s" : "fade_0", 0.0, 8.0, "-", "-", 12.0, 0.0,
          "pop_max_rel_change", worst);
    spdlog::info("streaming pop, fade {} s: largest frame-to-frame change {:.4g} (relative)", fade, worst);
  }
}

// Seams: jump of the sampled irradiance across the border x = 1024 at visible points, with the neighbour
// resident, and with it not resident (the camera far enough that only the near cell is wanted).
void streamingSeams(Ctx& c, StreamSummary& sum) {
  streaming::SyntheticCellSource src(streamWorld());
  streaming::StreamingConfig cfg = streamConfig(src.maxCellBytes(), 0.0f);
  for (int mode = 0; mode < 2; ++mode) {
    if (mode == 1) {
      cfg.decodeRadius = 1.0f;
      cfg.keepRadius = 2.0f;
    }
    streaming::StreamingManager m(src, cfg);
    streaming::FrameInput in;
    in.position = glm::vec3(1024.0f - 32.0f, 20.0f, 1024.0f + 32.0f);
    for (int f = 0; f < 30; ++f) m.update(in);
    const glm::ivec2 left(15, 16), right(16, 16);
    double worst = 0.0;
    for (int k = 0; k < 64; ++k) {
      const float z = 1024.0f + float(k) + 0.5f;
      for (float y : {1.0f, 4.0f, 8.0f}) {
        const glm::vec3 n = glm::normalize(glm::vec3(std::sin(float(k)), 1.0f, std::cos(float(k))));
        const glm::vec3 a = m.sample(glm::vec3(1024.0f - 1e-3f, y, z), n).irradiance;
        const glm::vec3 b = m.sample(glm::vec3(1024.0f + 1e-3f, y, z), n).irradiance;
        worst = std::max(worst, std::abs(lum(a) - lum(b)) / std::max(1e-9, 0.5 * (lum(a) + lum(b))));
      }
    }
    const bool resident = m.isResident(right) && m.isResident(left);
    (mode == 0 ? sum.seamResident : sum.seamFallback) = worst;
    c.row("streaming", mode == 0 ? "neighbour_resident" : "neighbour_fallback", 0.0, 8.0,
          resident ? "both" : "one", "-", 12.0, 0.0, "seam_max_rel_diff", worst);
    spdlog::info("streaming seam, {}: largest relative jump across the border {:.4g} (both resident: {})",
                 mode == 0 ? "neighbour resident" : "neighbour not wanted", worst, resident);
  }
}

// Burst: 10x the normal request rate (a teleport to a random far position every frame), then a normal
// flight at 50 m/s; frames until the visible fallback fraction is < 1 % again.
void streamingBurst(Ctx& c, StreamSummary& sum) {
  streaming::SyntheticCellSource src(streamWorld());
  streaming::StreamingConfig cfg = streamConfig(src.maxCellBytes(), 0.5f);
  cfg.memoryBudgetBytes = 24 * src.maxCellBytes();
  streaming::StreamingManager m(src, cfg);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(100.0f, 1948.0f);
  const int burst = c.quick ? 60 : 240;
  glm::vec3 p(0.0f);
  int frame = 0, recovered = -1;
  auto visibleFallback = [&](glm::vec3 cam) {
    int fb = 0, n = 0;
    for (int j = 0; j < 6; ++j)
      for (int i = -3; i < 3; ++i) {
        const streaming::IrradianceSample s =
            m.sample(cam + glm::vec3(10.0f * float(i), -cam.y, 10.0f + 10.0f * float(j)), glm::vec3(0, 1, 0));
        sum.missing += s.missing;
        fb += s.fallbackWeight > 0.01f;
        ++n;
      }
    return double(fb) / double(n);
  };
  for (; frame < burst; ++frame) {
    p = glm::vec3(u(rng), 20.0f, u(rng));
    streaming::FrameInput in;
    in.position = p;
    in.direction = glm::vec3(0, 0, 1);
    in.dtSeconds = 1.0f / 60.0f;
    const streaming::FrameStats st = m.update(in);
    sum.budgetHeld = sum.budgetHeld && st.bytesResident <= cfg.memoryBudgetBytes;
    visibleFallback(p);
  }
  for (int f = 0; f < 600; ++f, ++frame) {
    streaming::FrameInput in;
    in.position = p;
    in.direction = glm::vec3(0, 0, 1);
    in.velocity = glm::vec3(0, 0, 50.0f);
    in.dtSeconds = 1.0f / 60.0f;
    const streaming::FrameStats st = m.update(in);
    sum.budgetHeld = sum.budgetHeld && st.bytesResident <= cfg.memoryBudgetBytes;
    const double fb = visibleFallback(p);
    if (fb < 0.01 && recovered < 0) recovered = f;
    if (fb >= 0.01) recovered = -1;  // must stay recovered
    p += in.velocity * in.dtSeconds;
    if (p.z > 1900.0f) p.z = 100.0f;
  }
  sum.burstRecoveryFrames = recovered;
  c.row("streaming", "burst", 0.0, 8.0, "-", "-", 12.0, 0.0, "burst_frames", double(burst));
  c.row("streaming", "burst", 0.0, 8.0, "-", "-", 12.0, 0.0, "frames_to_recovery", double(recovered));
  c.row("streaming", "burst", 0.0, 8.0, "-", "-", 12.0, 0.0, "budget_held", sum.budgetHeld ? 1.0 : 0.0);
  c.row("streaming", "burst", 0.0, 8.0, "-", "-", 12.0, 0.0, "missing_samples", double(sum.missing));
  spdlog::info(
      "burst: {} teleport frames, then recovery (fallback < 1 %) after {} frames; budget held {}, {} "
      "missing samples",
      burst, recovered, sum.budgetHeld, sum.missing);
}

StreamSummary streamingSection(Ctx& c) {
  StreamSummary sum;
  streamingPops(c, sum);
  streamingSeams(c, sum);
  streamingBurst(c, sum);
  return sum;
}

// ---------------------------------------------------------------------------------------------------------
// Command line and the run of the selected sections.

struct Options {
  std::string out = "out/bench/stability";
  bool quick = false;
  std::string sections = "streaming,leak,unseen,fallback,flicker";
  std::vector<float> walls, spacings;
  int leakSteps = 0;
  bool want(const std::string& name) const {
    return ("," + sections + ",").find("," + name + ",") != std::string::npos;
  }
};

void addOptions(CLI::App& app, Options& opt) {
  app.add_option("--out", opt.out, "Output directory");
  app.add_flag("--quick", opt.quick, "Smaller sweeps (< 5 min on 2 cores)");
  app.add_option("--sections", opt.sections,
                 "Comma-separated sections to run (streaming,leak,unseen,fallback,flicker)");
  app.add_option("--leak-walls", opt.walls,
                 "Wall thicknesses of the leak sweep (m; default 0.05,0.1,0.2,0.5)")
      ->delimiter(',');
  app.add_option("--leak-spacings", opt.spacings,
                 "Probe spacings of the leak sweep (m; default 0.5,1,2; --quick 1,2)")
      ->delimiter(',');
  app.add_option("--leak-steps", opt.leakSteps,
                 "Generator training steps of the leak sweep (default 500; --quick 150)")
      ->check(CLI::Range(1, 100000));
}

void runStreaming(Ctx& c, nlohmann::ordered_json& s) {
  StreamSummary st = streamingSection(c);
  s["seam_max_diff"] = st.seamResident;
  s["seam_max_diff_neighbour_fallback"] = st.seamFallback;
  s["pop_max_rel_change_fade"] = st.popFade;
  s["pop_max_rel_change_no_fade"] = st.popNoFade;
  s["burst_frames_to_recovery"] = st.burstRecoveryFrames;
  s["burst_budget_held"] = st.budgetHeld;
  s["burst_missing_samples"] = st.missing;
}

void runLeak(Ctx& c, const Options& opt, nlohmann::ordered_json& s) {
  std::vector<float> walls = opt.walls, spacings = opt.spacings;
  if (walls.empty()) walls = {0.05f, 0.1f, 0.2f, 0.5f};
  if (spacings.empty())
    spacings = opt.quick ? std::vector<float>{1.0f, 2.0f} : std::vector<float>{0.5f, 1.0f, 2.0f};
  const LeakSummary l = leakSection(c, walls, spacings);
  for (const auto& [m, v] : l.worst) s["leak_ratio_worst_" + m] = v;
  for (const auto& [m, v] : l.worstOff) s["leak_ratio_worst_without_chebyshev_" + m] = v;
}

// The shared cell's scene: t = 0.2 m wall and the 1e-5 interior panel.
LeakScene panelScene() {
  const worlds::SkyModel noon = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
  // Ceiling panel radiance giving the sealed room's probes ~1e-5 of the sunlit room's irradiance
  // (measured: 1e-4 x E_sun gave a ratio of 6.4e3, so 6.4e-6 x E_sun gives ~1e5).
  const float panel = float(6.4e-6 * lum(noon.sun.irradianceNormal()));
  return makeLeakScene(0.2f, glm::vec3(panel));
}

// The shared cell's probes (1 m spacing, relocation on) and their captures at the 3 training keys.
void prepareCell(Ctx& c, CellSetup& cs, const bake::EmbreeScene& scene) {
  cs.grid = leakProbeGrid(cs.scene, 1.0f);
  cs.placement = place(cs.scene, cs.grid, true);
  for (int64_t i = 0; i < cs.grid.probeCount(); ++i)
    if (cs.placement.active[size_t(i)]) {
      cs.idx.push_back(i);
      cs.positions.push_back(cs.grid.probePosition(cs.grid.probeCoord(i)) + cs.placement.offsets[size_t(i)]);
    }
  const bake::LightingKeySpec keys[] = {{8.0f, 0.0f}, {12.0f, 0.0f}, {17.5f, 0.0f}};
  cs.train =
      bake::captureTrainingSet(scene, cs.positions, cs.grid.origin, cs.grid.boxMax(), keys, c.capture());
}

void trainCellGenerator(Ctx& c, CellSetup& cs) {
  const auto t0 = std::chrono::steady_clock::now();
  cs.model = bake::trainGenerator(cs.train, generatorOptions(c.resolution, c.quick ? 300 : 1500));
  spdlog::info("generator on keys 8, 12, 17.5 h: {} probes, {} steps, irradiance rel RMS {:.4f} in {:.1f} s",
               cs.idx.size(), cs.model.report.steps, cs.model.report.irradianceRelativeRms, seconds(t0));
  c.row("unseen", "generator", 0.2, 1.0, "trained", "-", -1.0, 0.0, "train_irr_rel_rms",
        cs.model.report.irradianceRelativeRms);
}

// The sections on the shared cell: t = 0.2 m, 1 m spacing, relocation on, 1e-5 interior panel, generator on
// 3 keys.
void runCellSections(Ctx& c, const Options& opt, nlohmann::ordered_json& s) {
  CellSetup cs;
  cs.scene = panelScene();
  const bake::EmbreeScene scene(cs.scene.mesh, "unseen-lighting scene");
  prepareCell(c, cs, scene);
  if (opt.want("unseen") || opt.want("flicker")) trainCellGenerator(c, cs);
  if (opt.want("unseen")) {
    const UnseenSummary un = unseenSection(c, cs, scene);
    s["unseen_time_irr_rel_rms"] = un.betweenRelRms;  // times between the keys (10, 15 h)
    for (const auto& [k, v] : un.generator) s["unseen_irr_rel_rms_" + k] = v;
    for (const auto& [k, v] : un.vir) s["unseen_vir_relight_irr_rel_rms_" + k] = v;
    s["train_irr_rel_rms"] = cs.model.report.irradianceRelativeRms;
    s["nonfinite_decoded_values"] = un.nonFiniteValues;
  }
  if (opt.want("fallback")) fallbackSection(c, cs);
  if (opt.want("flicker")) {
    bake::ShadingRenderer renderer(c.gpu, cs.scene.mesh);
    s["max_flicker"] = flickerSection(c, cs, scene, renderer);
  }
}

void run(const Options& opt) {
  const auto start = std::chrono::steady_clock::now();
  bench::BenchOutput o(opt.out, opt.quick);
  auto gpuCtx = gpu::createContext();
  o.setDevice(gpuCtx->info.name);
  o.setColumns({"section", "method", "wall_m", "spacing_m", "probe_setup", "chebyshev", "time_h", "overcast",
                "metric", "value"});
  Ctx c{o, *gpuCtx, opt.quick, 8, opt.quick ? 4 : 16, opt.leakSteps};
  auto& s = o.summary();
  // Keys of the bad-input and interruption parts (docs/ARCHITECTURE.md "Bad input and interruption") are
  // measured by their own tests.
  s["readers_inputs_tried"] = nullptr;
  s["readers_crashes"] = nullptr;
  s["readers_unclear_errors"] = nullptr;
  s["resume_hash_equal"] = nullptr;
  if (opt.want("streaming")) runStreaming(c, s);
  if (opt.want("leak")) runLeak(c, opt, s);
  if (opt.want("unseen") || opt.want("fallback") || opt.want("flicker")) runCellSections(c, opt, s);
  s["seconds"] = seconds(start);
  o.save();
  std::filesystem::copy_file(std::filesystem::path(opt.out) / "results.csv",
                             std::filesystem::path(opt.out) / "stability.csv",
                             std::filesystem::copy_options::overwrite_existing);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "lfgi benchmark: failure modes (leaks, unseen lighting, generator fallback, flicker, streaming)"};
  Options opt;
  addOptions(app, opt);
  CLI11_PARSE(app, argc, argv);
  try {
    run(opt);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
