// The GPU shading pass (gpu/probe_shading_pass.h) against the streaming manager's CPU view of the same
// cells (streaming::StreamingManager::sample()): resident cells mid cross-fade, resident cells fully faded in
// and cells on their SH L1 fallback, packed the way a renderer fed by the manager would pack them. Here in
// bake/ because gpu/ must not depend on streaming/ (and this binary already links both sides).
#include <gtest/gtest.h>

#include <map>
#include <numbers>
#include <random>

#include "bake/shading_inputs.h"
#include "core/error.h"
#include "core/sh.h"
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
  in.position =
      glm::vec3(80.0f, 10.0f, 80.0f);  // cell 2,2: cells 1..3 resident, the x = 0 and z = 0 rows not
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
  pass.setView({}, gpu::makeGpuCamera(eye, eye + glm::vec3(0.0f, 0.0f, -1.0f), 60.0f, g.width, 1), g.width, 1,
               sb, o);
  gpu::GBuffer gb = gpu::createGBuffer(*ctx, g.width, 1);
  gpu::writeGBuffer(*ctx, g, gb);
  gpu::ShadeOutput out = gpu::createShadeOutput(*ctx, g.width, 1);
  gpu::submitAndWait(*ctx, [&](VkCommandBuffer cmd) { pass.record(cmd, sb, gb, out); });
  const gpu::ShadeOutputHost r = gpu::readShadeOutput(*ctx, out);

  // sample(), except in the last probe interval of a cell on its fallback before a resident neighbour:
  // there the pass blends into the neighbour's first layer (no step at the face) where sample() keeps the
  // fallback up to the face; the expected value is then sample() at the lattice planes around the point
  // (the cell's last layer, the face: the neighbour's first layer), bilinear in x and z.
  const streaming::WorldLayout& layout = manager.layout();
  int blended = 0;
  auto expected = [&](glm::vec3 q, glm::vec3 nn) {
    const glm::ivec2 a = layout.cellOf(q);
    const glm::vec2 lo = layout.cellMin(a);
    const float last = layout.cellSize - so.probeSpacing;
    glm::vec2 t(0.0f);
    for (int k = 0; k < 2; ++k) {
      const float local = (k == 0 ? q.x - lo.x : q.z - lo.y) - last;
      const glm::ivec2 next = a + (k == 0 ? glm::ivec2(1, 0) : glm::ivec2(0, 1));
      if (!manager.isResident(a) && local > 0.0f && layout.contains(next))
        t[k] = std::min(1.0f, local / so.probeSpacing);
    }
    if (t.x == 0.0f && t.y == 0.0f) return manager.sample(q, nn);
    ++blended;
    streaming::IrradianceSample sum;
    sum.fallbackWeight = 0.0f;
    for (int k = 0; k < 4; ++k) {
      const int dx = k & 1, dz = k >> 1;
      const float w = (dx ? t.x : 1.0f - t.x) * (dz ? t.y : 1.0f - t.y);
      if (w == 0.0f) continue;
      glm::vec3 plane = q;
      if (t.x > 0.0f) plane.x = lo.x + (dx ? layout.cellSize : last);
      if (t.y > 0.0f) plane.z = lo.y + (dz ? layout.cellSize : last);
      const streaming::IrradianceSample s = manager.sample(plane, nn);
      sum.irradiance += w * s.irradiance;
      sum.fallbackWeight += w * s.fallbackWeight;
    }
    return sum;
  };
  int mixed = 0, onFallback = 0;
  double worst = 0.0;
  for (size_t k = 0; k < p.size(); ++k) {
    const streaming::IrradianceSample s = expected(p[k], n[k]);
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
  EXPECT_GT(blended, 10);
  EXPECT_GT(onFallback, 100);
  RecordProperty("worst_relative_difference", std::to_string(worst));
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// The fallback `lfgi render --neighbours-fallback` gives a cell: the mean SH L1 of its active probes (the
// inactive ones, zero maps here, must not pull it down), from a sparse mask of columns.
TEST(StreamingShading, FieldFallbackIsTheMeanShL1OfActiveProbes) {
  ProbeField f;
  f.grid = {glm::vec3(0.0f), glm::vec3(2.0f), glm::ivec3(8, 3, 8)};
  f.resolution = 8;
  f.irradianceResolution = 4;
  const size_t P = size_t(f.grid.probeCount());
  f.radiance.assign(P * 64 * 3, 0.0f);
  f.distance.assign(P * 64 * 2, 1.0f);
  f.irradiance.assign(P * 16 * 3, 0.0f);
  f.active.assign(P, 0);
  for (size_t i = 0; i < P; i += 2) {  // active probes: constant radiance 1 or 3 (mean 2)
    f.active[i] = 1;
    const float L = (i / 2) % 2 == 0 ? 1.0f : 3.0f;
    for (int j = 0; j < 8; ++j)
      for (int k = 0; k < 8; ++k)
        for (int c = 0; c < 3; ++c) f.radiance[(i * 64 + size_t(j * 8 + k)) * 3 + size_t(c)] = L;
  }
  const ShL1 sh = bake::fieldFallback(f);
  for (const glm::vec3 n : {glm::vec3(0, 1, 0), glm::vec3(1, 0, 0), glm::vec3(0, 0, -1)})
    EXPECT_NEAR(shIrradiance(sh, n).x, 2.0f * kPi, 1e-4f);
  f.active.assign(P, 0);
  EXPECT_THROW(bake::fieldFallback(f), Error);

  std::vector<uint8_t> disabled(P, 0);
  disabled[size_t(f.grid.linearIndex({1, 0, 1}))] = 1;
  const std::vector<uint8_t> mask = bake::fallbackProbeMask(f.grid, disabled, 3);
  size_t count = 0;
  for (uint8_t m : mask) count += m;
  EXPECT_EQ(count, 3u * 3u * 3u - 1u);  // 3 x 3 columns x 3 layers, one inside solid
  EXPECT_EQ(mask[size_t(f.grid.linearIndex({1, 1, 1}))], 1);
  EXPECT_EQ(mask[size_t(f.grid.linearIndex({1, 0, 1}))], 0);
  EXPECT_EQ(mask[size_t(f.grid.linearIndex({0, 0, 0}))], 0);
  EXPECT_THROW(bake::fallbackProbeMask(f.grid, std::vector<uint8_t>(3), 3), Error);
}

}  // namespace
}  // namespace lfgi
