#include "gpu/probe_shading_pass.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include "core/error.h"
#include "core/sh.h"

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
    return shadeCells(in, g, eye, o, sky);
  }
  ShadeOutputHost shadeCells(const std::vector<ShadingCellInput>& in, const GBufferHost& g, glm::vec3 eye,
                             const ShadingOptions& o, const shared::SkyParams& sky = {}) {
    pass.setProbes(packShadingProbes(in, 1));
    const shared::GpuCamera cam =
        makeGpuCamera(eye, eye + glm::vec3(0.0f, 0.0f, -1.0f), 60.0f, g.width, g.height);
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
  const ShadeOutputHost r =
      h.shade({&f}, points(p, n, albedo), glm::vec3(1.0f, 1.0f, 5.0f), ShadingOptions{});
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
  // B's layers at other heights (world cells place them per cell): x and z still match, so the corners at
  // x = 4 take B's own layers around each point's height with B's y weights; E = 1 + x + 2 y stays exact.
  auto irrY = [](glm::vec3 q) { return glm::vec3(1.0f + q.x + 2.0f * q.y); };
  const ProbeField ay = makeField({glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 2)}, irrY);
  const ProbeField by = makeField({glm::vec3(4.0f, 0.2f, 0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 2)}, irrY);
  const ShadeOutputHost shifted = h.shade({&ay, &by}, points(p, n, albedo), glm::vec3(3.0f, 5.0f, 5.0f), o);
  for (size_t k = 0; k < p.size(); ++k) {
    const float e = 1.0f + p[k].x + 2.0f * p[k].y;
    EXPECT_NEAR(shifted.diffuse[k].x, e, 2e-4f * e) << "x = " << p[k].x << ", y = " << p[k].y;
  }
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
      h.shade({&f},
              points({glm::vec3(-0.5f, 0.0f, 0.0f), glm::vec3(2.0f, 0.0f, 0.0f)},
                     {glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f)}, albedo),
              glm::vec3(0.0f, 2.0f, 3.0f), ShadingOptions{}, sky);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(r.direct[0][c], 0.5f / kPi * sky.sunIrradiance[c] * sunDir.y, 1e-4f);
    EXPECT_EQ(r.direct[1][c], 0.0f);
  }
}

// SH L1 radiance of a constant sky L (exact: shProject integrates a constant map exactly).
ShL1 constantSky(glm::vec3 L) {
  constexpr int n = 8;
  std::vector<float> map(size_t(n * n * 3));
  for (size_t t = 0; t < size_t(n * n); ++t)
    for (int c = 0; c < 3; ++c) map[t * 3 + size_t(c)] = L[c];
  return shProject<4>(map, n);
}

ShadingCellInput fullCell(const ProbeField& f, float fade, const ShL1& fallback) {
  ShadingCellInput c{&f, {}};
  c.fade = fade;
  c.fallback = fallback;
  return c;
}

ShadingCellInput fallbackCell(const ProbeGrid& box, const ShL1& fallback) {
  ShadingCellInput c;
  c.fallbackOnly = true;
  c.box = box;
  c.fallback = fallback;
  return c;
}

glm::vec3 unitVector(std::mt19937& rng) {
  std::normal_distribution<float> g;
  for (;;) {
    const glm::vec3 v(g(rng), g(rng), g(rng));
    if (glm::length(v) > 1e-3f) return glm::normalize(v);
  }
}

// Cell A (x in [0, 4), probes of constant irradiance E) next to cell B (x in [4, 8)) that is not resident:
// only its SH L1 fallback of a constant sky L. Checked per point, with albedo pi (diffuse = irradiance):
//   B beyond its centre (its +x neighbour is missing, so the fallback clamps to B): pi L, any normal;
//   B before its centre: bilinear between the cell centres, (1 - t) pi L_A + t pi L, t = 0.5 + (x - 4) / 4;
//   A before its last probe interval: exactly the result of shading A alone (the existing path);
//   A's last interval [3, 4): (1 - tx) E + tx (pi L_A + pi L) / 2 (the corners at x = 4 are B's fallback,
//   evaluated on the face as StreamingManager::sample() does), with visibility off;
// and the fallback share (ShadeOutput direct.w) 1 in B, tx in A's last interval, 0 before it.
TEST(ProbeShading, FallbackOnlyCellIsLitByItsShL1) {
  Harness h;
  const glm::vec3 E(1.5f, 2.0f, 2.5f), L(0.7f, 0.5f, 0.3f), LA(0.2f, 0.4f, 0.6f);
  const ProbeGrid gridA{glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 4)};
  const ProbeGrid gridB{glm::vec3(4.0f, 0.0f, 0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 4)};
  const ProbeField a = makeField(gridA, [&](glm::vec3) { return E; });
  std::mt19937 rng(11);
  std::vector<glm::vec3> p, n;
  for (int k = 0; k < 160; ++k) {
    p.push_back(glm::vec3(0.025f + 0.05f * float(k), 0.5f, 0.3f + 0.02f * float(k % 50)));
    n.push_back(unitVector(rng));
  }
  const GBufferHost g = points(p, n, glm::vec3(kPi));
  const glm::vec3 eye(4.0f, 6.0f, 6.0f);
  const std::vector<ShadingCellInput> cells{fullCell(a, 1.0f, constantSky(LA)),
                                            fallbackCell(gridB, constantSky(L))};
  ShadingOptions noVis;
  noVis.chebyshev = false;
  noVis.backface = false;
  const ShadeOutputHost r = h.shadeCells(cells, g, eye, ShadingOptions{});
  const ShadeOutputHost rNoVis = h.shadeCells(cells, g, eye, noVis);
  const ShadeOutputHost alone = h.shade({&a}, g, eye, ShadingOptions{});
  int inB = 0, inBNear = 0, inA = 0, inALast = 0;
  for (size_t k = 0; k < p.size(); ++k) {
    const float x = p[k].x;
    for (int c = 0; c < 3; ++c) {
      if (x >= 6.0f) {
        EXPECT_NEAR(r.diffuse[k][c], kPi * L[c], 1e-5f * kPi * L[c]) << "x = " << x << " channel " << c;
      } else if (x >= 4.0f) {
        const float t = 0.5f + (x - 4.0f) / 4.0f;
        const float expect = (1.0f - t) * kPi * LA[c] + t * kPi * L[c];
        EXPECT_NEAR(r.diffuse[k][c], expect, 1e-5f * expect) << "x = " << x;
      } else if (x < 3.0f) {
        EXPECT_NEAR(r.diffuse[k][c], alone.diffuse[k][c], 1e-6f * alone.diffuse[k][c]) << "x = " << x;
      } else {
        const float tx = x - 3.0f;
        const float expect = (1.0f - tx) * E[c] + tx * 0.5f * (kPi * LA[c] + kPi * L[c]);
        EXPECT_NEAR(rNoVis.diffuse[k][c], expect, 2e-5f * expect) << "x = " << x;
      }
    }
    const float share = r.direct[k].w;
    if (x >= 4.0f) {
      EXPECT_EQ(share, 1.0f) << x;
      EXPECT_EQ(r.diffuse[k].w, 0.0f) << x;  // no probe weight
    } else if (x < 3.0f) {
      EXPECT_EQ(share, 0.0f) << x;
    } else {
      EXPECT_NEAR(share, x - 3.0f, 1e-5f) << x;
    }
    (x >= 6.0f ? inB : x >= 4.0f ? inBNear : x < 3.0f ? inA : inALast)++;
  }
  EXPECT_GT(inB, 20);
  EXPECT_GT(inBNear, 20);
  EXPECT_GT(inA, 20);
  EXPECT_GT(inALast, 10);
  EXPECT_EQ(h.ctx->validationErrors.load(), 0u);
}

// Irradiance along a line across the border x = 4 (A full, E = 1 + 0.25 x, fallback pi L_A = 1.5), 2 cm
// steps, visibility and backface weights on: no step between neighbouring points beyond 0.03, with B
// full (fade 1: the field's own slope, 0.005 a step), B half faded in (fade 0.5) and B on its fallback
// (pi L_B = 4.7). The value changes by more than 1 between x = 3 (A's last probe layer) and just past the
// face: a seam there (the owning cell's clamped probes up to the face, the fallback after it) would be a
// step of that size; the border blend spreads it over one probe interval (<= 0.027 a step).
TEST(ProbeShading, NoJumpAcrossABorderToAFullOrFallbackNeighbour) {
  Harness h;
  auto irr = [](glm::vec3 q) { return glm::vec3(1.0f + 0.25f * q.x); };
  const ProbeGrid gridA{glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 2)};
  const ProbeGrid gridB{glm::vec3(4.0f, 0.0f, 0.0f), glm::vec3(1.0f), glm::ivec3(4, 2, 2)};
  const ProbeField a = makeField(gridA, irr), b = makeField(gridB, irr);
  const ShL1 fbA = constantSky(glm::vec3(1.5f / kPi)), fbB = constantSky(glm::vec3(1.5f));
  std::vector<glm::vec3> p, n;
  for (int k = 0; k <= 200; ++k) {
    p.push_back(glm::vec3(2.0f + 0.02f * float(k), 0.4f, 0.7f));
    n.push_back(glm::vec3(0.0f, 1.0f, 0.0f));
  }
  const GBufferHost g = points(p, n, glm::vec3(kPi));
  const glm::vec3 eye(4.0f, 5.0f, 5.0f);
  struct Line {
    float maxJump = 0.0f, change = 0.0f;  // change: |E(x = 4.02) - E(x = 3)|
  };
  auto line = [&](const std::vector<ShadingCellInput>& cells) {
    const ShadeOutputHost r = h.shadeCells(cells, g, eye, ShadingOptions{});
    Line l;
    for (size_t k = 1; k < p.size(); ++k)
      l.maxJump = std::max(l.maxJump, std::abs(r.diffuse[k].x - r.diffuse[k - 1].x));
    l.change = std::abs(r.diffuse[101].x - r.diffuse[50].x);  // x = 4.02 and x = 3.00
    return l;
  };
  const Line full = line({fullCell(a, 1.0f, fbA), fullCell(b, 1.0f, fbB)});
  const Line half = line({fullCell(a, 1.0f, fbA), fullCell(b, 0.5f, fbB)});
  const Line fallback = line({fullCell(a, 1.0f, fbA), fallbackCell(gridB, fbB)});
  // The other way round: A on its fallback, B resident. A's last interval blends its fallback (2.3 at
  // x = 3) into B's first probe layer (E = 2 at x = 4); the fallback at the face, 3.1, is 1.1 from it (the
  // step StreamingManager::sample() has there).
  const Line reverse = line({fallbackCell(gridA, fbA), fullCell(b, 1.0f, fbB)});
  EXPECT_LT(reverse.maxJump, 0.03f);
  EXPECT_LT(full.maxJump, 0.006f);
  EXPECT_LT(half.maxJump, 0.03f);
  EXPECT_LT(fallback.maxJump, 0.03f);
  EXPECT_GT(fallback.change, 1.0f);
  EXPECT_GT(half.change, 0.5f);
  RecordProperty("max_jump_full", std::to_string(full.maxJump));
  RecordProperty("max_jump_half", std::to_string(half.maxJump));
  RecordProperty("max_jump_fallback", std::to_string(fallback.maxJump));
  RecordProperty("max_jump_reverse", std::to_string(reverse.maxJump));
  EXPECT_EQ(h.ctx->validationErrors.load(), 0u);
}

// The cross-fade of one cell: fade 0 gives the image of the cell on its fallback alone (fallback-only),
// fade 1 the image of its probes alone (no fallback given), fade 0.5 their mean, in diffuse and specular
// (glossy points), with visibility on; and a constant sky L gives the same specular from probes holding
// radiance L as from its SH L1 fallback.
TEST(ProbeShading, FadeBlendsLinearlyFromFallbackToProbes) {
  Harness h;
  const ProbeGrid grid{glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(3, 3, 3)};
  const ProbeField f =
      makeField(grid, [](glm::vec3 q) { return glm::vec3(1.0f + q.x, 2.0f + q.y, 3.0f - q.z); });
  const glm::vec3 L(0.4f, 0.9f, 0.2f);
  const ShL1 sky = constantSky(L);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.05f, 2.95f);
  std::vector<glm::vec3> p, n;
  for (int k = 0; k < 64; ++k) {
    p.push_back(glm::vec3(u(rng), u(rng), u(rng)));
    n.push_back(unitVector(rng));
  }
  GBufferHost g = points(p, n, glm::vec3(0.6f, 0.5f, 0.4f));
  for (size_t k = 0; k < p.size(); k += 2) {
    g.normal[k].w = 0.3f;  // glossy metal: specular from probes / fallback
    g.albedo[k].w = 0.5f;
  }
  const glm::vec3 eye(1.5f, 6.0f, 5.0f);
  const ShadeOutputHost probesOnly = h.shadeCells({ShadingCellInput{&f, {}}}, g, eye, ShadingOptions{});
  const ShadeOutputHost fallbackOnly = h.shadeCells({fallbackCell(grid, sky)}, g, eye, ShadingOptions{});
  const ShadeOutputHost f0 = h.shadeCells({fullCell(f, 0.0f, sky)}, g, eye, ShadingOptions{});
  const ShadeOutputHost f1 = h.shadeCells({fullCell(f, 1.0f, sky)}, g, eye, ShadingOptions{});
  const ShadeOutputHost fh = h.shadeCells({fullCell(f, 0.5f, sky)}, g, eye, ShadingOptions{});
  int glossy = 0;
  for (size_t k = 0; k < p.size(); ++k) {
    for (int c = 0; c < 3; ++c) {
      const float d0 = fallbackOnly.diffuse[k][c], d1 = probesOnly.diffuse[k][c];
      EXPECT_NEAR(f0.diffuse[k][c], d0, 1e-5f * d0) << k;
      EXPECT_NEAR(f1.diffuse[k][c], d1, 1e-5f * d1) << k;
      EXPECT_NEAR(fh.diffuse[k][c], 0.5f * (d0 + d1), 1e-5f * (d0 + d1)) << k;
      const float s0 = fallbackOnly.specular[k][c], s1 = probesOnly.specular[k][c];
      EXPECT_NEAR(f0.specular[k][c], s0, 1e-5f * s0 + 1e-7f) << k;
      EXPECT_NEAR(f1.specular[k][c], s1, 1e-5f * s1 + 1e-7f) << k;
      EXPECT_NEAR(fh.specular[k][c], 0.5f * (s0 + s1), 1e-5f * (s0 + s1) + 1e-7f) << k;
    }
    EXPECT_NEAR(fh.direct[k].w, 0.5f, 1e-6f);
    EXPECT_GT(glm::length(glm::vec3(fh.diffuse[k])), 0.0f);
    if (k % 2 == 0) {
      ++glossy;
      EXPECT_GT(probesOnly.specular[k].x + probesOnly.specular[k].y + probesOnly.specular[k].z, 0.0f);
    }
  }
  EXPECT_GT(glossy, 20);
  // Constant sky: probes of radiance L (irradiance pi L) and the SH L1 of L give the same specular.
  const ProbeField flat = makeField(grid, [&](glm::vec3) { return kPi * L; });
  const ShadeOutputHost a = h.shadeCells({ShadingCellInput{&flat, {}}}, g, eye, ShadingOptions{});
  for (size_t k = 0; k < p.size(); k += 2)
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(fallbackOnly.specular[k][c], a.specular[k][c], 1e-5f * a.specular[k][c]) << k;
      EXPECT_NEAR(fallbackOnly.diffuse[k][c], a.diffuse[k][c], 1e-5f * a.diffuse[k][c]) << k;
    }
  EXPECT_EQ(h.ctx->validationErrors.load(), 0u);
}

TEST(ProbeShading, InconsistentInputsAreErrors) {
  const ProbeField a = makeField({glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(2, 2, 2)},
                                 [](glm::vec3) { return glm::vec3(1.0f); });
  const ProbeField b = makeField(
      {glm::vec3(2.0f, 0.0f, 0.0f), glm::vec3(1.0f), glm::ivec3(2, 2, 2)},
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
  ShadingCellInput fbWithField = fallbackCell(a.grid, ShL1{});
  fbWithField.field = &a;
  EXPECT_THROW(packShadingProbes(std::vector<ShadingCellInput>{fbWithField}, 1), Error);
  ShadingCellInput badBox = fallbackCell(ProbeGrid{glm::vec3(0.0f), glm::vec3(0.0f), glm::ivec3(2)}, ShL1{});
  EXPECT_THROW(packShadingProbes(std::vector<ShadingCellInput>{badBox}, 1), Error);
  for (float fade : {-0.1f, 1.5f, std::nanf("")})
    EXPECT_THROW(packShadingProbes(std::vector<ShadingCellInput>{fullCell(a, fade, ShL1{})}, 1), Error)
        << fade;
  ShL1 inf;
  inf.c[1].y = INFINITY;
  EXPECT_THROW(packShadingProbes(std::vector<ShadingCellInput>{fullCell(a, 1.0f, inf)}, 1), Error);
  // Fallback-only cells alone are fine (no probes uploaded).
  const ShadingProbeSet s = packShadingProbes(std::vector<ShadingCellInput>{fallbackCell(a.grid, ShL1{})}, 1);
  EXPECT_EQ(s.cells.size(), 1u);
  EXPECT_TRUE(s.probes.empty());
  // The fallback neighbour table: a 2 x 2 block of cells, each links its xz neighbours, clamped per axis.
  std::vector<ShadingCellInput> block;
  for (int z = 0; z < 2; ++z)
    for (int x = 0; x < 2; ++x)
      block.push_back(fallbackCell(
          ProbeGrid{glm::vec3(2.0f * float(x), 0.0f, 2.0f * float(z)), glm::vec3(1.0f), glm::ivec3(2)},
          ShL1{}));
  const ShadingProbeSet t = packShadingProbes(block, 1);
  auto entry = [&](int cell, int dx, int dz) {
    const int k = (dz + 1) * 3 + dx + 1;
    return t.cells[size_t(cell)].fallbackCells[k / 4][k % 4];
  };
  EXPECT_EQ(entry(0, 0, 0), 0);
  EXPECT_EQ(entry(0, 1, 0), 1);
  EXPECT_EQ(entry(0, 0, 1), 2);
  EXPECT_EQ(entry(0, 1, 1), 3);
  EXPECT_EQ(entry(0, -1, 0), 0);  // world edge in x: clamped to the cell itself
  EXPECT_EQ(entry(0, -1, 1), 2);  // x clamped, z kept
  EXPECT_EQ(entry(3, -1, -1), 0);
  EXPECT_EQ(entry(3, 1, -1), 1);  // x clamped at the +x edge
}

// Every cell on its fallback (nothing resident yet): the pass still shades every point, pi L.
TEST(ProbeShading, OnlyFallbackCellsStillLightEveryPoint) {
  Harness h;
  const glm::vec3 L(0.3f, 0.6f, 0.9f);
  const ProbeGrid box{glm::vec3(0.0f), glm::vec3(2.0f), glm::ivec3(2, 2, 2)};
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  std::vector<glm::vec3> p, n;
  for (int k = 0; k < 32; ++k) {
    p.push_back(glm::vec3(u(rng), u(rng), u(rng)));
    n.push_back(unitVector(rng));
  }
  const ShadeOutputHost r = h.shadeCells({fallbackCell(box, constantSky(L))}, points(p, n, glm::vec3(kPi)),
                                         glm::vec3(2.0f, 8.0f, 8.0f), {});
  for (size_t k = 0; k < p.size(); ++k) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.diffuse[k][c], kPi * L[c], 1e-5f * kPi * L[c]) << k;
    EXPECT_EQ(r.direct[k].w, 1.0f);
  }
  EXPECT_EQ(h.ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::gpu
