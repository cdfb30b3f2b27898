#include "core/quantize.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/error.h"
#include "core/half.h"
#include "generator_test_util.h"

namespace lfgi {
namespace {

GeneratorWeights randomWeights(const GeneratorArch& arch, uint32_t seed, float amplitude = 0.5f) {
  std::mt19937 rng(seed);
  return test::uniformRandomWeights(arch, rng, amplitude);
}

GeneratorArch smallArch() {
  GeneratorArch a;
  a.latentDim = 8;
  a.convChannels = {8, 6, kGeneratorChannels};
  return a;
}

TEST(Quantize, PerChannelErrorIsAtMostHalfAStep) {
  // [outer 3][channels 5][inner 7] with very different ranges per channel: each channel gets its own step.
  std::mt19937 rng(7);
  std::vector<float> x(3 * 5 * 7);
  for (size_t i = 0; i < x.size(); ++i) {
    size_t c = (i / 7) % 5;
    x[i] = std::uniform_real_distribution<float>(-1.0f, 1.0f)(rng) * std::pow(10.0f, float(c) - 2.0f);
  }
  for (int bits : {8, 4}) {
    PerChannelCodes q = quantizePerChannel(x, 3, 5, 7, bits, "x");
    std::vector<float> y = dequantizePerChannel(q.codes, q.scales, 3, 5, 7);
    int m = (1 << (bits - 1)) - 1;
    double worstRatio = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
      size_t c = (i / 7) % 5;
      EXPECT_LE(std::abs(q.codes[i]), m);
      double err = std::fabs(double(x[i]) - double(y[i]));
      // s/2 plus the float rounding of x/s and q*s (a few ulps of |x|).
      EXPECT_LE(err, 0.5 * q.scales[c] + 4e-7 * std::fabs(x[i])) << "bits " << bits << " element " << i;
      worstRatio = std::max(worstRatio, err / q.scales[c]);
    }
    std::printf("bits %d: worst |x - q(x)| = %.4f steps\n", bits, worstRatio);
  }
}

TEST(Quantize, ValuesOnTheGridAreExact) {
  // Channel c has step 2^-c and holds k * step for k in [-127, 127] (its max, 127 * step, fixes the scale).
  const int64_t channels = 4, inner = 255;
  std::vector<float> x(size_t(channels * inner));
  for (int64_t c = 0; c < channels; ++c)
    for (int64_t t = 0; t < inner; ++t) x[size_t(c * inner + t)] = float(t - 127) * std::ldexp(1.0f, -int(c));
  PerChannelCodes q = quantizePerChannel(x, 1, channels, inner, 8, "grid");
  for (int64_t c = 0; c < channels; ++c) EXPECT_EQ(q.scales[size_t(c)], std::ldexp(1.0f, -int(c)));
  std::vector<float> y = dequantizePerChannel(q.codes, q.scales, 1, channels, inner);
  for (size_t i = 0; i < x.size(); ++i) ASSERT_EQ(x[i], y[i]) << i;
  // An all-zero channel has scale 0 and decodes to exact zeros.
  std::vector<float> z(8, 0.0f);
  PerChannelCodes qz = quantizePerChannel(z, 1, 2, 4, 8, "zero");
  EXPECT_EQ(qz.scales[0], 0.0f);
  for (float v : dequantizePerChannel(qz.codes, qz.scales, 1, 2, 4)) EXPECT_EQ(v, 0.0f);
}

TEST(Quantize, ConvWeightsShareAScalePerOutputChannel) {
  // ConvTranspose2d [in 2][out 3][16]: output channel 1 is 100x larger; its scale must not coarsen 0 and 2.
  GeneratorArch a;
  a.latentDim = 2;
  a.condDim = 0;
  a.convChannels = {2, 3};
  GeneratorWeights w = randomWeights(a, 3, 1.0f);
  for (int i = 0; i < 2; ++i)
    for (int t = 0; t < 16; ++t) w.convWeight[0][size_t((i * 3 + 1) * 16 + t)] *= 100.0f;
  QuantizedWeights q = quantizeWeights(w, WeightPrecision::Int8);
  const QuantizedTensor& conv = q.tensors[2];
  ASSERT_EQ(conv.scales.size(), 3u);
  EXPECT_GT(conv.scales[1], 50.0f * conv.scales[0]);
  EXPECT_GT(conv.scales[1], 50.0f * conv.scales[2]);
  // Linear weight [out 32][in 2]: one scale per row.
  EXPECT_EQ(q.tensors[0].scales.size(), 32u);
  EXPECT_EQ(q.tensors[1].encoding, TensorEncoding::Float32);  // bias stays float32 in int8 mode
}

TEST(Quantize, WeightsRoundTripWithinBoundsAndReportBytes) {
  GeneratorArch a = smallArch();
  GeneratorWeights w = randomWeights(a, 11);
  size_t params = a.parameterCount();

  QuantizedWeights h = quantizeWeights(w, WeightPrecision::Float16);
  EXPECT_EQ(h.bytes(), params * 2);
  GeneratorWeights wh = dequantizeWeights(h);
  wh.validate();
  for (size_t i = 0; i < w.linearWeight.size(); ++i)
    EXPECT_EQ(wh.linearWeight[i], halfToFloat(floatToHalfClamped(w.linearWeight[i])));

  QuantizedWeights q = quantizeWeights(w, WeightPrecision::Int8);
  // int8: 1 byte per weight + 4 per channel scale; biases 4 bytes.
  size_t biases = 16 * 8 + 6 + size_t(kGeneratorChannels);
  size_t scales = 16 * 8 + 6 + size_t(kGeneratorChannels);
  EXPECT_EQ(q.bytes(), (params - biases) + 4 * scales + 4 * biases);
  GeneratorWeights wq = dequantizeWeights(q);
  wq.validate();
  for (int i = 0; i < a.layers(); ++i) {
    const QuantizedTensor& t = q.tensors[size_t(2 + 2 * i)];
    for (size_t k = 0; k < w.convWeight[size_t(i)].size(); ++k) {
      size_t c = (k / 16) % size_t(t.channels);
      EXPECT_LE(std::fabs(w.convWeight[size_t(i)][k] - wq.convWeight[size_t(i)][k]),
                0.5f * t.scales[c] * 1.0001f);
    }
    EXPECT_EQ(wq.convBias[size_t(i)], w.convBias[size_t(i)]);
  }
  std::printf("%zu parameters: fp32 %zu B, fp16 %zu B, int8 %zu B\n", params, params * 4, h.bytes(),
              q.bytes());

  // Decoding the dequantized network stays close to the float one (the error a cell file adds).
  std::vector<float> lat(3 * size_t(a.latentDim));
  for (size_t i = 0; i < lat.size(); ++i) lat[i] = std::sin(float(i));
  auto cond = conditioningVector(12.0f, 0.0f);
  size_t outN = 3 * size_t(a.outChannels() * a.outputResolution() * a.outputResolution());
  std::vector<float> y(outN), yq(outN);
  generatorForward(w, lat, cond, 3, y);
  generatorForward(wq, lat, cond, 3, yq);
  double maxDiff = 0.0, maxAbs = 0.0;
  for (size_t i = 0; i < outN; ++i) {
    maxDiff = std::max(maxDiff, double(std::fabs(y[i] - yq[i])));
    maxAbs = std::max(maxAbs, double(std::fabs(y[i])));
  }
  std::printf("int8 weights: max output diff %.4g (max |output| %.4g)\n", maxDiff, maxAbs);
  EXPECT_LT(maxDiff, 0.05 * maxAbs);
}

TEST(Quantize, LatentsPerDimensionEightAndFourBits) {
  const int dim = 6;
  const int64_t count = 50;
  std::vector<float> lat(size_t(count * dim));
  std::mt19937 rng(5);
  for (size_t i = 0; i < lat.size(); ++i)
    lat[i] = std::normal_distribution<float>(0.0f, 1.0f)(rng) * float(1 + i % dim);  // dim d has sigma d+1
  for (int bits : {8, 4}) {
    QuantizedLatents q = quantizeLatents(lat, dim, bits);
    q.validate("q");
    EXPECT_EQ(q.count, count);
    EXPECT_EQ(q.bytes(), size_t(dim) * 4 + size_t(count * dim * bits) / 8);
    std::vector<float> back = dequantizeLatents(q);
    for (size_t i = 0; i < lat.size(); ++i)
      EXPECT_LE(std::fabs(lat[i] - back[i]), 0.5f * q.scales[i % dim] * 1.0001f)
          << "bits " << bits << " " << i;
    EXPECT_GT(q.scales[5], 2.0f * q.scales[0]);  // per-dimension scales follow the spread
  }
}

TEST(Quantize, RejectsNonFiniteAndOutOfRangeWithAClearError) {
  GeneratorWeights w = randomWeights(smallArch(), 2);
  w.convWeight[1][17] = std::numeric_limits<float>::quiet_NaN();
  try {
    quantizeWeights(w, WeightPrecision::Int8);
    FAIL() << "NaN accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("conv1Weight: element 17 is nan"), std::string::npos) << e.what();
  }
  w = randomWeights(smallArch(), 2);
  w.linearBias[3] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(quantizeWeights(w, WeightPrecision::Float16), Error);
  w = randomWeights(smallArch(), 2);
  w.linearWeight[0] = 1e6f;
  try {
    quantizeWeights(w, WeightPrecision::Float16);
    FAIL() << "FP16 overflow accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("exceeds the FP16 range"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(quantizeWeights(w, WeightPrecision::Int8));  // int8 has no range limit
  std::vector<float> lat = {0.0f, 1.0f, -std::numeric_limits<float>::infinity(), 2.0f};
  try {
    quantizeLatents(lat, 2);
    FAIL() << "Inf latent accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("element 2 is -inf"), std::string::npos) << e.what();
  }
  EXPECT_THROW(quantizeLatents(std::vector<float>(5, 0.0f), 2), Error);  // not a whole number of latents
  EXPECT_THROW(quantizeLatents(std::vector<float>(4, 0.0f), 2, 3), Error);
  // A corrupt stored tensor is caught before it is dequantized.
  QuantizedWeights q = quantizeWeights(randomWeights(smallArch(), 2), WeightPrecision::Int8);
  q.tensors[0].codes[0] = -128;
  EXPECT_THROW(dequantizeWeights(q), Error);
  q = quantizeWeights(randomWeights(smallArch(), 2), WeightPrecision::Int8);
  q.tensors[2].scales.pop_back();
  EXPECT_THROW(dequantizeWeights(q), Error);
}

}  // namespace
}  // namespace lfgi

namespace lfgi {
namespace {

// A per-cell adapter: one scale for the scale array, one for the shift array; error <= half a step,
// bytes = 1 + 8 + packed codes; the identity adapter (all zero) comes back exactly.
TEST(Quantize, AdapterTwoScalesHalfAStepAndBytes) {
  GeneratorArch arch;
  arch.latentDim = 4;
  arch.convChannels = {16, 8, kGeneratorChannels};
  GeneratorAdapter a = identityAdapter(arch, 2);
  ASSERT_EQ(a.scale.size(), 24u);
  std::mt19937 rng(3);
  std::normal_distribution<float> nd(0.0f, 0.2f);
  for (float& v : a.scale) v = nd(rng);
  for (float& v : a.shift) v = 3.0f * nd(rng);  // a larger range: its own scale
  for (int bits : {8, 4}) {
    const QuantizedAdapter q = quantizeAdapter(a, bits);
    EXPECT_EQ(q.bytes(), 1u + 8u + (48u * size_t(bits) + 7) / 8);
    const GeneratorAdapter b = dequantizeAdapter(q);
    ASSERT_EQ(b.scale.size(), a.scale.size());
    EXPECT_EQ(b.stages, 2);
    for (size_t i = 0; i < a.scale.size(); ++i) {
      EXPECT_LE(std::abs(b.scale[i] - a.scale[i]), 0.5f * q.scales[0] * 1.0001f);
      EXPECT_LE(std::abs(b.shift[i] - a.shift[i]), 0.5f * q.scales[1] * 1.0001f);
    }
    EXPECT_GT(q.scales[1], 2.0f * q.scales[0]);  // max 1.29 vs 0.55 for this seed
  }
  const GeneratorAdapter id = dequantizeAdapter(quantizeAdapter(identityAdapter(arch, 3), 8));
  EXPECT_EQ(id.scale, identityAdapter(arch, 3).scale);
  GeneratorAdapter bad = a;
  bad.shift[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(quantizeAdapter(bad), Error);
}

}  // namespace
}  // namespace lfgi
