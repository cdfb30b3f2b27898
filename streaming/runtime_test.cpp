// The public runtime API (include/lfgi/runtime.h) as a host sees it: the test binary links lfgi::runtime
// (the shared library) for the API and lfgi_core / lfgi_worlds only to write its test world.
#include "lfgi/runtime.h"
#include "lfgi/runtime_vulkan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <mutex>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/cell_file.h"
#include "core/cell_store.h"
#include "core/half.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/gbuffer_pass.h"
#include "worlds/world_cells.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kSeed = 5;
constexpr float kCell = 32.0f;
constexpr float kRadiance = 0.75f;  // every cell's SH: constant radiance -> irradiance pi * L

// A 2 x 2 world of 32 m cells, each an SH-only cell (4 x 2 x 4 probes, 7 m apart) of constant radiance.
fs::path makeWorld(const std::string& name) {
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "runtime" / name;
  fs::remove_all(dir);
  fs::create_directories(dir / "baked" / "cells");
  worlds::writeWorldManifest(dir, worlds::WorldParams{kSeed, 2 * kCell, kCell});
  const float l0 =
      kRadiance / 0.28209479f;  // SH L0 coefficient of constant radiance (Y00 = 1 / (2 sqrt(pi)))
  for (int z = 0; z < 2; ++z)
    for (int x = 0; x < 2; ++x) {
      CellFile c;
      c.worldSeed = kSeed;
      c.cellX = x;
      c.cellZ = z;
      c.grid.origin = {float(x) * kCell + 2.0f, 0.5f, float(z) * kCell + 2.0f};
      c.grid.spacing = glm::vec3(7.0f);
      c.grid.dims = {4, 2, 4};
      c.fallback.shHalf.assign(12, floatToHalfClamped(0.0f));
      for (int ch = 0; ch < 3; ++ch) c.fallback.shHalf[size_t(ch)] = floatToHalfClamped(l0);
      c.stats.model = "no network: SH L1";
      writeCellFile(dir / "baked" / "cells" / cellFileName({x, z}), c);
    }
  return dir;
}

std::string errorOf(const RuntimeConfig& c) {
  try {
    Runtime::open(c);
  } catch (const RuntimeError& e) {
    return e.what();
  }
  return "";
}

TEST(Runtime, StreamsABakedWorldAndSamplesItsLight) {
  RuntimeConfig c;
  c.world = makeWorld("stream");
  c.ioThreads = 0;  // deterministic: loads inline in update()
  c.decodeRadius = 40.0f;
  c.keepRadius = 60.0f;
  const std::unique_ptr<Runtime> rt = Runtime::open(c);
  EXPECT_EQ(rt->worldSizeX(), 2 * kCell);
  EXPECT_EQ(rt->cellSize(), kCell);
  Frame f;
  f.position[0] = 20.0f, f.position[1] = 10.0f, f.position[2] = 20.0f;
  FrameReport r;
  for (int i = 0; i < 120; ++i) r = rt->update(f);
  EXPECT_EQ(r.residentCells, 4);
  EXPECT_EQ(r.failedCells, 0);
  EXPECT_GT(r.bytesResident, 0u);
  EXPECT_LE(r.bytesResident, c.memoryBudgetBytes);
  const std::vector<float> pos = {10.0f, 2.0f, 10.0f, 50.0f, 3.0f, 40.0f, -100.0f, 1.0f, 5.0f};
  const std::vector<float> nrm = {0.0f, 1.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
  std::vector<GiSample> out(3);
  rt->sample(pos, nrm, out);
  for (int i = 0; i < 2; ++i) {
    EXPECT_FALSE(out[size_t(i)].missing);
    EXPECT_LT(out[size_t(i)].fallbackWeight, 1e-6f);  // faded in: all from the decoded cells
    for (float e : out[size_t(i)].irradiance) EXPECT_NEAR(e, std::numbers::pi_v<float> * kRadiance, 0.01f);
  }
  EXPECT_TRUE(out[2].missing);  // outside the world
  // Sizes are checked.
  std::vector<GiSample> two(2);
  EXPECT_THROW(rt->sample(pos, nrm, two), RuntimeError);
  f.position[0] = std::nanf("");
  EXPECT_THROW(rt->update(f), RuntimeError);
}

TEST(Runtime, BadInputsGiveNamedErrors) {
  RuntimeConfig c;
  c.world = "/nonexistent/lfgi-world";
  EXPECT_NE(errorOf(c).find("/nonexistent/lfgi-world: no world.json"), std::string::npos) << errorOf(c);
  c.world = makeWorld("errors");
  RuntimeConfig b = c;
  b.memoryBudgetBytes = 0;
  EXPECT_NE(errorOf(b).find("memoryBudgetBytes is 0"), std::string::npos) << errorOf(b);
  b = c;
  b.memoryBudgetBytes = 16;  // less than one cell
  EXPECT_NE(errorOf(b).find("memoryBudgetBytes = 16 is smaller than one cell"), std::string::npos)
      << errorOf(b);
  b = c;
  b.decodeRadius = -1.0f;
  EXPECT_NE(errorOf(b).find("decodeRadius = -1"), std::string::npos) << errorOf(b);
  b = c;
  b.keepRadius = 10.0f;
  EXPECT_NE(errorOf(b).find("keepRadius = 10"), std::string::npos) << errorOf(b);
  b = c;
  b.ioThreads = 65;
  EXPECT_NE(errorOf(b).find("ioThreads = 65"), std::string::npos) << errorOf(b);
  // A world on a dead server is named, with visibility from geometry or without (port 9 on 127.0.0.1:
  // nothing listens).
  b = c;
  b.world = "http://127.0.0.1:9/world";
  for (bool vir : {true, false}) {
    b.virVisibility = vir;
    EXPECT_NE(errorOf(b).find("http://127.0.0.1:9/world/world.json: "), std::string::npos) << errorOf(b);
  }
  // A world that was never baked.
  fs::remove_all(c.world / "baked");
  EXPECT_NE(errorOf(c).find("no cell-file directory"), std::string::npos) << errorOf(c);
}

// The host's device as lfgi takes it (the test's own gpu::Context plays the host).
VulkanDevice hostDevice(const gpu::Context& ctx, std::mutex* queueMutex) {
  return {ctx.instance, ctx.physicalDevice,       ctx.device,
          ctx.queue,    ctx.queueFamily,          true,
          true,         ctx.features.shaderInt64, ctx.features.shaderBufferInt64Atomics,
          queueMutex};
}

template <typename F>
std::string errorText(F&& f) {
  try {
    f();
  } catch (const RuntimeError& e) {
    return e.what();
  }
  return "";
}

TEST(Runtime, ShadesOnAHostDeviceItNeverCreatesOrDestroys) {
  const std::unique_ptr<gpu::Context> host = gpu::createContext();
  std::mutex queueMutex;
  RuntimeConfig c;
  c.world = makeWorld("host_device");
  c.ioThreads = 0;
  c.decodeRadius = 40.0f;
  c.keepRadius = 60.0f;
  // The device features the contract names.
  VulkanDevice bad = hostDevice(*host, &queueMutex);
  bad.int64AtomicsEnabled = false;
  EXPECT_NE(errorText([&] { Runtime::open(c, bad); }).find("shaderBufferInt64Atomics"), std::string::npos);
  RuntimeConfig threaded = c;
  threaded.ioThreads = 2;
  EXPECT_NE(errorText([&] { Runtime::open(threaded, hostDevice(*host, nullptr)); }).find("queueMutex"),
            std::string::npos);
  {
    const std::unique_ptr<Runtime> rt = Runtime::open(c, hostDevice(*host, &queueMutex));
    bad = hostDevice(*host, &queueMutex);
    bad.pushDescriptorEnabled = false;
    EXPECT_NE(errorText([&] { VulkanShading::create(*rt, bad); }).find("VK_KHR_push_descriptor"),
              std::string::npos);
    bad = hostDevice(*host, &queueMutex);
    bad.maintenance4Enabled = false;
    EXPECT_NE(errorText([&] { VulkanShading::create(*rt, bad); }).find("maintenance4"), std::string::npos);
    const std::unique_ptr<VulkanShading> shading = VulkanShading::create(*rt, hostDevice(*host, &queueMutex));
    Frame f;
    f.position[0] = 20.0f, f.position[1] = 10.0f, f.position[2] = 20.0f;
    for (int i = 0; i < 120; ++i) {
      ASSERT_EQ(rt->update(f).failedCells, 0);
      shading->upload();
    }
    EXPECT_GT(shading->deviceBytes(), 0u);
    // A host G-buffer of 4 points in different cells, Lambertian white: diffuse = albedo / pi x pi L = L.
    gpu::GBufferHost g;
    g.width = 4;
    g.height = 1;
    for (glm::vec3 p :
         {glm::vec3(10, 2, 10), glm::vec3(50, 3, 40), glm::vec3(40, 5, 12), glm::vec3(9, 1, 55)}) {
      g.position.push_back(glm::vec4(p, 10.0f));
      g.normal.push_back(glm::vec4(0.0f, 1.0f, 0.0f, 1.0f));
      g.albedo.push_back(glm::vec4(1.0f, 1.0f, 1.0f, 0.0f));
      g.emission.push_back(glm::vec4(0.0f));
    }
    gpu::GBuffer gb = gpu::createGBuffer(*host, 4, 1);
    gpu::writeGBuffer(*host, g, gb);
    gpu::Buffer diffuse = gpu::createStorageBuffer(*host, 4 * sizeof(glm::vec4));
    const ShadeTarget target{4,
                             1,
                             gb.position.handle(),
                             gb.normal.handle(),
                             gb.albedo.handle(),
                             gb.emission.handle(),
                             diffuse.handle(),
                             VK_NULL_HANDLE};
    const View view{{30.0f, 20.0f, 30.0f}, {30.0f, 0.0f, 31.0f}, 60.0f};
    gpu::submitAndWait(*host, [&](VkCommandBuffer cmd) {  // the host's command buffer on its queue
      shading->record(cmd, target, view);
      gpu::memoryBarrier(cmd);
    });
    std::vector<glm::vec4> out(4);
    gpu::readback<glm::vec4>(*host, diffuse, out);
    for (const glm::vec4& v : out)
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(v[k], kRadiance, 0.01f);
    ShadeTarget noDiffuse = target;
    noDiffuse.diffuse = VK_NULL_HANDLE;
    EXPECT_NE(errorText([&] { shading->record(VK_NULL_HANDLE, noDiffuse, view); }).find("diffuse"),
              std::string::npos);
  }
  // lfgi is gone; the host's device is not: it still runs work, and no validation error was raised.
  gpu::Buffer b = gpu::createStorageBuffer(*host, 64);
  gpu::fillBuffer(*host, b, 7u);
  std::vector<uint32_t> words(16);
  gpu::readback<uint32_t>(*host, b, words);
  EXPECT_EQ(words[3], 7u);
  EXPECT_EQ(host->validationErrors.load(), 0u);
}

TEST(Runtime, ReportsItsVersion) {
  EXPECT_STREQ(runtimeVersion(), LFGI_TEST_PROJECT_VERSION);
}

}  // namespace
}  // namespace lfgi
