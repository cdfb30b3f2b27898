// `lfgi bake --codec shared` end to end on the tiny world (bake/world_bake.h ensureSharedModel + bakeCell,
// core/shared_model.h, cell file version 3) and streamed back through streaming::CellFileSource.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "bake/embree_scene.h"
#include "bake/world_bake.h"
#include "core/error.h"
#include "core/generator_cpu.h"
#include "core/metrics.h"
#include "streaming/cell_file_source.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {
namespace {

namespace fs = std::filesystem;

// The tiny settings of the other world-bake tests (resolution 8, 2 spp, 1 bounce, 40 steps), two lighting
// keys (the conditioning must carry the time of day) and a target no SH L1 meets (cells train).
WorldBakeSettings tinySharedSettings() {
  WorldBakeSettings s;
  s.resolution = 8;
  s.spp = 2;
  s.bounces = 1;
  s.maxSteps = 40;
  s.keys = "8,17.5";
  s.errorTarget = 0.001;
  s.codec = "shared";
  s.sharedSteps = 60;
  return s;
}

// The bake's training set of a cell, captured again (capture is deterministic per probe seed).
GeneratorTrainingSet recapture(const worlds::SyntheticWorld& world, worlds::CellCoord c,
                               const WorldBakeSettings& s) {
  CellBakeInputs in = prepareCellBake(world, c, s);
  std::vector<glm::vec3> positions;
  for (size_t i = 0; i < in.built.probes.flags.size(); ++i)
    if (!(in.built.probes.flags[i] & worlds::kProbeDisabledSolid))
      positions.push_back(in.built.probes.position(int64_t(i)));
  const EmbreeScene scene(std::move(in.sceneMesh), "recapture");
  return captureTrainingSet(scene, positions, in.built.probes.grid.origin, in.built.probes.grid.boxMax(),
                            parseLightingKeys(s.keys), worldBakeCaptureOptions(world, s));
}

struct SharedWorld {
  fs::path dir;
  SharedModel model;
  ResolvedSharedModel resolved;
  std::vector<worlds::CellCoord> networkCells;
};

// Bakes the tiny world once per process (every test here, when one binary runs them all). The directory is
// named after the first test that asks for it: ctest runs each test in its own process, in parallel, and
// processes sharing one directory would delete each other's files.
const SharedWorld& sharedWorld() {
  static const SharedWorld w = [] {
    SharedWorld r;
    const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
    const WorldBakeSettings s = tinySharedSettings();
    const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
    r.dir = fs::path(LFGI_TEST_TMP_DIR) / (std::string("shared_codec_bake_") + (test ? test->name() : "all"));
    fs::remove_all(r.dir);
    fs::create_directories(r.dir / "baked" / "cells");
    worlds::writeWorldManifest(r.dir, world.params());
    bool reused = true;
    r.model = ensureSharedModel(world, s, r.dir / "baked", &reused);
    EXPECT_FALSE(reused);
    r.resolved = loadSharedModel(sharedModelPath(r.dir / "baked"));
    EXPECT_EQ(r.resolved.hash, r.model.weightsHash());
    for (int z = 0; z < world.cellsZ(); ++z)
      for (int x = 0; x < world.cellsX(); ++x) {
        const worlds::CellCoord c{x, z};
        const CellFile cf =
            bakeCell(world, prepareCellBake(world, c, s, r.resolved.hash), s, nullptr, &r.resolved);
        writeCellFile(cellFilePath(r.dir / "baked", c), cf);
        if (cf.generator) r.networkCells.push_back(c);
      }
    return r;
  }();
  return w;
}

TEST(SharedCodecBake, SharedModelIsReusedAndEntersTheInputHash) {
  const SharedWorld& w = sharedWorld();
  const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
  WorldBakeSettings s = tinySharedSettings();
  bool reused = false;
  const SharedModel again = ensureSharedModel(world, s, w.dir / "baked", &reused);
  EXPECT_TRUE(reused);
  EXPECT_EQ(again.weightsHash(), w.resolved.hash);
  EXPECT_EQ(currentSharedModelHash(world, s, w.dir / "baked"), w.resolved.hash);
  std::printf("[ measure  ] shared model: %d steps on %s, mean irradiance rel RMS %.4f, %zu weight bytes\n",
              again.stats.steps, again.stats.cells.c_str(), again.stats.errorAchieved, again.weights.bytes());
  // Codec and shared model hash are bake inputs: switching either changes every cell's hash.
  const worlds::CellCoord c{1, 0};
  const uint64_t shared = cellInputHash(world, c, s, w.resolved.hash);
  EXPECT_NE(shared, cellInputHash(world, c, s, w.resolved.hash ^ 1));
  s.codec = "per-cell";
  EXPECT_NE(shared, cellInputHash(world, c, s));
  EXPECT_EQ(currentSharedModelHash(world, s, w.dir / "baked"), 0u);
  // Other pre-training settings: the file no longer matches.
  s = tinySharedSettings();
  s.sharedSteps = 61;
  EXPECT_EQ(currentSharedModelHash(world, s, w.dir / "baked"), 0u);
}

TEST(SharedCodecBake, CellsDecodeThroughCellFileSourceAsTheAdapterFoldedByHand) {
  const SharedWorld& w = sharedWorld();
  ASSERT_FALSE(w.networkCells.empty()) << "the tiny world's target should need a network somewhere";
  const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
  streaming::CellFileSourceOptions o;
  o.worldDir = w.dir;
  streaming::CellFileSource source(o);
  EXPECT_EQ(source.validCells(), 4);
  const GeneratorWeights shared = dequantizeWeights(w.model.weights);
  for (const worlds::CellCoord c : w.networkCells) {
    const fs::path path = cellFilePath(w.dir / "baked", c);
    CellFileBytes parts;
    const CellFile cf = readCellFile(path, &parts);
    ASSERT_TRUE(cf.generator && cf.generator->shared);
    EXPECT_EQ(parts.version, 3);
    EXPECT_EQ(parts.weights, 0u);
    EXPECT_EQ(cf.generator->shared->modelHash, w.resolved.hash);
    const glm::ivec2 cell{c.x, c.z};
    const GeneratorTrainingSet set = recapture(world, c, tinySharedSettings());
    const int n = cf.generator->weights.arch.outputResolution();
    const size_t tn3 = size_t(n * n * 3);
    // By hand: the shared floats with the cell's adapter folded in, through the CPU decoder.
    GeneratorCpu byHand(applyAdapter(shared, dequantizeAdapter(cf.generator->shared->adapter)));
    const std::vector<float> latents = dequantizeLatents(cf.generator->latents);
    std::vector<std::vector<float>> decoded;
    double maxDiff = 0.0, maxValue = 0.0;
    for (const LightingKey& key : set.keys) {
      source.setTimeOfDay(key.timeOfDayHours);
      ProbeField streamed;
      source.load(cell, streamed);
      ProbeField dense;
      dense.grid.dims = {int(cf.activeProbeCount()), 1, 1};
      dense.resolution = n;
      dense.irradianceResolution = std::max(2, n / 2);
      const auto cond = conditioningVector(key.timeOfDayHours, key.weather);
      decodeProbeField(byHand, latents, cond, cf.outputScale, dense);
      std::vector<float> active;
      size_t k = 0;
      for (int64_t i = 0; i < streamed.probeCount(); ++i) {
        if (!streamed.isActive(i)) continue;
        for (size_t t = 0; t < tn3; ++t) {
          const float a = streamed.radiance[size_t(i) * tn3 + t],
                      b = std::max(0.0f, dense.radiance[k * tn3 + t]);
          maxDiff = std::max(maxDiff, double(std::abs(a - b)));
          maxValue = std::max(maxValue, double(std::abs(b)));
          active.push_back(a);
        }
        ++k;
      }
      ASSERT_EQ(k, size_t(cf.activeProbeCount()));
      decoded.push_back(std::move(active));
    }
    const double e = codecError(set, decoded).irradianceRelativeRms;
    std::printf(
        "[ measure  ] cell %d,%d (%s): %zu B (adapter %zu, latents %zu); streamed vs folded by hand max "
        "|diff| %.3g of %.3g; irradiance rel RMS %.4f (stored %.4f)\n",
        c.x, c.z, cf.stats.model.c_str(), parts.total, parts.adapter, parts.latents, maxDiff, maxValue, e,
        cf.stats.errorAchieved);
    EXPECT_LE(maxDiff, 1e-5 * maxValue + 1e-7);
    EXPECT_GT(cf.stats.errorAchieved, 0.0);
    EXPECT_LE(e, cf.stats.errorAchieved * 1.02 + 1e-3);
  }
}

TEST(SharedCodecBake, MissingOrOtherSharedModelNamesBothFiles) {
  const SharedWorld& w = sharedWorld();
  ASSERT_FALSE(w.networkCells.empty());
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "shared_codec_bake_missing";
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::copy(w.dir, dir, fs::copy_options::recursive);
  const fs::path model = sharedModelPath(dir / "baked");
  fs::remove(model);
  const worlds::CellCoord c = w.networkCells.front();
  // One cell without a network, so the source has a valid cell (with none it refuses the directory).
  const worlds::CellCoord plainCell =
      c.x == 0 && c.z == 0 ? worlds::CellCoord{1, 1} : worlds::CellCoord{0, 0};
  CellFile plain = readCellFile(cellFilePath(dir / "baked", plainCell));
  plain.generator.reset();
  writeCellFile(cellFilePath(dir / "baked", plainCell), plain);
  const glm::ivec2 cell{c.x, c.z};
  const std::string cellPath = cellFilePath(dir / "baked", c).string();
  streaming::CellFileSourceOptions o;
  o.worldDir = dir;
  {
    streaming::CellFileSource source(o);
    const std::string& e = source.info(cell).error;
    std::printf("missing: %s\n", e.c_str());
    EXPECT_EQ(source.info(cell).state, streaming::CellFileState::Corrupt);
    EXPECT_NE(e.find(cellPath), std::string::npos) << e;
    EXPECT_NE(e.find(model.string() + ": no shared model file"), std::string::npos) << e;
    ProbeField f;
    EXPECT_THROW(source.load(cell, f), Error);
  }
  // Another world's model under the same name: the hash check names both files.
  SharedModel other = w.model;
  other.weights.tensors[1].f32[0] += 1.0f;  // the linear bias (float32 in int8 mode)
  writeSharedModel(model, other);
  streaming::CellFileSource source(o);
  const std::string& e = source.info(cell).error;
  std::printf("other: %s\n", e.c_str());
  EXPECT_EQ(source.info(cell).state, streaming::CellFileState::Corrupt);
  EXPECT_NE(e.find(cellPath + ": refers to shared model"), std::string::npos) << e;
  EXPECT_NE(e.find("but " + model.string() + " holds"), std::string::npos) << e;
}

}  // namespace
}  // namespace lfgi::bake
