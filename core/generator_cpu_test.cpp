#include "core/generator_cpu.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"
#include "generator_test_util.h"

namespace lfgi {
namespace {

using test::randomLatents;
using test::relMaxError;

struct Case {
  GeneratorArch arch;
  size_t count;
  size_t chunk;
};

GeneratorArch makeArch(int latent, int cond, std::vector<int> channels) {
  GeneratorArch a;
  a.latentDim = latent;
  a.condDim = cond;
  a.convChannels = std::move(channels);
  return a;
}

// Tolerance: 1e-5 of the output's largest magnitude (float sums of up to 4 * 64 terms in another order; the
// measured error is printed).
TEST(GeneratorCpu, MatchesReferenceOnRandomWeights) {
  const Case cases[] = {
      {makeArch(16, 3, {32, kGeneratorChannels}), 37, 0},        // 8x8
      {makeArch(8, 0, {24, 12, kGeneratorChannels}), 50, 16},    // 16x16, several chunks
      {makeArch(16, 3, {32, 16, 8, kGeneratorChannels}), 9, 0},  // 32x32
      {makeArch(5, 3, {7, 5, 3}), 21, 8},                        // odd sizes everywhere
  };
  unsigned seed = 1;
  for (const Case& c : cases) {
    GeneratorWeights w = randomGeneratorWeights(c.arch, seed++);
    std::vector<float> z = randomLatents(c.count, c.arch.latentDim, seed++);
    std::vector<float> cond;
    if (c.arch.condDim) {
      auto cv = conditioningVector(14.5f, 0.3f);
      cond.assign(cv.begin(), cv.end());
    }
    const size_t R = size_t(c.arch.outputResolution()), n = c.count * size_t(c.arch.outChannels()) * R * R;
    std::vector<float> ref(n), fast(n, -7.0f);
    generatorForward(w, z, cond, c.count, ref);
    GeneratorCpu dec(w, c.chunk);
    dec.forward(z, cond, c.count, fast);
    double e = relMaxError(fast, ref);
    std::printf("  arch R=%zu layers=%d chunk=%zu: max rel error %.2e\n", R, c.arch.layers(),
                dec.chunkProbes(), e);
    EXPECT_LT(e, 1e-5) << "R=" << R;
    // The outputs are not trivially zero (the ReLUs did not kill everything).
    double energy = 0.0;
    for (float v : ref) energy += double(v) * v;
    EXPECT_GT(energy, 1e-3 * double(n));
    // A second call reuses the scratch and gives the same bits.
    std::vector<float> again(n);
    dec.forward(z, cond, c.count, again);
    EXPECT_EQ(again, fast);
  }
}

TEST(GeneratorCpu, RejectsSizeMismatches) {
  GeneratorArch a = makeArch(4, 3, {8, kGeneratorChannels});
  GeneratorCpu dec(randomGeneratorWeights(a, 3));
  std::vector<float> z(8), cond(3), out(2 * kGeneratorChannels * 64);
  EXPECT_NO_THROW(dec.forward(z, cond, 2, out));
  EXPECT_THROW(dec.forward(z, cond, 3, out), Error);
  EXPECT_THROW(dec.forward(z, std::vector<float>(2), 2, out), Error);
  std::vector<float> small(5);
  EXPECT_THROW(dec.forward(z, cond, 2, small), Error);
  GeneratorWeights bad = randomGeneratorWeights(a, 3);
  bad.convWeight[0].pop_back();
  EXPECT_THROW(GeneratorCpu{bad}, Error);
}

TEST(GeneratorCpu, DecodeProbeFieldMatchesReferenceChannels) {
  GeneratorArch a = makeArch(6, 3, {16, 8, kGeneratorChannels});
  GeneratorWeights w = randomGeneratorWeights(a, 11);
  ProbeField field;
  field.grid.dims = {3, 2, 2};
  field.resolution = a.outputResolution();
  const size_t count = size_t(field.probeCount()), T = size_t(field.resolution * field.resolution);
  std::vector<float> z = randomLatents(count, a.latentDim, 12);
  auto cv = conditioningVector(9.0f, 0.0f);
  std::vector<float> cond(cv.begin(), cv.end());
  const GeneratorOutputScale scale{0.5f, 20.0f};
  GeneratorCpu dec(w, 5);
  decodeProbeField(dec, z, cond, scale, field);

  std::vector<float> raw(count * kGeneratorChannels * T);
  generatorForward(w, z, cond, count, raw);
  double worst[4] = {0, 0, 0, 0};
  for (size_t p = 0; p < count; ++p) {
    std::vector<float> rad(T * 3), dist(T * 2), nrm(T * 3), alb(T * 3);
    decodeChannels(std::span(raw).subspan(p * kGeneratorChannels * T, kGeneratorChannels * T),
                   field.resolution, scale, rad, dist, nrm, alb);
    auto cmp = [&](const std::vector<float>& want, const std::vector<float>& got, size_t per, int which) {
      for (size_t i = 0; i < want.size(); ++i) {
        double d = std::abs(double(got[p * T * per + i]) - want[i]) / (1.0 + std::abs(double(want[i])));
        worst[which] = std::max(worst[which], d);
      }
    };
    cmp(rad, field.radiance, 3, 0);
    cmp(dist, field.distance, 2, 1);
    cmp(nrm, field.normal, 3, 2);
    cmp(alb, field.albedo, 3, 3);
  }
  std::printf(
      "  decodeProbeField max error vs reference: radiance %.2e distance %.2e normal %.2e albedo %.2e\n",
      worst[0], worst[1], worst[2], worst[3]);
  EXPECT_LT(worst[0], 1e-5);
  EXPECT_LT(worst[1], 1e-6 * scale.range * scale.range);  // r^2 = raw * range^2 scales the rounding up
  EXPECT_LT(worst[3], 1e-5);
  // normalize() amplifies the raw rounding difference by 1 / |n| where the raw normal is short
  EXPECT_LT(worst[2], 1e-3);
  field.resolution = 8;
  EXPECT_THROW(decodeProbeField(dec, z, cond, scale, field), Error);
}

}  // namespace
}  // namespace lfgi
