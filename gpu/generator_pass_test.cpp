#include "gpu/generator_pass.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "core/error.h"
#include "core/generator_cpu.h"
#include "generator_test_util.h"
#include "gpu/timing.h"

namespace lfgi::gpu {
namespace {

using test::randomLatents;
using test::relMaxError;

GeneratorArch makeArch(int latent, int cond, std::vector<int> channels) {
  GeneratorArch a;
  a.latentDim = latent;
  a.condDim = cond;
  a.convChannels = std::move(channels);
  return a;
}

std::vector<float> condFor(const GeneratorArch& a) {
  if (a.condDim == 0) return {};
  auto c = conditioningVector(17.0f, 0.6f);
  return {c.begin(), c.end()};
}

// Both kernels against the CPU reference (generatorForward), on random weights. Tolerance: 1e-5 of the
// output's largest magnitude (float sums in another order; lavapipe may fuse multiply-adds).
TEST(GpuGenerator, BothKernelsMatchCpuReference) {
  auto ctx = createContext();
  GeneratorDecodePass pass(*ctx);
  struct Case {
    GeneratorArch arch;
    size_t count;
  };
  const Case cases[] = {
      {makeArch(16, 3, {32, kGeneratorChannels}), 13},        // 8x8, count not a multiple of 4
      {makeArch(8, 0, {24, 12, kGeneratorChannels}), 20},     // 16x16, channels not multiples of 4 or 16
      {makeArch(16, 3, {20, 16, 8, kGeneratorChannels}), 6},  // 32x32
      {makeArch(5, 3, {7, 37, 3}), 9},                        // odd sizes, Cin > one 16-channel tile
  };
  unsigned seed = 5;
  for (const Case& c : cases) {
    GeneratorWeights w = randomGeneratorWeights(c.arch, seed++);
    std::vector<float> z = randomLatents(c.count, c.arch.latentDim, seed++), cond = condFor(c.arch);
    const size_t R = size_t(c.arch.outputResolution());
    std::vector<float> ref(c.count * size_t(c.arch.outChannels()) * R * R);
    generatorForward(w, z, cond, c.count, ref);
    GeneratorGpuModel model(*ctx, w);
    for (GeneratorKernel k : {GeneratorKernel::RowStrip, GeneratorKernel::Tiled}) {
      std::vector<float> got = pass.run(model, z, cond, c.count, k);
      ASSERT_EQ(got.size(), ref.size());
      double e = relMaxError(got, ref);
      std::printf("  %s R=%zu layers=%d probes=%zu: max rel error %.2e\n", generatorKernelName(k), R,
                  c.arch.layers(), c.count, e);
      EXPECT_LT(e, 1e-5) << generatorKernelName(k) << " R=" << R;
    }
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// One resident model and one scratch serve batches of different sizes (the zero borders must survive),
// recorded into a single submission; a model with fewer channels reuses a larger scratch.
TEST(GpuGenerator, ScratchIsReusedAcrossBatchesAndModels) {
  auto ctx = createContext();
  GeneratorDecodePass pass(*ctx);
  GeneratorArch big = makeArch(8, 3, {16, 12, kGeneratorChannels}),
                small = makeArch(8, 3, {8, 4, kGeneratorChannels});
  GeneratorWeights wb = randomGeneratorWeights(big, 21), ws = randomGeneratorWeights(small, 22);
  GeneratorGpuModel mb(*ctx, wb), ms(*ctx, ws);
  GeneratorScratch scratch(*ctx, big, 16);
  const size_t R = 16, per = size_t(kGeneratorChannels) * R * R;
  const uint32_t counts[] = {16, 5, 11};
  std::vector<float> cond = condFor(big);
  std::vector<std::vector<float>> z;
  std::vector<Buffer> lat, out;
  for (size_t i = 0; i < 3; ++i) {
    z.push_back(randomLatents(counts[i], 8, 30 + unsigned(i)));
    lat.push_back(createStorageBuffer(*ctx, z.back().size() * sizeof(float)));
    upload<float>(*ctx, lat.back(), z.back());
    out.push_back(createStorageBuffer(*ctx, counts[i] * per * sizeof(float)));
  }
  submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
    pass.record(cmd, mb, scratch, lat[0], cond, counts[0], out[0], GeneratorKernel::RowStrip);
    pass.record(cmd, ms, scratch, lat[1], cond, counts[1], out[1], GeneratorKernel::Tiled);
    pass.record(cmd, mb, scratch, lat[2], cond, counts[2], out[2], GeneratorKernel::RowStrip);
  });
  for (size_t i = 0; i < 3; ++i) {
    const GeneratorWeights& w = i == 1 ? ws : wb;
    std::vector<float> ref(counts[i] * per), got(counts[i] * per);
    generatorForward(w, z[i], cond, counts[i], ref);
    readback<float>(*ctx, out[i], got);
    double e = relMaxError(got, ref);
    std::printf("  batch %zu (%u probes): max rel error %.2e\n", i, counts[i], e);
    EXPECT_LT(e, 1e-5) << "batch " << i;
  }
  EXPECT_THROW(pass.record(VK_NULL_HANDLE, mb, scratch, lat[0], cond, 17, out[0], GeneratorKernel::RowStrip),
               Error);
  EXPECT_THROW(pass.record(VK_NULL_HANDLE, mb, scratch, lat[0], {}, 16, out[0], GeneratorKernel::RowStrip),
               Error);
  GeneratorScratch tooSmall(*ctx, small, 16);
  EXPECT_THROW(pass.record(VK_NULL_HANDLE, mb, tooSmall, lat[0], cond, 16, out[0], GeneratorKernel::RowStrip),
               Error);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::gpu
