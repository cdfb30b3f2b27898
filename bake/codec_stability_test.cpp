// Failure modes of the codecs (measured at scale by bench/stability):
// - lighting the generator never saw (times between and outside its keys, overcast, the ends of the
//   conditioning range) decodes to finite, non-negative radiance and finite distances;
// - FP16 storage of a field whose sun is 1e5 x its interior light stays finite and keeps the dark values;
// - a cell whose network misses its error target, or whose training diverges, ends with a finite model
//   (the SH L1 fallback when the network is worse) and the choice reports that the target was missed.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bake/box_cell_test_util.h"
#include "bake/generator_training.h"
#include "core/generator.h"
#include "core/probe_codecs.h"

namespace lfgi::bake {
namespace {

// A box on a ground slab, 8 probes, keys 8, 12, 17.5 h (the bench's training keys).
const GeneratorTrainingSet& threeKeyCell() {
  static const GeneratorTrainingSet set = [] {
    const LightingKeySpec keys[] = {{8.0f, 0.0f}, {12.0f, 0.0f}, {17.5f, 0.0f}};
    return test::boxOnGroundCell(glm::vec3(0.3f), glm::vec3(0.7f, 0.6f, 0.5f), glm::vec3(-2.0f, 0.0f, -2.0f),
                                 glm::vec3(2.0f, 6.0f, 2.0f), keys, "stability cell");
  }();
  return set;
}

GeneratorTrainingOptions smallOptions(int steps) {
  GeneratorTrainingOptions o;
  o.arch.latentDim = 4;
  o.arch.convChannels = {16, kGeneratorChannels};  // 8 x 8 output
  o.maxSteps = steps;
  o.evalEvery = std::max(1, steps / 3);
  o.irradianceErrorTarget = 0.0;
  o.threads = 1;
  return o;
}

TEST(CodecStability, UnseenLightingDecodesFinite) {
  const GeneratorTrainingSet& set = threeKeyCell();
  const TrainedGenerator g = trainGenerator(set, smallOptions(120));
  const std::vector<float> z = g.decoderLatents(set);
  const GeneratorArch& a = g.weights.arch;
  const int n = a.outputResolution();
  const size_t P = set.probeCount(), per = size_t(kGeneratorChannels) * size_t(n * n);
  std::vector<float> raw(P * per), rad(size_t(n * n) * 3), dist(size_t(n * n) * 2);
  int decoded = 0;
  for (float t : {0.0f, 6.0f, 10.0f, 15.0f, 20.0f, 23.99f, 24.0f})
    for (float weather : {0.0f, 0.5f, 1.0f}) {
      const auto c = conditioningVector(t, weather);
      generatorForward(g.weights, z, std::span<const float>(c.data(), size_t(a.condDim)), P, raw);
      for (size_t p = 0; p < P; ++p) {
        decodeChannels(std::span<const float>(raw.data() + p * per, per), n, g.scale, rad, dist, {}, {});
        for (float v : rad) {
          ASSERT_TRUE(std::isfinite(v)) << "time " << t << " weather " << weather << " probe " << p;
          ASSERT_GE(v, 0.0f);
        }
        for (float v : dist) ASSERT_TRUE(std::isfinite(v)) << "time " << t << " weather " << weather;
        ++decoded;
      }
    }
  EXPECT_EQ(decoded, 21 * int(P));
}

TEST(CodecStability, OverflowingNetworkOutputDecodesFinite) {
  // A collapsed model (learning rate 1e3 in bench/stability) emits raw radiance channels far above 88,
  // where expm1 overflows float: the decoder clamps as training does (y <= 20), and NaN decodes as 0.
  const int n = 4;
  std::vector<float> raw(size_t(kGeneratorChannels) * n * n, 0.5f), rad(size_t(n * n) * 3);
  raw[0] = 1e4f;
  raw[1] = std::numeric_limits<float>::infinity();
  raw[2] = std::numeric_limits<float>::quiet_NaN();
  decodeChannels(raw, n, GeneratorOutputScale{2.0f, 64.0f}, rad, {}, {}, {});
  for (float v : rad) ASSERT_TRUE(std::isfinite(v));
  EXPECT_FLOAT_EQ(rad[0], 2.0f * std::expm1(20.0f));
  EXPECT_FLOAT_EQ(rad[3], 2.0f * std::expm1(20.0f));  // texel 1 of channel 0 (texel-major output)
  EXPECT_EQ(rad[6], 0.0f);                            // texel 2: NaN -> 0
  EXPECT_FLOAT_EQ(rad[9], 2.0f * std::expm1(0.5f));   // an ordinary output is untouched
}

TEST(CodecStability, Fp16KeepsSunAndA1e5DarkerInteriorFinite) {
  // Sun texels above FP16's largest finite value (65504) next to interior texels 1e5 x darker.
  ProbeField f;
  f.grid.dims = glm::ivec3(2, 1, 1);
  f.resolution = 4;
  f.irradianceResolution = 4;
  const size_t n2 = 16;
  f.radiance.assign(2 * n2 * 3, 0.0f);
  const float sun = 3.0e6f, interior = sun * 1e-5f;
  for (size_t t = 0; t < n2 * 3; ++t) {
    f.radiance[t] = t < 3 ? sun : interior * (1.0f + 0.01f * float(t));  // probe 0: one sun texel
    f.radiance[n2 * 3 + t] = interior * (1.0f + 0.02f * float(t));       // probe 1: interior only
  }
  for (int lmax : {0, 2}) {
    const auto codec = lmax == 0 ? makeRawFp16Codec() : makeShCodec(lmax);
    ProbeField out = f;
    codec->decode(codec->encode(f), out);
    if (!codec->decodesIrradiance()) deriveIrradiance(out);
    for (float v : out.radiance) ASSERT_TRUE(std::isfinite(v)) << codec->name();
    for (float v : out.irradiance) ASSERT_TRUE(std::isfinite(v)) << codec->name();
    if (lmax == 0) {
      // Pre-scaled by a power of two (largest magnitude <= 2^14): the dark texels stay normal FP16 numbers,
      // so every texel keeps FP16's relative precision (2^-11, half an ulp).
      for (size_t t = 0; t < f.radiance.size(); ++t)
        EXPECT_NEAR(out.radiance[t], f.radiance[t], f.radiance[t] * 0x1p-11f) << "texel " << t;
    }
  }
}

TEST(CodecStability, MissedTargetFallsBackAndIsReported) {
  const GeneratorTrainingSet& set = threeKeyCell();
  ModelSizingOptions so;
  so.irradianceErrorTarget = 0.001;  // unreachable in 5 steps
  so.noNetworkKinds = {CellModelKind::kShL1};
  so.training = smallOptions(5);
  so.candidates = {so.training.arch};
  const CellModelChoice c = chooseCellModel(set, {}, so);
  ASSERT_EQ(c.attempts.size(), 2u);  // SH L1, then the network
  EXPECT_FALSE(c.reachedTarget);
  EXPECT_DOUBLE_EQ(c.errorTarget, 0.001);
  EXPECT_GT(c.error.irradianceRelativeRms, c.errorTarget);  // what the bake stores as errorAchieved
  // The kept model is the better of the two: a 5-step network worse than SH L1 is not shipped.
  const double shL1 = c.attempts[0].irradianceRelativeRms, net = c.attempts[1].irradianceRelativeRms;
  EXPECT_DOUBLE_EQ(c.error.irradianceRelativeRms, std::min(shL1, net));
  EXPECT_EQ(c.kind, net < shL1 ? CellModelKind::kGenerator : CellModelKind::kShL1);
  std::printf("[ measure  ] missed target: SH L1 %.4f, 5-step network %.4f -> %s\n", shL1, net,
              c.describe().c_str());
}

TEST(CodecStability, DivergedTrainingIsDetectedAndNeverShipped) {
  const GeneratorTrainingSet& set = threeKeyCell();
  GeneratorTrainingOptions o = smallOptions(40);
  o.learningRate = 1e6f;  // Adam steps of 1e6: the weights blow up within a few steps
  o.latentLearningRate = 1e6f;
  const TrainedGenerator g = trainGenerator(set, o);
  EXPECT_TRUE(g.report.diverged);
  EXPECT_FALSE(g.report.reachedTarget);
  EXPECT_LT(g.report.steps, 40);  // stopped when the loss went non-finite
  g.weights.validate();           // what is exported is finite (the last finite state)

  ModelSizingOptions so;
  so.irradianceErrorTarget = 0.001;
  so.noNetworkKinds = {CellModelKind::kShL1};
  so.training = o;
  so.candidates = {o.arch};
  const CellModelChoice c = chooseCellModel(set, {}, so);
  EXPECT_EQ(c.kind, CellModelKind::kShL1);
  EXPECT_TRUE(std::isfinite(c.error.irradianceRelativeRms));
  EXPECT_FALSE(c.reachedTarget);
}

}  // namespace
}  // namespace lfgi::bake
