#include "gpu/probe_shading_pass.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include "core/error.h"

namespace lfgi::gpu {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// A field whose probe i has constant irradiance irr(position) in every direction, radiance = irr / pi, and
// distance moments (r, r^2 + var) everywhere.
ProbeField makeField(ProbeGrid grid, const std::function<glm::vec3(glm::vec3)>& irr, float r = 100.0f,
                     float var = 1.0f, int n = 4, int m = 4) {
  ProbeField f;
  f.grid = grid;
  f.resolution = n;
  f.irradianceResolution = m;
  const size_t count = size_t(grid.probeCount()), n2 = size_t(n * n), m2 = size_t(m * m);
  f.radiance.resize(count * n2 * 3);
  f.distance.resize(count * n2 * 2);
  f.irradiance.resize(count * m2 * 3);
  for (size_t i = 0; i < count; ++i) {
    const glm::vec3 e = irr(f.probePosition(int64_t(i)));
    for (size_t t = 0; t < m2; ++t)
      for (int c = 0; c < 3; ++c) f.irradiance[(i * m2 + t) * 3 + size_t(c)] = e[c];
    for (size_t t = 0; t < n2; ++t) {
      for (int c = 0; c < 3; ++c) f.radiance[(i * n2 + t) * 3 + size_t(c)] = e[c] / kPi;
      f.distance[(i * n2 + t) * 2] = r;
      f.distance[(i * n2 + t) * 2 + 1] = r * r + var;
    }
  }
  return f;
}

// Lambertian points at given positions and normals, viewed from `eye`.
GBufferHost points(const std::vector<glm::vec3>& p, const std::vector<glm::vec3>& n, glm::vec3 albedo) {
  GBufferHost g;
  g.width = int(p.size());
  g.height = 1;
  for (size_t k = 0; k < p.size(); ++k) {
    g.position.push_back(glm::vec4(p[k], 1.0f));
    g.normal.push_back(glm::vec4(n[k], 1.0f));
    g.albedo.push_back(glm::vec4(albedo, 0.0f));
    g.emission.push_back(glm::vec4(0.0f));
  }
  return g;
}

struct Harness {
  std::unique_ptr<Context> ctx = createContext();
  GpuScene scene = buildGpuScene({}, {}, {}, {});
  GpuSceneBuffers sceneBuffers = uploadGpuScene(*ctx, scene);
  ProbeShadingPass pass{*ctx};

  ShadeOutputHost shade(const std::vector<const ProbeField*>& fields, const GBufferHost& g, glm::vec3 eye,
                        const ShadingOptions& o, const shared::SkyParams& sky = {}) {
    std::vector<ShadingCellInput> in;
    for (const ProbeField* f : fields) in.push_back({f, {}});
    pass.setProbes(packShadingProbes(in, 1));
    const shared::GpuCamera cam = makeGpuCamera(eye, eye + glm::vec3(0.0f, 0.0f, -1.0f), 60.0f, g.width, g.height);
    pass.setView(sky, cam, g.width, g.height, sceneBuffers, o);
    GBuffer gb = createGBuffer(*ctx, g.width, g.height);
    writeGBuffer(*ctx, g, gb);
    ShadeOutput out = createShadeOutput(*ctx, g.width, g.height);
    submitAndWait(*ctx, [&](VkCommandBuffer cmd) { pass.record(cmd, sceneBuffers, gb, out); });
    return readShadeOutput(*ctx, out);
  }
};

// Constant irradiance E everywhere: whatever the weights, indirect diffuse = albedo / pi * E.
TEST(ProbeShading, ConstantFieldGivesAlbedoOverPiTimesE) {
  Harness h;
  const ProbeField f = makeField({glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(3, 3, 3)},
                                 [](glm::vec3) { return glm::vec3(2.0f, 4.0f, 8.0f); });
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 2.0f), s(-1.0f, 1.0f);
  std::vector<glm::vec3> p, n;
  for (int k = 0; k < 64; ++k) {
    p.push_back(glm::vec3(u(rng), u(rng), u(rng)));
    n.push_back(glm::normalize(glm::vec3(s(rng), s(rng), s(rng)) + glm::vec3(0.0f, 1e-3f, 0.0f)));
  }
  const glm::vec3 albedo(0.5f, 0.25f, 1.0f);
  const ShadeOutputHost r = h.shade({&f}, points(p, n, albedo), glm::vec3(1.0f, 1.0f, 5.0f), ShadingOptions{});
  for (size_t k = 0; k < p.size(); ++k)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(r.diffuse[k][c], albedo[c] / kPi * glm::vec3(2.0f, 4.0f, 8.0f)[c], 1e-5f) << k;
  EXPECT_EQ(h.ctx->validationErrors.load(), 0u);
}

// Irradiance linear in x over two cells that share a lattice (A: x probes 0..3, B: 4..7): with
// visibility and backface weights off, trilinear interpolation reproduces E = 1 + x exactly, also in
// A's last interval [3, 4) where the corner probes at x = 4 belong to B. Without B, A clamps there.
TEST(ProbeShading, LinearFieldIsExactAcrossACellBorder) {
  Harness h;
  auto irr = [](glm::vec3 q) { return glm::vec3(1.0f + q.x); };
  const ProbeField a = makeField({glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 2)}, irr);
  const ProbeField b = makeField({glm::vec3(4.0f, 0.0f, 0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 2)}, irr);
  std::vector<glm::vec3> p, n;
  for (int k = 0; k < 50; ++k) {
    p.push_back(glm::vec3(0.1f + 0.135f * float(k), 0.3f + 0.01f * float(k % 7), 0.6f));
    n.push_back(glm::vec3(0.0f, 1.0f, 0.0f));
  }
  ShadingOptions o;
  o.chebyshev = false;
  o.backface = false;
  const glm::vec3 albedo(kPi);  // diffuse = E
  const ShadeOutputHost both = h.shade({&a, &b}, points(p, n, albedo), glm::vec3(3.0f, 5.0f, 5.0f), o);
  const ShadeOutputHost alone = h.shade({&a}, points(p, n, albedo), glm::vec3(3.0f, 5.0f, 5.0f), o);
  int inLastInterval = 0;
  for (size_t k = 0; k < p.size(); ++k) {
    EXPECT_NEAR(both.diffuse[k].x, 1.0f + p[k].x, 2e-4f * (1.0f + p[k].x)) << "x = " << p[k].x;
    if (p[k].x > 3.2f && p[k].x < 4.0f) {
      ++inLastInterval;
      EXPECT_NEAR(alone.diffuse[k].x, 4.0f, 1e-3f);  // clamped to A's last probe layer (x = 3)
    }
  }
  EXPECT_GT(inLastInterval, 3);
  EXPECT_EQ(h.ctx->validationErrors.load(), 0u);
}

// Two probes along x; the point sits between them, and probe 1's distance map says a wall is 0.2 m away
// in every direction (the point is 0.5 m away): Chebyshev visibility must all but remove probe 1.
TEST(ProbeShading, ChebyshevVisibilityRejectsAnOccludedProbe) {
  Harness h;
  ProbeField f = makeField({glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(2, 1, 1)},
                           [](glm::vec3 q) { return glm::vec3(q.x > 0.5f ? 100.0f : 1.0f); });
  const size_t n2 = 16;
  for (size_t t = 0; t < n2; ++t) {
    f.distance[(n2 + t) * 2] = 0.2f;
    f.distance[(n2 + t) * 2 + 1] = 0.2f * 0.2f + 1e-4f;
  }
  const GBufferHost g = points({glm::vec3(0.5f, 0.0f, 0.0f)}, {glm::vec3(0.0f, 1.0f, 0.0f)}, glm::vec3(kPi));
  ShadingOptions on;
  on.backface = false;
  on.normalBias = 0.0f;
  on.viewBias = 0.0f;
  ShadingOptions off = on;
  off.chebyshev = false;
  const float withVis = h.shade({&f}, g, glm::vec3(0.5f, 2.0f, 1.0f), on).diffuse[0].x;
  const float without = h.shade({&f}, g, glm::vec3(0.5f, 2.0f, 1.0f), off).diffuse[0].x;
  EXPECT_NEAR(without, 50.5f, 1e-3f);
  EXPECT_LT(withVis, 1.01f);
  EXPECT_GE(withVis, 1.0f);
}

// Direct sun on a Lambertian point: albedo / pi * E_sun * cos, and 0 under an occluder (shadow ray).
TEST(ProbeShading, SunIsShadowedThroughTheBvh) {
  Harness h;
  const ProbeField f = makeField({glm::vec3(-1.0f), glm::vec3(2.0f), glm::ivec3(2, 2, 2)},
                                 [](glm::vec3) { return glm::vec3(0.0f); });
  shared::SkyParams sky{};
  const glm::vec3 sunDir = glm::normalize(glm::vec3(0.3f, 1.0f, 0.0f));
  sky.sunDirection = glm::vec4(sunDir, 0.99999f);
  sky.sunIrradiance = glm::vec4(10.0f, 20.0f, 30.0f, 1.0f);
  // An occluder over the second point only.
  const std::vector<glm::vec3> pos{glm::vec3(1.5f, 1.0f, -1.0f), glm::vec3(3.5f, 1.0f, -1.0f),
                                   glm::vec3(2.5f, 1.0f, 1.0f)};
  const std::vector<uint32_t> idx{0, 1, 2}, mat{0};
  h.scene = buildGpuScene(pos, idx, mat, {shared::GpuMaterial{}});
  h.sceneBuffers = uploadGpuScene(*h.ctx, h.scene);
  const glm::vec3 albedo(0.5f);
  const ShadeOutputHost r =
      h.shade({&f}, points({glm::vec3(-0.5f, 0.0f, 0.0f), glm::vec3(2.0f, 0.0f, 0.0f)},
                           {glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f)}, albedo),
              glm::vec3(0.0f, 2.0f, 3.0f), ShadingOptions{}, sky);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(r.direct[0][c], 0.5f / kPi * sky.sunIrradiance[c] * sunDir.y, 1e-4f);
    EXPECT_EQ(r.direct[1][c], 0.0f);
  }
}

TEST(ProbeShading, InconsistentInputsAreErrors) {
  const ProbeField a = makeField({glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(2, 2, 2)}, [](glm::vec3) { return glm::vec3(1.0f); });
  const ProbeField b = makeField({glm::vec3(2.0f, 0.0f, 0.0f), glm::vec3(1.0f), glm::ivec3(2, 2, 2)},
                                 [](glm::vec3) { return glm::vec3(1.0f); }, 100.0f, 1.0f, 8, 4);
  const std::vector<ShadingCellInput> mixed{{&a, {}}, {&b, {}}};
  EXPECT_THROW(packShadingProbes(mixed, 1), Error);
  const std::vector<ShadingCellInput> none{{nullptr, {}}};
  EXPECT_THROW(packShadingProbes(none, 1), Error);
  const std::vector<float> wrong(5);
  const std::vector<ShadingCellInput> badSpec{{&a, wrong}};
  EXPECT_THROW(packShadingProbes(badSpec, 2), Error);
  const std::vector<ShadingCellInput> ok{{&a, {}}};
  EXPECT_THROW(packShadingProbes(ok, 0), Error);
}

}  // namespace
}  // namespace lfgi::gpu
