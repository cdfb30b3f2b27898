#include "bake/generator_training.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "core/error.h"
#include "worlds/probe_placement.h"

namespace lfgi::bake {
namespace {

// A tiny outdoor cell: ground, one building, eight probes around it, captured at 8 x 8 under two times
// of day (cheap: 4 spp, 1 bounce).
struct TinyCell {
  std::vector<glm::vec3> positions;
  GeneratorTrainingSet set;
};

const TinyCell& tinyCell() {
  static const TinyCell cell = [] {
    TinyCell c;
    worlds::TriangleMesh mesh;
    worlds::Material ground, wall;
    ground.albedo = glm::vec3(0.3f, 0.25f, 0.2f);
    wall.albedo = glm::vec3(0.7f, 0.6f, 0.5f);
    const uint32_t g = mesh.addMaterial(ground), w = mesh.addMaterial(wall);
    mesh.addBox(glm::vec3(-30.0f, -1.0f, -30.0f), glm::vec3(30.0f, 0.0f, 30.0f), g);
    mesh.addBox(glm::vec3(-2.0f, 0.0f, -2.0f), glm::vec3(2.0f, 6.0f, 2.0f), w);
    const EmbreeScene scene(std::move(mesh), "tiny cell");
    for (float x : {-4.0f, 4.0f})
      for (float z : {-4.0f, 4.0f})
        for (float y : {1.0f, 4.0f}) c.positions.push_back(glm::vec3(x, y, z));
    CaptureOptions o;
    o.resolution = 8;
    o.irradianceResolution = 4;
    o.samplesPerTexel = 4;
    o.maxBounces = 1;
    const LightingKeySpec keys[] = {{9.0f, 0.0f}, {15.0f, 0.3f}};
    c.set = captureTrainingSet(scene, c.positions, glm::vec3(-4.0f, 1.0f, -4.0f), glm::vec3(4.0f, 4.0f, 4.0f),
                               keys, o);
    return c;
  }();
  return cell;
}

GeneratorTrainingOptions tinyOptions() {
  GeneratorTrainingOptions o;
  o.arch.latentDim = 4;
  o.arch.convChannels = {16, kGeneratorChannels};  // 8 x 8 output
  o.maxSteps = 60;
  o.evalEvery = 20;
  o.irradianceErrorTarget = 0.0;  // never reached: runs all steps
  o.threads = 1;
  return o;
}

std::filesystem::path tmpDir() {
  std::filesystem::path d = std::filesystem::path(LFGI_TEST_TMP_DIR) / "generator_training";
  std::filesystem::create_directories(d);
  return d;
}

bool sameWeights(const TrainedGenerator& a, const TrainedGenerator& b) {
  if (a.weights.linearWeight != b.weights.linearWeight || a.weights.linearBias != b.weights.linearBias ||
      a.latents != b.latents || a.weights.convWeight != b.weights.convWeight ||
      a.weights.convBias != b.weights.convBias)
    return false;
  return a.scale.exposure == b.scale.exposure && a.scale.range == b.scale.range;
}

// The CPU reference decoder (core/generator.cpp) must be PyTorch's network: random weights of two
// architectures (depth 2 and 3, with and without conditioning) through both. Tolerance: float sums in a
// different order, |diff| <= 1e-5 x (1 + max |y|) (measured ~1e-7 relative).
TEST(GeneratorTraining, CpuReferenceMatchesLibtorchForward) {
  std::mt19937 rng(7);
  std::normal_distribution<float> nd(0.0f, 1.0f);
  for (int variant = 0; variant < 2; ++variant) {
    GeneratorWeights w;
    w.arch.latentDim = variant == 0 ? 5 : 12;
    w.arch.condDim = variant == 0 ? kConditioningDim : 0;
    w.arch.convChannels = variant == 0 ? std::vector<int>{12, 7, kGeneratorChannels}
                                       : std::vector<int>{9, 6, 5, kGeneratorChannels};
    const GeneratorArch& a = w.arch;
    auto fill = [&](size_t count, float scale) {
      std::vector<float> v(count);
      for (float& x : v) x = scale * nd(rng);
      return v;
    };
    const size_t c0 = size_t(a.convChannels[0]);
    w.linearWeight = fill(16 * c0 * size_t(a.inputDim()), 0.5f);
    w.linearBias = fill(16 * c0, 0.2f);
    for (int i = 0; i < a.layers(); ++i) {
      const size_t ci = size_t(a.convChannels[size_t(i)]), co = size_t(a.convChannels[size_t(i) + 1]);
      w.convWeight.push_back(fill(ci * co * 16, 0.3f));
      w.convBias.push_back(fill(co, 0.1f));
    }
    const size_t count = 3;
    const std::vector<float> z = fill(count * size_t(a.latentDim), 1.0f);
    const auto c = conditioningVector(17.5f, 0.4f);
    const std::span<const float> cond(c.data(), size_t(a.condDim));
    const std::vector<float> ref = torchGeneratorForward(w, z, cond, count);
    std::vector<float> cpu(ref.size());
    generatorForward(w, z, cond, count, cpu);
    double maxAbs = 0.0, maxDiff = 0.0;
    size_t nonZero = 0;
    for (size_t i = 0; i < ref.size(); ++i) {
      maxAbs = std::max(maxAbs, double(std::abs(ref[i])));
      maxDiff = std::max(maxDiff, double(std::abs(ref[i] - cpu[i])));
      nonZero += ref[i] != 0.0f;
    }
    std::printf("variant %d: %zu outputs, max |y| %.3f, max |cpu - torch| %.3g\n", variant, ref.size(),
                maxAbs, maxDiff);
    EXPECT_GT(nonZero, ref.size() / 2);  // the comparison is not between two zero maps
    EXPECT_LE(maxDiff, 1e-5 * (1.0 + maxAbs));
  }
}

TEST(GeneratorTraining, TrainingBeatsTheCellConstantAndExportsAValidModel) {
  const GeneratorTrainingSet& set = tinyCell().set;
  GeneratorTrainingOptions o = tinyOptions();
  o.maxSteps = 400;
  o.evalEvery = 100;
  const TrainedGenerator g = trainGenerator(set, o);
  EXPECT_NO_THROW(g.weights.validate());
  EXPECT_EQ(g.latents.size(), set.probeCount() * 4);
  EXPECT_EQ(g.report.steps, 400);
  ModelSizingOptions so;
  so.irradianceErrorTarget = 0.0;
  so.candidates = {o.arch};
  so.training = o;
  so.training.maxSteps = 1;
  const CellModelChoice none = chooseCellModel(set, {}, so);
  ASSERT_GE(none.attempts.size(), 3u);
  const double constantError = none.attempts[0].irradianceRelativeRms;
  std::printf(
      "tiny cell: trained %d steps in %.2f s: irradiance rel RMS %.4f, radiance rel RMS %.4f, PSNR %.1f dB; "
      "cell constant %.4f, SH L1 %.4f, SH L2 %.4f\n",
      g.report.steps, g.report.seconds, g.report.irradianceRelativeRms, g.report.radianceRelativeRms,
      g.report.radiancePsnrDb, constantError, none.attempts[1].irradianceRelativeRms,
      none.attempts[2].irradianceRelativeRms);
  EXPECT_LT(g.report.irradianceRelativeRms, 0.5 * constantError);
  // The stop metric, measured again independently of the report.
  EXPECT_DOUBLE_EQ(evaluateGenerator(g, set).irradianceRelativeRms, g.report.irradianceRelativeRms);
}

TEST(GeneratorTraining, StopsAtTheErrorTarget) {
  GeneratorTrainingOptions o = tinyOptions();
  o.maxSteps = 2000;
  o.evalEvery = 10;
  o.irradianceErrorTarget = 0.5;
  const TrainedGenerator g = trainGenerator(tinyCell().set, o);
  EXPECT_TRUE(g.report.reachedTarget);
  EXPECT_LT(g.report.steps, 2000);
  EXPECT_EQ(g.report.steps % 10, 0);
  EXPECT_LE(g.report.irradianceRelativeRms, 0.5);
}

TEST(GeneratorTraining, SameSeedIsBitIdenticalAndOtherSeedsDiffer) {
  const GeneratorTrainingSet& set = tinyCell().set;
  GeneratorTrainingOptions o = tinyOptions();
  const TrainedGenerator a = trainGenerator(set, o);
  const TrainedGenerator b = trainGenerator(set, o);
  EXPECT_TRUE(sameWeights(a, b));
  o.seed = 2;
  const TrainedGenerator c = trainGenerator(set, o);
  EXPECT_FALSE(sameWeights(a, c));
}

// Interrupted at step 25 (checkpoint), resumed to 60: bit-identical to 60 uninterrupted steps, with the
// adversarial term on (so the discriminator and its optimiser are part of the checkpoint) and
// minibatches (so the batch schedule is too).
TEST(GeneratorTraining, ResumedRunEndsBitIdenticalToAnUninterruptedOne) {
  const GeneratorTrainingSet& set = tinyCell().set;
  GeneratorTrainingOptions o = tinyOptions();
  o.adversarial = true;
  o.batchSize = 6;
  const TrainedGenerator whole = trainGenerator(set, o);
  const std::filesystem::path ckpt = tmpDir() / "resume.ckpt";
  std::filesystem::remove(ckpt);
  o.checkpoint = ckpt;
  o.checkpointEvery = 10;
  o.stopAfterSteps = 25;
  const TrainedGenerator first = trainGenerator(set, o);
  EXPECT_TRUE(first.report.interrupted);
  EXPECT_EQ(first.report.steps, 25);
  ASSERT_TRUE(std::filesystem::exists(ckpt));
  o.stopAfterSteps = 0;
  const TrainedGenerator resumed = trainGenerator(set, o);
  EXPECT_EQ(resumed.report.resumedFromStep, 25);
  EXPECT_EQ(resumed.report.steps, 60);
  EXPECT_FALSE(resumed.report.interrupted);
  EXPECT_TRUE(sameWeights(whole, resumed));
  EXPECT_FALSE(std::filesystem::exists(ckpt));  // a finished run leaves nothing to resume
}

// A model search interrupted twice (stopAfterSteps stands in for Ctrl-C) and rerun each time: finished
// candidates come back from their kept checkpoints without training, the interrupted one resumes, and the
// choice is the uninterrupted search's, bit for bit.
TEST(GeneratorTraining, SizingResumesItsSearchFromCheckpoints) {
  ModelSizingOptions so;
  so.irradianceErrorTarget = 1e-6;  // never met: both candidates train all 60 steps
  so.noNetworkKinds = {};           // generators only: the best of the two is the choice
  so.training = tinyOptions();
  GeneratorArch small = tinyOptions().arch, big = small;
  small.convChannels = {8, kGeneratorChannels};
  so.candidates = {small, big};
  const CellModelChoice whole = chooseCellModel(tinyCell().set, {}, so);
  const std::filesystem::path prefix = tmpDir() / "search.train";
  for (int i = 0; i < 2; ++i) std::filesystem::remove(prefix.string() + ".candidate" + std::to_string(i));
  so.training.checkpoint = prefix;
  so.training.keepFinishedCheckpoint = true;
  so.training.stopAfterSteps = 40;
  std::vector<CellModelChoice> runs;
  for (int run = 0; run < 3; ++run) runs.push_back(chooseCellModel(tinyCell().set, {}, so));
  // Run 1: candidate 0 stops at 40. Run 2: it resumes to 60, candidate 1 stops at 40. Run 3: candidate 0
  // is its kept final state (resumed at 60, no step), candidate 1 resumes to 60.
  ASSERT_EQ(runs[0].attempts.size(), 1u);
  ASSERT_EQ(runs[1].attempts.size(), 2u);
  ASSERT_EQ(runs[2].attempts.size(), 2u);
  EXPECT_EQ(runs[0].attempts[0].steps, 40);
  EXPECT_EQ(runs[1].attempts[0].resumedFromStep, 40);
  EXPECT_EQ(runs[1].attempts[1].steps, 40);
  EXPECT_EQ(runs[2].attempts[0].resumedFromStep, 60);
  EXPECT_EQ(runs[2].attempts[1].resumedFromStep, 40);
  EXPECT_EQ(runs[2].attempts[1].steps, 60);
  const CellModelChoice& last = runs[2];
  ASSERT_TRUE(last.generator && whole.generator);
  EXPECT_TRUE(sameWeights(*whole.generator, *last.generator));
  EXPECT_EQ(whole.error.irradianceRelativeRms, last.error.irradianceRelativeRms);
  for (size_t i = 0; i < whole.attempts.size(); ++i)
    EXPECT_EQ(whole.attempts[i].irradianceRelativeRms, last.attempts[i].irradianceRelativeRms) << i;
  for (int i = 0; i < 2; ++i)  // kept for the caller to remove once the cell is written
    EXPECT_TRUE(std::filesystem::exists(prefix.string() + ".candidate" + std::to_string(i))) << i;
}

TEST(GeneratorTraining, CheckpointOfOtherOptionsIsRefused) {
  const GeneratorTrainingSet& set = tinyCell().set;
  GeneratorTrainingOptions o = tinyOptions();
  o.checkpoint = tmpDir() / "other.ckpt";
  std::filesystem::remove(o.checkpoint);
  o.stopAfterSteps = 5;
  trainGenerator(set, o);
  o.stopAfterSteps = 0;
  o.learningRate *= 2.0f;
  try {
    trainGenerator(set, o);
    FAIL() << "expected lfgi::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("other.ckpt: checkpoint of other training data or options"),
              std::string::npos)
        << e.what();
  }
  std::filesystem::remove(o.checkpoint);
}

TEST(GeneratorTraining, PositionLatentsStoreNothingAndDecode) {
  const GeneratorTrainingSet& set = tinyCell().set;
  GeneratorTrainingOptions o = tinyOptions();
  o.arch.latentSource = LatentSource::PositionFourier;
  o.arch.fourierOctaves = 2;
  o.arch.latentDim = 12;
  o.maxSteps = 200;
  const TrainedGenerator g = trainGenerator(set, o);
  EXPECT_TRUE(g.latents.empty());
  EXPECT_EQ(g.decoderLatents(set).size(), set.probeCount() * 12);
  EXPECT_TRUE(std::isfinite(g.report.irradianceRelativeRms));
  EXPECT_LT(g.report.irradianceRelativeRms, 1.0);
  std::printf("position latents, 200 steps: irradiance rel RMS %.4f\n", g.report.irradianceRelativeRms);
}

TEST(GeneratorTraining, BadOptionsAreErrors) {
  const GeneratorTrainingSet& set = tinyCell().set;
  GeneratorTrainingOptions o = tinyOptions();
  o.arch.convChannels = {16, 8, kGeneratorChannels};  // 16 x 16 output for 8 x 8 captures
  EXPECT_THROW(trainGenerator(set, o), Error);
  o = tinyOptions();
  o.maxSteps = 0;
  EXPECT_THROW(trainGenerator(set, o), Error);
  GeneratorTrainingSet broken = set;
  broken.keys[1].probes.pop_back();
  EXPECT_THROW(trainGenerator(broken, tinyOptions()), Error);
}

// An all-sky cell (ground only, every probe flagged kProbeSkyOnly) gets no network, even with a target
// no model could reach; a cell with geometry and an unreachable target tries the generator candidates
// cheapest first and keeps the best.
TEST(GeneratorTraining, SizingGivesAnAllSkyCellNoNetwork) {
  worlds::TriangleMesh mesh;
  worlds::Material ground;
  ground.albedo = glm::vec3(0.3f);
  mesh.addBox(glm::vec3(-50.0f, -1.0f, -50.0f), glm::vec3(50.0f, 0.0f, 50.0f), mesh.addMaterial(ground));
  const EmbreeScene scene(std::move(mesh), "sky cell");
  std::vector<glm::vec3> positions;
  for (float x : {-8.0f, 8.0f})
    for (float z : {-8.0f, 8.0f}) positions.push_back(glm::vec3(x, 2.0f, z));
  CaptureOptions co;
  co.resolution = 8;
  co.irradianceResolution = 4;
  co.samplesPerTexel = 4;
  co.maxBounces = 1;
  const LightingKeySpec keys[] = {{10.0f, 0.0f}, {16.0f, 0.0f}};
  const GeneratorTrainingSet set = captureTrainingSet(scene, positions, glm::vec3(-8.0f, 2.0f, -8.0f),
                                                      glm::vec3(8.0f, 2.0f, 8.0f), keys, co);
  const std::vector<uint8_t> flags(positions.size(), worlds::kProbeSkyOnly);
  ModelSizingOptions so;
  so.irradianceErrorTarget = 1e-6;
  so.training = tinyOptions();
  const CellModelChoice c = chooseCellModel(set, flags, so);
  std::printf("all-sky cell: %s, irradiance rel RMS %.4f, %zu bytes\n", cellModelKindName(c.kind).data(),
              c.error.irradianceRelativeRms, c.bytes);
  EXPECT_NE(c.kind, CellModelKind::kGenerator);
  EXPECT_FALSE(c.generator.has_value());
  ASSERT_EQ(c.attempts.size(), 3u);  // constant, SH L1, SH L2: nothing trained
  std::printf("  constant %.4f, SH L1 %.4f, SH L2 %.4f\n", c.attempts[0].irradianceRelativeRms,
              c.attempts[1].irradianceRelativeRms, c.attempts[2].irradianceRelativeRms);
  EXPECT_EQ(c.kind, CellModelKind::kShL2);  // the sun's irradiance lobe needs band 2
  EXPECT_EQ(c.lighting.size(), 2u * 9u * 3u);
  EXPECT_LT(c.error.irradianceRelativeRms, 0.1);
  EXPECT_EQ(c.describe(), "no network: sh-l2");
  // Restricted to what core/cell_file.h stores (one SH L1 fallback): SH L1.
  ModelSizingOptions l1 = so;
  l1.noNetworkKinds = {CellModelKind::kShL1};
  const CellModelChoice c1 = chooseCellModel(set, flags, l1);
  EXPECT_EQ(c1.kind, CellModelKind::kShL1);
  EXPECT_EQ(c1.lighting.size(), 2u * 4u * 3u);
  EXPECT_FALSE(c.reachedTarget);
  EXPECT_EQ(c.parameterCount, 0u);

  // Geometry, no flags, unreachable target: two candidates, cheapest first, the best kept.
  GeneratorArch small = tinyOptions().arch, big = small;
  small.convChannels = {8, kGeneratorChannels};
  so.candidates = {big, small};
  so.training.maxSteps = 300;
  const CellModelChoice g = chooseCellModel(tinyCell().set, {}, so);
  ASSERT_EQ(g.attempts.size(), 5u);
  EXPECT_EQ(g.attempts[3].arch.convChannels[0], 8);
  EXPECT_EQ(g.attempts[4].arch.convChannels[0], 16);
  EXPECT_LT(g.attempts[3].bytes, g.attempts[4].bytes);
  EXPECT_EQ(g.kind, CellModelKind::kGenerator);
  ASSERT_TRUE(g.generator.has_value());
  EXPECT_NE(g.describe().find(" C"), std::string::npos) << g.describe();
  EXPECT_EQ(g.bytes, generatorBytes(g.generator->weights.arch, tinyCell().set.probeCount()));
  for (const SizingAttempt& a : g.attempts) EXPECT_GE(a.irradianceRelativeRms, g.error.irradianceRelativeRms);
}

}  // namespace
}  // namespace lfgi::bake
