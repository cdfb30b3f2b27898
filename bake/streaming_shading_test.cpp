// The GPU shading pass (gpu/probe_shading_pass.h) against the streaming manager's CPU view of the same
// cells (streaming::StreamingManager::sample()): resident cells mid cross-fade, resident cells fully faded in
// and cells on their SH L1 fallback, packed the way a renderer fed by the manager would pack them. Here in
// bake/ because gpu/ must not depend on streaming/ (and this binary already links both sides).
#include <gtest/gtest.h>

#include <map>
#include <numbers>
#include <random>

#include "gpu/gbuffer_pass.h"
#include "gpu/probe_shading_pass.h"
#include "streaming/streaming_manager.h"

namespace lfgi {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// With visibility and backface weights off the shading pass computes exactly sample()'s blend: trilinear
// over the probes of the owning cell and, in its last probe interval, the neighbour's first layer or
// fallback, each cell's probes weighted by its fade against the bilinear-over-cell-centres fallback.
TEST(StreamingShading, GpuMatchesStreamingSampleAcrossFadesAndFallbacks) {
  streaming::SyntheticSourceOptions so;
  so.layout = {{0.0f, 0.0f}, 32.0f, {4, 4}};
  so.probeSpacing = 8.0f;
  so.layers = 3;
  so.resolution = 4;
  so.irradianceResolution = 8;
  streaming::SyntheticCellSource source(so);
  streaming::StreamingConfig cfg;
  cfg.decodeRadius = 20.0f;
  cfg.keepRadius = 60.0f;
  cfg.ioThreads = 0;
  cfg.maxInlineLoadsPerFrame = 2;  // cells arrive on different frames: different fades
  cfg.maxActivationsPerFrame = 64;
  cfg.activateBudgetMs = 1e9;
  cfg.fadeSeconds = 0.5f;
  cfg.maxRelightsPerFrame = 0;
  streaming::StreamingManager manager(source, cfg);
  std::map<std::pair<int, int>, ProbeField> fields;
  manager.onActivate = [&](glm::ivec2 c, const ProbeField& f) { fields[{c.x, c.y}] = f; };
  streaming::FrameInput in;
  in.position = glm::vec3(40.0f, 10.0f, 40.0f);  // cell 1,1
  in.dtSeconds = 0.1f;
  for (int f = 0; f < 6; ++f) manager.update(in);

  std::vector<gpu::ShadingCellInput> cells;
  std::vector<ProbeField> boxes(16);
  int partial = 0, full = 0, fallbackOnly = 0;
  for (int z = 0; z < 4; ++z)
    for (int x = 0; x < 4; ++x) {
      gpu::ShadingCellInput c;
      c.fallback = source.fallback({x, z});
      if (manager.isResident({x, z})) {
        c.field = &fields.at({x, z});
        c.fade = manager.fade({x, z});
        (c.fade < 1.0f ? partial : full)++;
      } else {
        source.load({x, z}, boxes[size_t(z * 4 + x)]);  // only for the cell's box
        c.fallbackOnly = true;
        c.box = boxes[size_t(z * 4 + x)].grid;
        ++fallbackOnly;
      }
      cells.push_back(c);
    }
  ASSERT_GT(partial, 0);
  ASSERT_GT(full, 0);
  ASSERT_GT(fallbackOnly, 4);

  // Points everywhere, and many within one probe interval of a border (x or z near a multiple of 32).
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> u(0.0f, 128.0f), uy(0.6f, 20.0f), border(-8.0f, 8.0f);
  std::uniform_int_distribution<int> line(1, 3);
  std::normal_distribution<float> gauss;
  gpu::GBufferHost g;
  std::vector<glm::vec3> p, n;
  for (int k = 0; k < 600; ++k) {
    glm::vec3 q(u(rng), uy(rng), u(rng));
    if (k % 3 == 1) q.x = std::clamp(32.0f * float(line(rng)) + border(rng), 0.0f, 127.9f);
    if (k % 3 == 2) q.z = std::clamp(32.0f * float(line(rng)) + border(rng), 0.0f, 127.9f);
    glm::vec3 d(gauss(rng), gauss(rng), gauss(rng));
    d = glm::length(d) > 1e-3f ? glm::normalize(d) : glm::vec3(0.0f, 1.0f, 0.0f);
    p.push_back(q);
    n.push_back(d);
  }
  g.width = int(p.size());
  g.height = 1;
  for (size_t k = 0; k < p.size(); ++k) {
    g.position.push_back(glm::vec4(p[k], 1.0f));
    g.normal.push_back(glm::vec4(n[k], 1.0f));
    g.albedo.push_back(glm::vec4(glm::vec3(kPi), 0.0f));  // diffuse = irradiance
    g.emission.push_back(glm::vec4(0.0f));
  }

  auto ctx = gpu::createContext();
  const gpu::GpuScene scene = gpu::buildGpuScene({}, {}, {}, {});
  const gpu::GpuSceneBuffers sb = gpu::uploadGpuScene(*ctx, scene);
  gpu::ProbeShadingPass pass(*ctx);
  pass.setProbes(gpu::packShadingProbes(cells, 1));
  gpu::ShadingOptions o;
  o.chebyshev = false;
  o.backface = false;
  const glm::vec3 eye(64.0f, 200.0f, 64.0f);
  pass.setView({}, gpu::makeGpuCamera(eye, eye + glm::vec3(0.0f, 0.0f, -1.0f), 60.0f, g.width, 1), g.width, 1, sb, o);
  gpu::GBuffer gb = gpu::createGBuffer(*ctx, g.width, 1);
  gpu::writeGBuffer(*ctx, g, gb);
  gpu::ShadeOutput out = gpu::createShadeOutput(*ctx, g.width, 1);
  gpu::submitAndWait(*ctx, [&](VkCommandBuffer cmd) { pass.record(cmd, sb, gb, out); });
  const gpu::ShadeOutputHost r = gpu::readShadeOutput(*ctx, out);

  int mixed = 0, onFallback = 0;
  double worst = 0.0;
  for (size_t k = 0; k < p.size(); ++k) {
    const streaming::IrradianceSample s = manager.sample(p[k], n[k]);
    ASSERT_FALSE(s.missing);
    for (int c = 0; c < 3; ++c) {
      const float e = s.irradiance[c];
      EXPECT_NEAR(r.diffuse[k][c], e, 2e-4f * std::abs(e) + 1e-5f)
          << "point " << p[k].x << "," << p[k].y << "," << p[k].z << " channel " << c;
      worst = std::max(worst, double(std::abs(r.diffuse[k][c] - e) / std::max(std::abs(e), 1e-6f)));
    }
    EXPECT_NEAR(r.direct[k].w, s.fallbackWeight, 1e-5f) << p[k].x << "," << p[k].z;
    if (s.fallbackWeight > 0.0f && s.fallbackWeight < 1.0f) ++mixed;
    if (s.fallbackWeight == 1.0f) ++onFallback;
  }
  EXPECT_GT(mixed, 30);
  EXPECT_GT(onFallback, 100);
  RecordProperty("worst_relative_difference", std::to_string(worst));
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi
