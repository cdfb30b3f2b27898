// The leak scene is what every leak test measures against, so its promises are held here: the sealed room
// is sealed (no ray from inside escapes the house), the sunlit room is open to the sky, and the default
// lattice straddles the partition.
#include "worlds/leak_scene.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "worlds/triangle_bvh.h"

namespace lfgi::worlds {
namespace {

// Fraction of a Fibonacci sphere of rays from p that leave the house's box without a hit.
double escapeFraction(const TriangleBvh& bvh, glm::vec3 p, int rays) {
  int escaped = 0;
  for (int i = 0; i < rays; ++i) {
    const float z = 1.0f - 2.0f * (float(i) + 0.5f) / float(rays), rho = std::sqrt(1.0f - z * z);
    const float phi = 2.39996323f * float(i);
    if (!bvh.intersect(p, glm::vec3(rho * std::cos(phi), z, rho * std::sin(phi)), 50.0f)) ++escaped;
  }
  return double(escaped) / double(rays);
}

TEST(LeakScene, SealedRoomIsSealedAndSunlitRoomSeesTheSky) {
  for (float t : {0.05f, 0.1f, 0.5f}) {
    const LeakScene s = makeLeakScene(t);
    const TriangleBvh bvh(s.mesh);
    const glm::vec3 dark = 0.5f * (s.darkAir.min + s.darkAir.max), lit = 0.5f * (s.litAir.min + s.litAir.max);
    EXPECT_EQ(escapeFraction(bvh, dark, 4096), 0.0) << "t " << t;
    EXPECT_EQ(escapeFraction(bvh, dark + glm::vec3(-0.5f * s.darkAir.max.x + 0.3f, 1.2f, 1.5f), 4096), 0.0);
    EXPECT_GT(escapeFraction(bvh, lit, 4096), 0.02) << "t " << t;
    // The partition sits between the rooms: [-t / 2, t / 2] in x.
    EXPECT_NEAR(s.darkAir.min.x - s.litAir.max.x, t, 1e-6f);
  }
}

TEST(LeakScene, DefaultLatticeStraddlesThePartition) {
  const LeakScene s = makeLeakScene(0.1f);
  const ProbeGrid g = leakProbeGrid(s, 1.0f);
  bool below = false, above = false;
  for (int i = 0; i < g.dims.x; ++i) {
    const float x = g.origin.x + float(i) * g.spacing.x;
    EXPECT_GT(std::abs(x), 0.05f) << "a probe plane inside the partition at x " << x;
    below |= x < 0.0f;
    above |= x > 0.0f;
  }
  EXPECT_TRUE(below && above);
  EXPECT_LE(g.origin.x, s.house.min.x);
  EXPECT_GE(g.origin.x + float(g.dims.x - 1) * g.spacing.x, s.house.max.x);
  const ProbeGrid w = leakProbeGrid(s, 1.0f, true);
  bool onPlane = false;
  for (int i = 0; i < w.dims.x; ++i) onPlane |= std::abs(w.origin.x + float(i) * w.spacing.x) < 1e-5f;
  EXPECT_TRUE(onPlane);
}

TEST(LeakScene, RejectsBadSizes) {
  EXPECT_THROW(makeLeakScene(0.0f), Error);
  EXPECT_THROW(makeLeakScene(std::nanf("")), Error);
  EXPECT_THROW(leakProbeGrid(makeLeakScene(0.1f), -1.0f), Error);
}

}  // namespace
}  // namespace lfgi::worlds
