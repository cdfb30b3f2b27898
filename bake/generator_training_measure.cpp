// Developer measurement of the generator training (not a test, not built by default):
//   lfgi_generator_training_measure [SCENES_DIR] [--quick] [--threads N] [--steps N] [--probes N] [--spp N]
//   [--sizing-steps N]
// Captures a city cell and a field cell of WorldParams::smallDefault(1) under four lighting keys and the
// Cornell box under one, then trains per scene: stored latents without and with the adversarial term,
// position latents, and the automatic model sizing at a 5 % irradiance target. Prints one table row per
// run: irradiance relative RMS and radiance PSNR vs the captures, parameters, FP32 bytes, seconds.
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "bake/generator_training.h"
#include "worlds/gltf_io.h"
#include "worlds/probe_placement.h"
#include "worlds/world_cells.h"

using namespace lfgi;
using namespace lfgi::bake;

namespace {

struct Scene {
  std::string name;
  GeneratorTrainingSet set;
  std::vector<uint8_t> flags;
};

void row(const std::string& scene, const std::string& run, const std::string& model, size_t params,
         size_t bytes, size_t probes, double irr, double psnr, double seconds, int steps) {
  std::printf("%-12s %-22s %-26s %8zu %9zu %8.0f %8.4f %7.1f %8.1f %6d\n", scene.c_str(), run.c_str(),
              model.c_str(), params, bytes, double(bytes) / double(probes), irr, psnr, seconds, steps);
  std::fflush(stdout);
}

std::string archName(const GeneratorArch& a) {
  std::string s = a.latentSource == LatentSource::Stored ? "z" + std::to_string(a.latentDim)
                                                         : "pos" + std::to_string(a.fourierOctaves);
  s += " C";
  for (size_t i = 0; i + 1 < a.convChannels.size(); ++i)
    s += (i ? "-" : "") + std::to_string(a.convChannels[i]);
  return s;
}

Scene syntheticCell(worlds::CellKind kind, const CaptureOptions& co, size_t maxProbes, bool quick) {
  const worlds::SyntheticWorld world(worlds::WorldParams::smallDefault(1));
  worlds::CellCoord cell{-1, -1};
  for (int z = 0; z < world.cellsZ() && cell.x < 0; ++z)
    for (int x = 0; x < world.cellsX() && cell.x < 0; ++x)
      if (world.cellKind({x, z}) == kind) cell = {x, z};
  worlds::BuiltCell built = worlds::buildCell(world, cell);
  std::vector<size_t> usable;
  for (size_t i = 0; i < built.probes.flags.size(); ++i)
    if (!(built.probes.flags[i] & worlds::kProbeDisabledSolid)) usable.push_back(i);
  const size_t stride = std::max<size_t>(1, usable.size() / maxProbes);
  Scene s;
  s.name =
      std::string(worlds::cellKindName(kind)) + "_" + std::to_string(cell.x) + "_" + std::to_string(cell.z);
  std::vector<glm::vec3> positions;
  for (size_t k = 0; k < usable.size() && positions.size() < maxProbes; k += stride) {
    positions.push_back(built.probes.position(int64_t(usable[k])));
    s.flags.push_back(built.probes.flags[usable[k]]);
  }
  const ProbeGrid& g = built.probes.grid;
  const glm::vec3 lo = g.origin, hi = g.origin + glm::vec3(g.dims - 1) * g.spacing;
  const EmbreeScene scene(std::move(built.mesh), s.name);
  std::vector<LightingKeySpec> keys = {{8.0f, 0.0f}, {12.0f, 0.0f}, {17.0f, 0.0f}, {12.0f, 0.7f}};
  if (quick) keys.resize(2);
  const auto t0 = std::chrono::steady_clock::now();
  s.set = captureTrainingSet(scene, positions, lo, hi, keys, co);
  std::fprintf(stderr, "%s: %zu probes x %zu keys captured in %.1f s\n", s.name.c_str(), positions.size(),
               keys.size(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return s;
}

Scene cornell(const std::string& scenesDir, const CaptureOptions& co) {
  worlds::ScenePreset preset = worlds::findScenePreset("cornell");
  preset.probeDims = glm::ivec3(3);
  worlds::TriangleMesh mesh = worlds::loadScenePreset(preset, scenesDir);
  const ProbeGrid g = worlds::presetProbeGrid(preset, mesh.bounds());
  std::vector<glm::vec3> positions;
  for (int64_t i = 0; i < g.probeCount(); ++i) positions.push_back(g.probePosition(g.probeCoord(i)));
  const glm::vec3 lo = g.origin, hi = g.origin + glm::vec3(g.dims - 1) * g.spacing;
  const EmbreeScene scene(std::move(mesh), "cornell");
  const std::vector<LightingKeySpec> keys = {{12.0f, 0.0f}};
  Scene s;
  s.name = "cornell";
  s.set = captureTrainingSet(scene, positions, lo, hi, keys, co);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scenesDir = worlds::defaultScenesDir().string();
  bool quick = false;
  int threads = 1, steps = 0, probes = 0, spp = 0, sizingSteps = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return i + 1 < argc ? std::stoi(argv[++i]) : 0; };
    if (a == "--quick")
      quick = true;
    else if (a == "--threads")
      threads = next();
    else if (a == "--steps")
      steps = next();
    else if (a == "--probes")
      probes = next();
    else if (a == "--spp")
      spp = next();
    else if (a == "--sizing-steps")
      sizingSteps = next();
    else
      scenesDir = a;
  }
  if (steps <= 0) steps = quick ? 300 : 1500;
  if (probes <= 0) probes = quick ? 16 : 48;
  if (spp <= 0) spp = quick ? 4 : 16;
  if (sizingSteps <= 0) sizingSteps = steps;
  try {
    CaptureOptions co;
    co.resolution = 16;
    co.irradianceResolution = 8;
    co.samplesPerTexel = spp;
    co.maxBounces = 3;
    std::vector<Scene> scenes;
    scenes.push_back(syntheticCell(worlds::CellKind::kCity, co, size_t(probes), quick));
    scenes.push_back(syntheticCell(worlds::CellKind::kField, co, size_t(probes), quick));
    scenes.push_back(cornell(scenesDir, co));

    GeneratorTrainingOptions base;
    base.arch.latentDim = 8;
    base.arch.convChannels = {32, 16, kGeneratorChannels};
    base.maxSteps = steps;
    base.evalEvery = 100;
    base.irradianceErrorTarget = 0.0;  // fixed budget: compare options at equal steps
    base.threads = threads;
    base.batchSize = 64;
    std::printf("%-12s %-22s %-26s %8s %9s %8s %8s %7s %8s %6s\n", "scene", "run", "model", "params", "bytes",
                "B/probe", "irrRMS", "PSNRdB", "seconds", "steps");
    for (const Scene& s : scenes) {
      const size_t P = s.set.probeCount();
      struct Run {
        std::string name;
        GeneratorTrainingOptions o;
      };
      std::vector<Run> runs;
      runs.push_back({"stored", base});
      runs.push_back({"stored+gan", base});
      runs.back().o.adversarial = true;
      runs.push_back({"position", base});
      runs.back().o.arch.latentSource = LatentSource::PositionFourier;
      runs.back().o.arch.fourierOctaves = 3;
      runs.back().o.arch.latentDim = 18;
      for (const Run& r : runs) {
        const TrainedGenerator g = trainGenerator(s.set, r.o);
        row(s.name, r.name, archName(r.o.arch), r.o.arch.parameterCount(), generatorBytes(r.o.arch, P), P,
            g.report.irradianceRelativeRms, g.report.radiancePsnrDb, g.report.seconds, g.report.steps);
      }
      ModelSizingOptions so;
      so.irradianceErrorTarget = 0.05;
      so.training = base;
      so.training.maxSteps = sizingSteps;
      const CellModelChoice c = chooseCellModel(s.set, s.flags, so);
      for (const SizingAttempt& a : c.attempts)
        row(s.name, "  sizing try",
            a.kind == CellModelKind::kGenerator ? archName(a.arch) : std::string(cellModelKindName(a.kind)),
            a.kind == CellModelKind::kGenerator ? a.arch.parameterCount() : 0, a.bytes, P,
            a.irradianceRelativeRms, 0.0, a.seconds, a.steps);
      row(s.name, c.reachedTarget ? "sizing: chosen" : "sizing: best (missed)",
          c.generator ? archName(c.generator->weights.arch) : std::string(cellModelKindName(c.kind)),
          c.parameterCount, c.bytes, P, c.error.irradianceRelativeRms, c.error.radiancePsnrDb,
          c.trainingSeconds, c.generator ? c.generator->report.steps : 0);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
