#include "gpu/program.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <vector>

#include "core/error.h"
#include "gpu/timing.h"
#include "shared/octahedral.h"

namespace lfgi::gpu {
namespace {

TEST(GpuProgram, ReflectsLayoutAndLocalSize) {
  auto ctx = createContext();
  Program p(*ctx, "octahedral_decode");
  const ShaderReflection& r = p.reflection();
  EXPECT_EQ(r.localSize[0], 8u);
  EXPECT_EQ(r.localSize[1], 8u);
  EXPECT_EQ(r.localSize[2], 1u);
  ASSERT_EQ(r.bindings.size(), 1u);
  EXPECT_EQ(r.bindings[0].binding, 0u);
  EXPECT_EQ(r.bindings[0].type, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  EXPECT_EQ(r.pushConstantBytes, sizeof(uint32_t));
}

// The GPU decode of every texel centre matches the C++ build of the same shared header within 1e-6
// (both are single-precision; the difference measures the device's normalize/division accuracy).
TEST(GpuProgram, OctahedralDecodeMatchesCpu) {
  auto ctx = createContext();
  Program p(*ctx, "octahedral_decode");
  for (uint32_t n : {1u, 2u, 7u, 16u, 33u, 128u}) {
    Buffer out = createStorageBuffer(*ctx, size_t{n} * n * sizeof(glm::vec4));
    submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
      dispatch(*ctx, cmd, p, {&out}, n, {n, n, 1});
      memoryBarrier(cmd);
    });
    std::vector<glm::vec4> gpu(size_t{n} * n);
    readback<glm::vec4>(*ctx, out, gpu);
    float worst = 0.0f;
    for (uint32_t y = 0; y < n; ++y) {
      for (uint32_t x = 0; x < n; ++x) {
        glm::vec3 cpu = shared::octTexelDirection(glm::uvec2(x, y), n);
        glm::vec3 g(gpu[y * n + x]);
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(cpu[c] - g[c]));
      }
    }
    EXPECT_LE(worst, 1e-6f) << "n=" << n;
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

TEST(GpuProgram, DispatchRejectsLayoutMismatch) {
  auto ctx = createContext();
  Program p(*ctx, "octahedral_decode");
  Buffer a = createStorageBuffer(*ctx, 64), b = createStorageBuffer(*ctx, 64);
  uint32_t n = 2;
  uint64_t wrongSize = 2;
  submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
    EXPECT_THROW(dispatch(*ctx, cmd, p, {&a, &b}, n, {2, 2, 1}), Error);
    EXPECT_THROW(dispatch(*ctx, cmd, p, {&a}, wrongSize, {2, 2, 1}), Error);
  });
}

TEST(GpuProgram, MissingShaderNamesThePath) {
  auto ctx = createContext();
  try {
    Program p(*ctx, "no_such_shader");
    FAIL() << "expected lfgi::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_shader.spv"), std::string::npos) << e.what();
  }
}

TEST(GpuProgram, ReflectionRejectsGarbage) {
  std::vector<uint32_t> notSpirv(16, 0x12345678u);
  EXPECT_THROW(reflectComputeShader(notSpirv, "garbage"), Error);
  std::vector<uint32_t> truncated = {0x07230203u, 0x00010500u};
  EXPECT_THROW(reflectComputeShader(truncated, "short"), Error);
}

TEST(GpuProgram, ShaderDirectoryOverride) {
  ::setenv("LFGI_SHADER_DIR", "/nonexistent-lfgi-shaders", 1);
  EXPECT_EQ(shaderDirectory(), std::filesystem::path("/nonexistent-lfgi-shaders"));
  ::unsetenv("LFGI_SHADER_DIR");
  EXPECT_TRUE(std::filesystem::exists(shaderDirectory() / "octahedral_decode.spv"));
}

TEST(GpuTimer, MeasuresPositiveTimeForWork) {
  auto ctx = createContext();
  Program p(*ctx, "octahedral_decode");
  const uint32_t n = 512;
  Buffer out = createStorageBuffer(*ctx, size_t{n} * n * sizeof(glm::vec4));
  GpuTimer timer(*ctx, 2);
  submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    dispatch(*ctx, cmd, p, {&out}, n, {n, n, 1});
    timer.stamp(cmd, 1);
  });
  double ms = timer.elapsedMs(0, 1);
  EXPECT_GT(ms, 0.0);
  EXPECT_LT(ms, 60'000.0);
  submitAndWait(*ctx, [&](VkCommandBuffer cmd) { EXPECT_THROW(timer.stamp(cmd, 2), Error); });
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::gpu
