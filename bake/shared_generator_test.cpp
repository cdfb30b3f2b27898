// World-shared generator + per-cell adapters (bake/generator_training.h "shared generator") and the
// quantizer in the training loop. Tiny synthetic cells: ground + one box whose size, place and colour
// differ per cell, 8 probes, 8 x 8 maps, one lighting key, 4 spp, 1 bounce (captures take ~0.1 s).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "bake/box_cell_test_util.h"
#include "bake/generator_training.h"
#include "core/error.h"
#include "core/quantize.h"
#include "generator_test_util.h"

namespace lfgi::bake {
namespace {

GeneratorTrainingSet tinyCell(int variant) {
  const glm::vec3 ground = glm::vec3(0.3f, 0.25f, 0.2f) + 0.1f * float(variant % 2);
  const glm::vec3 wall =
      variant == 1 ? glm::vec3(0.2f, 0.5f, 0.7f) : glm::vec3(0.7f, 0.6f - 0.1f * float(variant), 0.5f);
  const float half = 1.5f + 0.5f * float(variant), height = 4.0f + 2.0f * float(variant);
  const glm::vec3 c(0.6f * float(variant) - 0.6f, 0.0f, 0.4f * float(variant));
  const LightingKeySpec keys[] = {{12.0f, 0.0f}};  // one time for every cell, as bench/codec
  return test::boxOnGroundCell(ground, wall, c - glm::vec3(half, 0.0f, half),
                               c + glm::vec3(half, height, half), keys, "tiny shared cell");
}

// Cells 0..2 pre-train, cell 3 is held out.
const std::vector<GeneratorTrainingSet>& cells() {
  static const std::vector<GeneratorTrainingSet> c = [] {
    std::vector<GeneratorTrainingSet> v;
    for (int i = 0; i < 4; ++i) v.push_back(tinyCell(i));
    return v;
  }();
  return c;
}

SharedTrainingOptions tinyOptions(int steps) {
  SharedTrainingOptions o;
  o.training.arch.latentDim = 4;
  o.training.arch.convChannels = {16, kGeneratorChannels};  // 8 x 8 output
  o.training.maxSteps = steps;
  o.training.evalEvery = 50;
  o.training.irradianceErrorTarget = 0.0;  // never reached: runs all steps
  o.training.threads = 1;
  o.adapterStages = 2;  // all stages of the depth-1 network
  return o;
}

// Pre-trained once for every test (200 steps on 3 cells).
const SharedGenerator& shared() {
  static const SharedGenerator s = [] {
    return pretrainSharedGenerator(std::span<const GeneratorTrainingSet>(cells().data(), 3),
                                   tinyOptions(200));
  }();
  return s;
}

const GeneratorTrainingSet& heldOut() {
  return cells()[3];
}

std::filesystem::path tmpDir() {
  std::filesystem::path d = std::filesystem::path(LFGI_TEST_TMP_DIR) / "shared_generator";
  std::filesystem::create_directories(d);
  return d;
}

// Irradiance error of a fitted cell after storing its latents with `bits` and its adapter as int8.
double errorAfterQuantization(const CellAdaptation& a, int bits) {
  CellAdaptation q = a;
  q.latents = dequantizeLatents(quantizeLatents(a.latents, shared().weights.arch.latentDim, bits));
  q.adapter = dequantizeAdapter(quantizeAdapter(a.adapter, 8));
  return evaluateGenerator(q.folded(shared().weights), heldOut()).irradianceRelativeRms;
}

// libtorch runs the adapter as FiLM after each layer; the decoders run applyAdapter's folded weights.
// Same tolerance as CpuReferenceMatchesLibtorchForward: |diff| <= 1e-5 (1 + max |y|).
TEST(SharedGenerator, FoldedAdapterMatchesLibtorchFilm) {
  std::mt19937 rng(11);
  GeneratorArch arch;
  arch.latentDim = 6;
  arch.convChannels = {12, 7, kGeneratorChannels};
  const GeneratorWeights w = test::uniformRandomWeights(arch, rng, 0.4f);
  for (int stages = 0; stages <= arch.layers() + 1; ++stages) {
    GeneratorAdapter a = identityAdapter(arch, stages);
    std::normal_distribution<float> nd(0.0f, 0.3f);
    for (float& v : a.scale) v = nd(rng);
    for (float& v : a.shift) v = nd(rng);
    const size_t count = 3;
    const std::vector<float> z = test::randomLatents(count, arch.latentDim, 5);
    const auto c = conditioningVector(14.0f, 0.2f);
    const std::vector<float> ref = torchGeneratorForward(w, z, c, count, &a);
    std::vector<float> cpu(ref.size()), plain(ref.size());
    generatorForward(applyAdapter(w, a), z, c, count, cpu);
    generatorForward(w, z, c, count, plain);
    double maxAbs = 0.0, maxDiff = 0.0, changed = 0.0;
    for (size_t i = 0; i < ref.size(); ++i) {
      maxAbs = std::max(maxAbs, double(std::abs(ref[i])));
      maxDiff = std::max(maxDiff, double(std::abs(ref[i] - cpu[i])));
      changed = std::max(changed, double(std::abs(plain[i] - cpu[i])));
    }
    std::printf("stages %d: max |y| %.3f, max |folded - torch FiLM| %.3g, adapter moves outputs by %.3g\n",
                stages, maxAbs, maxDiff, changed);
    EXPECT_LE(maxDiff, 1e-5 * (1.0 + maxAbs));
    if (stages > 0) {
      EXPECT_GT(changed, 1e-2);  // the adapter is not a no-op
    }
  }
  // The identity adapter folds to the very same weights.
  EXPECT_EQ(weightsContentHash(applyAdapter(w, identityAdapter(arch, 3))), weightsContentHash(w));
  const GeneratorAdapter bad{2, {1.0f}, {1.0f}};  // 2 stages need 12 + 7 floats each
  EXPECT_THROW(applyAdapter(w, bad), Error);
}

// A held-out cell fitted against the frozen shared model: the shared weights stay bit-exact, and the
// cell reaches an error bound far below what the shared model gives it untouched (identity adapter,
// latents of a pre-training cell) and below the cell's own error without an adapter.
TEST(SharedGenerator, FrozenFitChangesNoSharedWeightAndReachesABound) {
  const SharedGenerator& s = shared();
  std::printf("pretrain: %d steps, mean irradiance rel RMS %.4f over %zu cells (%.1f s)\n", s.report.steps,
              s.report.irradianceRelativeRms, s.cells.size(), s.report.seconds);
  ASSERT_EQ(s.cells.size(), 3u);
  EXPECT_FALSE(s.report.diverged);
  const uint64_t before = weightsContentHash(s.weights);
  const GeneratorWeights copy = s.weights;
  const CellAdaptation fit = fitCellToSharedGenerator(s.weights, heldOut(), tinyOptions(200));
  EXPECT_EQ(fit.sharedWeightsHash, before);
  EXPECT_EQ(weightsContentHash(s.weights), before);
  EXPECT_EQ(copy.linearWeight, s.weights.linearWeight);
  SharedTrainingOptions noAdapter = tinyOptions(200);
  noAdapter.adapterStages = 0;
  const CellAdaptation latentOnly = fitCellToSharedGenerator(s.weights, heldOut(), noAdapter);
  CellAdaptation untouched = s.cells[0];
  untouched.adapter = identityAdapter(s.weights.arch, 2);
  const double untouchedErr = evaluateGenerator(untouched.folded(s.weights), heldOut()).irradianceRelativeRms;
  std::printf("held-out cell: fit %.4f (latents only %.4f, untouched %.4f) in %.1f s, %zu adapter floats\n",
              fit.report.irradianceRelativeRms, latentOnly.report.irradianceRelativeRms, untouchedErr,
              fit.report.seconds, fit.adapter.scale.size() * 2);
  EXPECT_LE(fit.report.irradianceRelativeRms, 0.3);  // measured 0.262 (the per-probe loss weighs dark probes)
  EXPECT_LT(fit.report.irradianceRelativeRms, 0.6 * untouchedErr);
  EXPECT_LE(fit.report.irradianceRelativeRms, latentOnly.report.irradianceRelativeRms);
  EXPECT_EQ(fit.adapter.scale.size(), 16u + kGeneratorChannels);
}

// Quantizer in the loop: with 8- and 4-bit fake quantization the exported latents lie on the grid
// (quantizeLatents is lossless on them) and the error after quantization stays within 2 % (int8) / 7 %
// (4-bit) of the float fit's error before quantization (the two runs differ by training noise too, hence
// the margins).
TEST(SharedGenerator, QuantizationInTheLoopLosesNothing) {
  const GeneratorWeights& w = shared().weights;
  const CellAdaptation plain = fitCellToSharedGenerator(w, heldOut(), tinyOptions(200));
  const double before = plain.report.irradianceRelativeRms;
  for (int bits : {8, 4}) {
    SharedTrainingOptions o = tinyOptions(200);
    o.training.latentQuantBits = bits;
    o.adapterQuantBits = 8;
    const CellAdaptation qat = fitCellToSharedGenerator(w, heldOut(), o);
    const std::vector<float> back = dequantizeLatents(quantizeLatents(qat.latents, w.arch.latentDim, bits));
    EXPECT_EQ(back, qat.latents) << bits << "-bit latents are not on their grid";
    const double qatAfter = errorAfterQuantization(qat, bits),
                 plainAfter = errorAfterQuantization(plain, bits);
    std::printf("%d-bit: float fit %.4f; quantized after: QAT %.4f, no QAT %.4f\n", bits, before, qatAfter,
                plainAfter);
    EXPECT_NEAR(qatAfter, qat.report.irradianceRelativeRms,
                1e-3 * qatAfter);                             // the report is after quantization
    EXPECT_LE(qatAfter, before * (bits == 8 ? 1.02 : 1.07));  // measured 1.000 / 1.057
  }
}

TEST(SharedGenerator, SameSeedIsBitIdenticalAndOtherSeedsDiffer) {
  const GeneratorWeights& w = shared().weights;
  SharedTrainingOptions o = tinyOptions(60);
  o.training.latentQuantBits = 8;
  const CellAdaptation a = fitCellToSharedGenerator(w, heldOut(), o),
                       b = fitCellToSharedGenerator(w, heldOut(), o);
  EXPECT_EQ(a.latents, b.latents);
  EXPECT_EQ(a.adapter.scale, b.adapter.scale);
  EXPECT_EQ(a.adapter.shift, b.adapter.shift);
  o.training.seed = 2;
  const CellAdaptation c = fitCellToSharedGenerator(w, heldOut(), o);
  EXPECT_NE(a.latents, c.latents);
  // Pre-training too.
  const auto pre = std::span<const GeneratorTrainingSet>(cells().data(), 2);
  const SharedGenerator p = pretrainSharedGenerator(pre, tinyOptions(30)),
                        q = pretrainSharedGenerator(pre, tinyOptions(30));
  EXPECT_EQ(weightsContentHash(p.weights), weightsContentHash(q.weights));
  EXPECT_EQ(p.cells[1].latents, q.cells[1].latents);
}

TEST(SharedGenerator, ResumedPretrainingAndFitEndBitIdentical) {
  const auto pre = std::span<const GeneratorTrainingSet>(cells().data(), 2);
  SharedTrainingOptions o = tinyOptions(60);
  o.training.latentQuantBits = 4;
  o.adapterQuantBits = 8;
  const SharedGenerator full = pretrainSharedGenerator(pre, o);
  o.training.checkpoint = tmpDir() / "pretrain.pt";
  std::filesystem::remove(o.training.checkpoint);
  o.training.stopAfterSteps = 25;
  const SharedGenerator part = pretrainSharedGenerator(pre, o);
  EXPECT_TRUE(part.report.interrupted);
  EXPECT_EQ(part.report.steps, 25);
  ASSERT_TRUE(std::filesystem::exists(o.training.checkpoint));
  o.training.stopAfterSteps = 0;
  const SharedGenerator rest = pretrainSharedGenerator(pre, o);
  EXPECT_EQ(rest.report.resumedFromStep, 25);
  EXPECT_EQ(weightsContentHash(rest.weights), weightsContentHash(full.weights));
  EXPECT_EQ(rest.cells[0].latents, full.cells[0].latents);
  EXPECT_EQ(rest.cells[1].adapter.shift, full.cells[1].adapter.shift);
  EXPECT_FALSE(std::filesystem::exists(o.training.checkpoint));

  // The frozen fit resumes too, and refuses a checkpoint written against another shared model.
  SharedTrainingOptions f = tinyOptions(60);
  const CellAdaptation whole = fitCellToSharedGenerator(shared().weights, heldOut(), f);
  f.training.checkpoint = tmpDir() / "fit.pt";
  std::filesystem::remove(f.training.checkpoint);
  f.training.stopAfterSteps = 20;
  (void)fitCellToSharedGenerator(shared().weights, heldOut(), f);
  EXPECT_THROW(fitCellToSharedGenerator(full.weights, heldOut(), f), Error);
  f.training.stopAfterSteps = 0;
  const CellAdaptation resumed = fitCellToSharedGenerator(shared().weights, heldOut(), f);
  EXPECT_EQ(resumed.report.resumedFromStep, 20);
  EXPECT_EQ(resumed.latents, whole.latents);
  EXPECT_EQ(resumed.adapter.scale, whole.adapter.scale);
}

TEST(SharedGenerator, BadOptionsAreErrors) {
  SharedTrainingOptions o = tinyOptions(10);
  o.adapterStages = 3;  // a depth-1 network has 2 stages
  EXPECT_THROW(o.validate(), Error);
  o = tinyOptions(10);
  o.adapterQuantBits = 5;
  EXPECT_THROW(o.validate(), Error);
  o = tinyOptions(10);
  o.training.latentQuantBits = 3;
  EXPECT_THROW(o.validate(), Error);
  o = tinyOptions(10);
  o.training.adversarial = true;
  EXPECT_THROW(o.validate(), Error);
  o = tinyOptions(10);
  o.training.arch.latentDim = 5;  // not the shared model's
  EXPECT_THROW(fitCellToSharedGenerator(shared().weights, heldOut(), o), Error);
  EXPECT_THROW(pretrainSharedGenerator({}, tinyOptions(10)), Error);
}

}  // namespace
}  // namespace lfgi::bake
