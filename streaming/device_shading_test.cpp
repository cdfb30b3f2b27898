// streaming::DeviceShading (what `lfgi fly --render` and lfgi::VulkanShading draw with) against the streaming
// manager's CPU view of the same cells: resident cells and fallback-only cells of a baked world, each cell of
// its own constant radiance, so a cell packed into the wrong device slot, a stale slot or a wrong fallback
// shows as a wrong irradiance.
#include <gtest/gtest.h>

#include <filesystem>
#include <numbers>
#include <random>

#include "core/cell_file.h"
#include "core/cell_store.h"
#include "core/half.h"
#include "gpu/context.h"
#include "streaming/device_shading.h"
#include "worlds/world_cells.h"

namespace lfgi::streaming {
namespace {

namespace fs = std::filesystem;
// The probe lattice tiles the cell square, as the bake's placement does (4 x 8 m from the cell's corner).
constexpr float kCell = 32.0f, kSpacing = 8.0f;

// 3 x 3 SH-only cells (4 x 2 x 4 probes), cell (x, z) of constant radiance 0.25 (1 + x + 3 z).
fs::path makeWorld() {
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "device_shading";
  fs::remove_all(dir);
  fs::create_directories(dir / "baked" / "cells");
  worlds::writeWorldManifest(dir, worlds::WorldParams{7, 3 * kCell, kCell});
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) {
      CellFile c;
      c.worldSeed = 7;
      c.cellX = x;
      c.cellZ = z;
      c.grid.origin = {float(x) * kCell, 0.5f, float(z) * kCell};
      c.grid.spacing = glm::vec3(kSpacing);
      c.grid.dims = {4, 2, 4};
      const float l0 = 0.25f * float(1 + x + 3 * z) / 0.28209479f;  // Y00 = 1 / (2 sqrt(pi))
      c.fallback.shHalf.assign(12, floatToHalfClamped(0.0f));
      for (int ch = 0; ch < 3; ++ch) c.fallback.shHalf[size_t(ch)] = floatToHalfClamped(l0);
      c.stats.model = "no network: SH L1";
      writeCellFile(dir / "baked" / "cells" / cellFileName({x, z}), c);
    }
  return dir;
}

// Points inside each cell away from its last probe interval (where the pass and sample() blend towards the
// neighbour differently, bake/streaming_shading_test.cpp), albedo pi so the diffuse output is irradiance.
gpu::GBufferHost cellPoints() {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> local(0.5f, 3.0f * kSpacing - 0.5f), uy(1.0f, 9.0f);
  std::normal_distribution<float> gauss;
  gpu::GBufferHost g;
  g.width = 9 * 40;
  g.height = 1;
  for (int k = 0; k < g.width; ++k) {
    const int cell = k % 9;
    const glm::vec3 p{float(cell % 3) * kCell + local(rng), uy(rng), float(cell / 3) * kCell + local(rng)};
    glm::vec3 d(gauss(rng), gauss(rng), gauss(rng));
    d = glm::length(d) > 1e-3f ? glm::normalize(d) : glm::vec3(0.0f, 1.0f, 0.0f);
    g.position.push_back(glm::vec4(p, 1.0f));
    g.normal.push_back(glm::vec4(d, 1.0f));
    g.albedo.push_back(glm::vec4(glm::vec3(std::numbers::pi_v<float>), 0.0f));
    g.emission.push_back(glm::vec4(0.0f));
  }
  return g;
}

// The camera over cell 0,0, then over cell 2,2 (cells evicted, others loaded into freed device slots).
TEST(DeviceShading, ShadesWhatTheManagerSamplesInResidentAndFallbackCells) {
  CellFileSourceOptions so;
  so.worldDir = makeWorld();
  CellFileSource source(so);
  StreamingConfig cfg;
  cfg.decodeRadius = 40.0f;  // around a corner cell's centre: 4 cells resident, the rest fallback-only
  cfg.keepRadius = 60.0f;
  cfg.ioThreads = 0;
  cfg.activateBudgetMs = 1e9;
  StreamingManager manager(source, cfg);
  auto ctx = gpu::createContext();
  DeviceShading shading(*ctx, manager, source, cfg.keepRadius);
  const gpu::GBufferHost g = cellPoints();
  gpu::GBuffer gb = gpu::createGBuffer(*ctx, g.width, 1);
  gpu::writeGBuffer(*ctx, g, gb);
  gpu::ShadeOutput out = gpu::createShadeOutput(*ctx, g.width, 1);
  gpu::ShadingOptions o;
  o.chebyshev = false;
  o.backface = false;
  o.direct = false;
  o.sunShadows = false;
  for (const glm::vec3 camera : {glm::vec3(16.0f, 10.0f, 16.0f), glm::vec3(80.0f, 10.0f, 80.0f)}) {
    FrameInput in;
    in.position = camera;
    in.dtSeconds = 1.0f;  // fades complete
    for (int f = 0; f < 8; ++f) manager.update(in);
    int resident = 0;
    for (int z = 0; z < 3; ++z)
      for (int x = 0; x < 3; ++x) resident += manager.isResident({x, z});
    // 4 within decodeRadius; at the second camera the two kept by keepRadius too, and cell 0,0 dropped.
    ASSERT_EQ(resident, camera.x < 32.0f ? 4 : 6) << "camera " << camera.x << "," << camera.z;
    ASSERT_EQ(manager.isResident({0, 0}), camera.x < 32.0f);
    EXPECT_GT(shading.upload(camera), 0u);
    const glm::vec3 eye(48.0f, 200.0f, 48.0f);
    const shared::GpuCamera view =
        gpu::makeGpuCamera(eye, eye + glm::vec3(0.0f, 0.0f, -1.0f), 60.0f, g.width, 1);
    gpu::submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
      shading.recordShade(cmd, view, g.width, 1, 12.0f, 0.0f, shading.noScene(), o, gb, out);
    });
    const gpu::ShadeOutputHost r = gpu::readShadeOutput(*ctx, out);
    int fromProbes = 0, fromFallback = 0;
    for (size_t k = 0; k < size_t(g.width); ++k) {
      const glm::vec3 p(g.position[k]), n(g.normal[k]);
      const IrradianceSample s = manager.sample(p, n);
      ASSERT_FALSE(s.missing);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(r.diffuse[k][c], s.irradiance[c], 2e-4f * std::abs(s.irradiance[c]) + 1e-5f)
            << "camera " << camera.x << "," << camera.z << " point " << p.x << "," << p.y << "," << p.z;
      EXPECT_NEAR(r.direct[k].w, s.fallbackWeight, 1e-5f) << p.x << "," << p.z;
      fromProbes += s.fallbackWeight == 0.0f;
      fromFallback += s.fallbackWeight == 1.0f;
    }
    EXPECT_GT(fromProbes, 100);
    EXPECT_GT(fromFallback, 100);
  }
  EXPECT_GT(shading.deviceBytes(), 0u);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::streaming
