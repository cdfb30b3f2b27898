#include "core/generator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/error.h"

namespace lfgi {
namespace {

// One latent -> linear(identity-like) -> 1 channel 4x4 -> one transposed conv to 1 channel 8x8 whose kernel
// has a single tap (ky, kx): the output is the input scattered to (2 iy - 1 + ky, 2 ix - 1 + kx).
GeneratorWeights singleTap(int ky, int kx) {
  GeneratorWeights w;
  w.arch.latentDim = 16;
  w.arch.condDim = 0;
  w.arch.convChannels = {1, 1};
  w.linearWeight.assign(16 * 16, 0.0f);
  for (int i = 0; i < 16; ++i) w.linearWeight[size_t(i * 16 + i)] = 1.0f;  // h0 = ReLU(z)
  w.linearBias.assign(16, 0.0f);
  w.convWeight = {std::vector<float>(16, 0.0f)};
  w.convWeight[0][size_t(ky * 4 + kx)] = 1.0f;
  w.convBias = {{0.5f}};
  return w;
}

TEST(Generator, TransposedConvScattersByPyTorchRule) {
  for (int ky = 0; ky < 4; ++ky)
    for (int kx = 0; kx < 4; ++kx) {
      GeneratorWeights w = singleTap(ky, kx);
      w.validate();
      std::vector<float> z(16);
      for (int i = 0; i < 16; ++i) z[size_t(i)] = float(i + 1);
      std::vector<float> out(64);
      generatorForward(w, z, {}, 1, out);
      std::vector<float> want(64, 0.5f);
      for (int iy = 0; iy < 4; ++iy)
        for (int ix = 0; ix < 4; ++ix) {
          int oy = 2 * iy - 1 + ky, ox = 2 * ix - 1 + kx;
          if (oy >= 0 && oy < 8 && ox >= 0 && ox < 8) want[size_t(oy * 8 + ox)] += float(iy * 4 + ix + 1);
        }
      for (size_t t = 0; t < 64; ++t)
        ASSERT_EQ(out[t], want[t]) << "tap " << ky << "," << kx << " texel " << t;
    }
}

TEST(Generator, ReluAfterLinearAndHiddenLayersOnly) {
  GeneratorWeights w = singleTap(1, 1);
  std::vector<float> z(16, -1.0f), out(64);
  generatorForward(w, z, {}, 1, out);
  for (float v : out) EXPECT_EQ(v, 0.5f);  // negative linear outputs are cut, the bias passes (no final ReLU)
  w.convBias = {{-2.0f}};
  generatorForward(w, z, {}, 1, out);
  for (float v : out) EXPECT_EQ(v, -2.0f);
}

TEST(Generator, ParameterCountMatchesWeights) {
  GeneratorArch a;
  a.latentDim = 8;
  a.convChannels = {24, 12, 6, kGeneratorChannels};
  EXPECT_EQ(a.outputResolution(), 32);
  size_t want = 16 * 24 * 11 + 16 * 24 + 24 * 12 * 16 + 12 + 12 * 6 * 16 + 6 + 6 * 11 * 16 + 11;
  EXPECT_EQ(a.parameterCount(), want);
}

TEST(Generator, ValidateNamesTheBadField) {
  GeneratorWeights w = singleTap(0, 0);
  w.convBias[0].push_back(1.0f);
  EXPECT_THROW(
      {
        try {
          w.validate();
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("convBias[0]"), std::string::npos) << e.what();
          throw;
        }
      },
      Error);
  GeneratorArch a;
  a.latentSource = LatentSource::PositionFourier;
  a.fourierOctaves = 2;
  a.latentDim = 10;
  EXPECT_THROW(a.validate(), Error);
  a.latentDim = 12;
  EXPECT_NO_THROW(a.validate());
}

TEST(Generator, ConditioningAndPositionLatent) {
  auto c = conditioningVector(6.0f, 2.0f);
  EXPECT_NEAR(c[0], 1.0f, 1e-6f);
  EXPECT_NEAR(c[1], 0.0f, 1e-6f);
  EXPECT_EQ(c[2], 1.0f);  // weather clamps to [0, 1]
  std::vector<float> z(12);
  positionLatent({0.5f, 0.0f, 0.25f}, 2, z);
  EXPECT_NEAR(z[0], 1.0f, 1e-6f);                                   // sin(pi/2)
  EXPECT_NEAR(z[2], 0.0f, 1e-6f);                                   // sin(0)
  EXPECT_NEAR(z[3], 1.0f, 1e-6f);                                   // cos(0)
  EXPECT_NEAR(z[4], float(std::sin(std::numbers::pi / 4)), 1e-6f);  // sin(pi/4)
  EXPECT_NEAR(z[6], 0.0f, 1e-6f);                                   // sin(2 pi 0.5)
}

TEST(Generator, DecodeChannelsInvertsEncodings) {
  const int R = 2;
  std::vector<float> raw(size_t(kGeneratorChannels) * 4, 0.0f);
  const float L = 3.0f, exposure = 2.0f, range = 10.0f, r = 4.0f;
  for (int t = 0; t < 4; ++t) {
    for (int c = 0; c < 3; ++c) raw[size_t(c * 4 + t)] = std::log1p(L / exposure);
    raw[size_t(3 * 4 + t)] = r / range;
    raw[size_t(4 * 4 + t)] = r * r / (range * range);
    raw[size_t(5 * 4 + t)] = 0.0f;
    raw[size_t(6 * 4 + t)] = 2.0f;  // unnormalised normal
    raw[size_t(8 * 4 + t)] = 1.5f;  // albedo clamps
  }
  std::vector<float> rad(12), dist(8), nrm(12), alb(12);
  decodeChannels(raw, R, {exposure, range}, rad, dist, nrm, alb);
  EXPECT_NEAR(rad[0], L, 1e-5f);
  EXPECT_NEAR(dist[0], r, 1e-5f);
  EXPECT_NEAR(dist[1], r * r, 1e-4f);
  EXPECT_EQ(nrm[1], 1.0f);
  EXPECT_EQ(alb[0], 1.0f);
  EXPECT_THROW(decodeChannels(raw, 3, {}, rad, {}, {}, {}), Error);
}

}  // namespace
}  // namespace lfgi
