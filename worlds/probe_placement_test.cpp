#include "worlds/probe_placement.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <random>

#include "core/error.h"

namespace lfgi::worlds {
namespace {

TEST(TriangleBvh, MatchesBruteForceClosestHit) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f);
  TriangleMesh m;
  uint32_t mat = m.addMaterial({});
  for (int i = 0; i < 3000; ++i) {
    glm::vec3 c(u(rng), u(rng), u(rng));
    m.addTriangle(c, c + glm::vec3(u(rng), u(rng), u(rng)) * 0.1f,
                  c + glm::vec3(u(rng), u(rng), u(rng)) * 0.1f, mat);
  }
  TriangleBvh bvh(m);
  auto dirs = fibonacciSphere(50);
  int hits = 0;
  for (int r = 0; r < 400; ++r) {
    glm::vec3 o(u(rng), u(rng), u(rng));
    glm::vec3 d = dirs[size_t(r) % dirs.size()];
    float best = INFINITY;
    for (size_t t = 0; t < m.triangleCount(); ++t) {  // brute force, same Moller-Trumbore maths
      glm::vec3 e1 = m.vertex(t, 1) - m.vertex(t, 0), e2 = m.vertex(t, 2) - m.vertex(t, 0);
      glm::vec3 p = glm::cross(d, e2);
      float det = glm::dot(e1, p);
      if (std::abs(det) < 1e-12f) continue;
      glm::vec3 s = o - m.vertex(t, 0);
      float uu = glm::dot(s, p) / det;
      glm::vec3 q = glm::cross(s, e1);
      float vv = glm::dot(d, q) / det;
      float tt = glm::dot(e2, q) / det;
      if (uu >= 0 && vv >= 0 && uu + vv <= 1 && tt > 1e-5f) best = std::min(best, tt);
    }
    auto hit = bvh.intersect(o, d);
    if (best == INFINITY) {
      EXPECT_FALSE(hit.has_value());
    } else {
      ASSERT_TRUE(hit.has_value());
      EXPECT_NEAR(hit->t, best, 1e-4f * best);
      ++hits;
    }
  }
  EXPECT_GT(hits, 20);
}

TEST(TriangleBvh, ReportsBackfaces) {
  TriangleMesh m;
  m.addBox({-1, -1, -1}, {1, 1, 1}, m.addMaterial({}));
  TriangleBvh bvh(m);
  auto inside = bvh.intersect({0, 0, 0}, {1, 0, 0});
  ASSERT_TRUE(inside);
  EXPECT_TRUE(inside->backface);
  EXPECT_FLOAT_EQ(inside->t, 1.0f);
  auto outside = bvh.intersect({-5, 0, 0}, {1, 0, 0});
  ASSERT_TRUE(outside);
  EXPECT_FALSE(outside->backface);
  EXPECT_FLOAT_EQ(outside->t, 4.0f);
  EXPECT_FALSE(bvh.intersect({-5, 0, 0}, {-1, 0, 0}));
}

struct Scene {
  TriangleMesh mesh;
  std::vector<Aabb> solids;
};

Scene testScene() {
  Scene s;
  Material terrain;
  terrain.category = SurfaceCategory::kTerrain;
  Material wall;
  wall.category = SurfaceCategory::kWall;
  uint32_t t = s.mesh.addMaterial(terrain), w = s.mesh.addMaterial(wall);
  s.mesh.addQuad({-200, 0, -200}, {-200, 0, 200}, {200, 0, 200}, {200, 0, -200}, t);  // faces +Y
  const Aabb boxes[] = {
      {{0.3f, 0.0f, 0.3f}, {9.7f, 7.3f, 9.7f}},     // a big solid block
      {{12.3f, 0.0f, 0.0f}, {12.9f, 5.0f, 16.0f}},  // a 0.6 m thick wall slab
  };
  for (const Aabb& b : boxes) {
    s.mesh.addBox(b.min, b.max, w);
    s.solids.push_back(b);
  }
  return s;
}

bool strictlyInside(const Aabb& b, glm::vec3 p) {
  return p.x > b.min.x && p.x < b.max.x && p.y > b.min.y && p.y < b.max.y && p.z > b.min.z && p.z < b.max.z;
}

TEST(ProbePlacement, NoActiveProbeInsideSolid) {
  Scene s = testScene();
  TriangleBvh bvh(s.mesh);
  ProbeGrid grid = cellProbeGrid({-16.0f, -16.0f}, 32.0f, 2.0f, -1.0f, 8.0f);
  int initiallyInside = 0;
  for (int64_t i = 0; i < grid.probeCount(); ++i)
    for (const Aabb& b : s.solids)
      initiallyInside += strictlyInside(b, grid.probePosition(grid.probeCoord(i)));
  ASSERT_GT(initiallyInside, 40) << "the test must start with probes inside solids";

  PlacedProbes placed = placeProbes(s.mesh, bvh, grid);
  EXPECT_EQ(placed.active + placed.disabled, size_t(grid.probeCount()));
  size_t checked = 0;
  for (int64_t i = 0; i < grid.probeCount(); ++i) {
    if (placed.flags[size_t(i)] & kProbeDisabledSolid) continue;
    glm::vec3 p = placed.position(i);
    for (const Aabb& b : s.solids)
      EXPECT_FALSE(strictlyInside(b, p)) << "probe " << i << " at " << p.x << "," << p.y << "," << p.z;
    EXPECT_GE(p.y, 0.0f) << "probe " << i << " below the terrain";
    EXPECT_LE(glm::length(placed.offsets[size_t(i)]), 0.45f * 2.0f + 1e-5f);
    ++checked;
  }
  EXPECT_GT(checked, 500u);
  EXPECT_GT(placed.relocated, 0u);
  EXPECT_GT(placed.disabled, 0u);
  std::printf("probes %lld: active %zu, relocated %zu, disabled %zu, sky-only %zu\n",
              (long long)grid.probeCount(), placed.active, placed.relocated, placed.disabled, placed.skyOnly);
}

TEST(ProbePlacement, DeepInsideIsDisabledAndOpenFieldIsSkyOnly) {
  Scene s = testScene();
  TriangleBvh bvh(s.mesh);
  ProbeGrid grid = cellProbeGrid({-32.0f, -32.0f}, 64.0f, 4.0f, 0.0f, 8.0f);
  PlacedProbes placed = placeProbes(s.mesh, bvh, grid);
  // An open field far from the buildings: everything sees sky and terrain only.
  ProbeGrid field = cellProbeGrid({-192.0f, -192.0f}, 64.0f, 8.0f, 0.0f, 8.0f);
  PlacedProbes open = placeProbes(s.mesh, bvh, field);
  EXPECT_EQ(open.skyOnly, size_t(field.probeCount()));
  EXPECT_EQ(open.disabled, 0u);
  for (int64_t i = 0; i < grid.probeCount(); ++i) {
    glm::vec3 p = grid.probePosition(grid.probeCoord(i));
    if (p == glm::vec3(4.0f, 4.5f, 4.0f)) {
      EXPECT_TRUE(placed.flags[size_t(i)] & kProbeDisabledSolid);
    }
    if (p.x > 0.0f && p.x < 12.0f && p.z > 0.0f && p.z < 10.0f && p.y < 7.0f) {
      EXPECT_FALSE(placed.flags[size_t(i)] & kProbeSkyOnly);
    }
  }
}

TEST(ProbePlacement, Deterministic) {
  Scene s = testScene();
  TriangleBvh bvh(s.mesh);
  ProbeGrid grid = cellProbeGrid({-16.0f, -16.0f}, 32.0f, 2.0f, 0.0f, 8.0f);
  PlacedProbes a = placeProbes(s.mesh, bvh, grid), b = placeProbes(s.mesh, bvh, grid);
  EXPECT_EQ(a.flags, b.flags);
  EXPECT_EQ(0, std::memcmp(a.offsets.data(), b.offsets.data(), a.offsets.size() * sizeof(glm::vec3)));
}

TEST(ProbePlacement, SpacingFromDensity) {
  EXPECT_EQ(chooseProbeSpacing(4096.0, 4096.0), 8.0f);  // open land
  EXPECT_EQ(chooseProbeSpacing(4 * 4096.0, 4096.0), 4.0f);
  EXPECT_EQ(chooseProbeSpacing(16 * 4096.0, 4096.0), 2.0f);  // interiors
  EXPECT_EQ(chooseProbeSpacing(1e9, 4096.0), 1.0f);
  EXPECT_EQ(chooseProbeSpacing(0.0, 4096.0), 8.0f);
  EXPECT_THROW(chooseProbeSpacing(1.0, 0.0), Error);
}

TEST(ProbePlacement, CellGridOwnsExactlyTheCell) {
  ProbeGrid g = cellProbeGrid({64.0f, 128.0f}, 64.0f, 4.0f, 10.0f, 20.0f);
  EXPECT_EQ(g.dims.x, 16);
  EXPECT_EQ(g.dims.z, 16);
  EXPECT_TRUE(g.owns({64.0f, 12.0f, 128.0f}));
  EXPECT_FALSE(g.owns({128.0f, 12.0f, 150.0f}));  // the next cell's origin
  EXPECT_GE(g.origin.y + float(g.dims.y - 1) * 4.0f, 20.0f + 4.0f - 1e-4f);
  EXPECT_THROW(cellProbeGrid({0, 0}, 64.0f, 3.0f, 0.0f, 1.0f), Error);
}

}  // namespace
}  // namespace lfgi::worlds
