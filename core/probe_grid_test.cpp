#include "core/probe_grid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"

namespace lfgi {
namespace {

ProbeGrid testGrid() {
  return ProbeGrid{{-3.0f, 0.5f, 10.0f}, {2.0f, 1.5f, 4.0f}, {5, 3, 4}};
}

TEST(ProbeGrid, IndexRoundTripXFastest) {
  const ProbeGrid g = testGrid();
  g.validate();
  ASSERT_EQ(g.probeCount(), 60);
  for (std::int64_t i = 0; i < g.probeCount(); ++i) EXPECT_EQ(g.linearIndex(g.probeCoord(i)), i);
  EXPECT_EQ(g.linearIndex({1, 0, 0}), 1);
  EXPECT_EQ(g.linearIndex({0, 1, 0}), 5);
  EXPECT_EQ(g.linearIndex({0, 0, 1}), 15);
  EXPECT_EQ(g.probeCoord(59), glm::ivec3(4, 2, 3));
  EXPECT_EQ(g.probePosition({1, 2, 3}), glm::vec3(-1.0f, 3.5f, 22.0f));
}

TEST(ProbeGrid, ValidateRejectsBadGrids) {
  EXPECT_THROW((ProbeGrid{{0, 0, 0}, {1, 1, 1}, {0, 1, 1}}.validate()), Error);
  EXPECT_THROW((ProbeGrid{{0, 0, 0}, {1, 0, 1}, {1, 1, 1}}.validate()), Error);
  EXPECT_THROW((ProbeGrid{{0, NAN, 0}, {1, 1, 1}, {1, 1, 1}}.validate()), Error);
}

TEST(ProbeGrid, TrilinearWeightsSumToOneAndReproduceLinearFunctions) {
  const ProbeGrid g = testGrid();
  const glm::vec3 a(0.7f, -1.3f, 0.25f);
  const float b = 2.0f;
  auto f = [&](glm::vec3 p) { return glm::dot(a, p) + b; };
  std::mt19937 rng(3);
  const glm::vec3 lo = g.probePosition({0, 0, 0});
  const glm::vec3 hi = g.probePosition(g.dims - 1);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int k = 0; k < 10000; ++k) {
    const glm::vec3 p = lo + glm::vec3(u(rng), u(rng), u(rng)) * (hi - lo);
    const TrilinearProbes t = g.trilinear(p);
    float sum = 0.0f, value = 0.0f;
    for (int c = 0; c < 8; ++c) {
      ASSERT_GE(t.weights[c], 0.0f);
      ASSERT_LE(t.weights[c], 1.0f);
      ASSERT_EQ(t.indices[c], g.linearIndex(t.corners[c]));
      sum += t.weights[c];
      value += t.weights[c] * f(g.probePosition(t.corners[c]));
    }
    ASSERT_NEAR(sum, 1.0f, 1e-6f);
    ASSERT_NEAR(value, f(p), 1e-4f * (1.0f + std::abs(f(p))));
  }
  // Exactly on a probe (the last one on z and y too): all weight on it.
  for (const glm::ivec3 probe : {glm::ivec3(2, 1, 3), glm::ivec3(0, 0, 0), g.dims - 1}) {
    const TrilinearProbes t = g.trilinear(g.probePosition(probe));
    float onProbe = 0.0f;
    for (int c = 0; c < 8; ++c) onProbe += t.corners[c] == probe ? t.weights[c] : 0.0f;
    EXPECT_NEAR(onProbe, 1.0f, 1e-6f);
  }
}

TEST(ProbeGrid, TrilinearClampsOutsideTheGrid) {
  const ProbeGrid g = testGrid();
  const glm::vec3 far(-100.0f, 1000.0f, 0.0f);  // below x, above y, below z
  const TrilinearProbes t = g.trilinear(far);
  float sum = 0.0f;
  glm::vec3 blended(0.0f);
  for (int c = 0; c < 8; ++c) {
    EXPECT_TRUE(glm::all(glm::greaterThanEqual(t.corners[c], glm::ivec3(0))));
    EXPECT_TRUE(glm::all(glm::lessThan(t.corners[c], g.dims)));
    sum += t.weights[c];
    blended += t.weights[c] * g.probePosition(t.corners[c]);
  }
  EXPECT_NEAR(sum, 1.0f, 1e-6f);
  // The clamped point is the nearest probe-hull point: probe (0, dims.y - 1, 0).
  const glm::vec3 expected = g.probePosition({0, g.dims.y - 1, 0});
  EXPECT_NEAR(blended.x, expected.x, 1e-5f);
  EXPECT_NEAR(blended.y, expected.y, 1e-5f);
  EXPECT_NEAR(blended.z, expected.z, 1e-5f);
  // A one-probe axis: every corner on that axis is probe 0 and weights still sum to 1.
  const ProbeGrid flat{{0, 0, 0}, {1, 1, 1}, {4, 1, 4}};
  const TrilinearProbes tf = flat.trilinear({1.5f, 7.0f, 2.25f});
  float flatSum = 0.0f;
  for (int c = 0; c < 8; ++c) {
    EXPECT_EQ(tf.corners[c].y, 0);
    flatSum += tf.weights[c];
  }
  EXPECT_NEAR(flatSum, 1.0f, 1e-6f);
}

TEST(ProbeGrid, OwnershipIsHalfOpen) {
  const ProbeGrid a{{0.0f, 0.0f, 0.0f}, {0.75f, 1.25f, 0.5f}, {8, 4, 16}};
  ProbeGrid b = a;
  b.origin.x = a.boxMax().x;  // the neighbour along +X
  ProbeGrid c = a;
  c.origin.z = a.boxMax().z;  // the neighbour along +Z
  EXPECT_TRUE(a.owns(a.origin));
  EXPECT_FALSE(a.owns(a.boxMax()));
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int k = 0; k < 1000; ++k) {
    // Points exactly on the shared faces, and on random points of either box.
    const glm::vec3 onFaceX(a.boxMax().x, u(rng) * a.boxMax().y, u(rng) * a.boxMax().z);
    EXPECT_NE(a.owns(onFaceX), b.owns(onFaceX));
    EXPECT_TRUE(b.owns(onFaceX));
    const glm::vec3 onFaceZ(u(rng) * a.boxMax().x, u(rng) * a.boxMax().y, a.boxMax().z);
    EXPECT_NE(a.owns(onFaceZ), c.owns(onFaceZ));
    const glm::vec3 p(u(rng) * 2.0f * a.boxMax().x, u(rng) * a.boxMax().y, u(rng) * a.boxMax().z);
    EXPECT_LE(int(a.owns(p)) + int(b.owns(p)), 1);
  }
  // Every probe of a belongs to a and not to b.
  for (std::int64_t i = 0; i < a.probeCount(); ++i) {
    const glm::vec3 p = a.probePosition(a.probeCoord(i));
    EXPECT_TRUE(a.owns(p));
    EXPECT_FALSE(b.owns(p));
  }
}

}  // namespace
}  // namespace lfgi
