#include "bake/embree_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/error.h"

namespace lfgi::bake {
namespace {

worlds::TriangleMesh unitBox() {
  worlds::TriangleMesh mesh;
  const uint32_t m = mesh.addMaterial(worlds::Material{});
  mesh.addBox(glm::vec3(-1.0f), glm::vec3(1.0f), m);
  return mesh;
}

TEST(EmbreeScene, ClosestHitGivesDistanceFrontNormalAndSide) {
  const EmbreeScene scene(unitBox());
  const auto outside = scene.intersect(glm::vec3(-5.0f, 0.1f, 0.2f), glm::vec3(1.0f, 0.0f, 0.0f));
  ASSERT_TRUE(outside.has_value());
  EXPECT_NEAR(outside->t, 4.0f, 1e-6f);
  EXPECT_NEAR(outside->normal.x, -1.0f, 1e-6f);
  EXPECT_FALSE(outside->backface);
  const glm::vec3 h = scene.mesh().vertex(outside->triangle, 0);
  EXPECT_NEAR(h.x, -1.0f, 1e-6f);  // the hit triangle lies on the -X face

  const auto inside = scene.intersect(glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f));
  ASSERT_TRUE(inside.has_value());
  EXPECT_NEAR(inside->t, 1.0f, 1e-6f);
  EXPECT_NEAR(inside->normal.y, 1.0f, 1e-6f);  // front (outward) normal, seen from behind
  EXPECT_TRUE(inside->backface);
}

TEST(EmbreeScene, BarycentricsReconstructTheHitPoint) {
  worlds::TriangleMesh mesh;
  const uint32_t m = mesh.addMaterial(worlds::Material{});
  mesh.addTriangle({0, 0, 0}, {2, 0, 0}, {0, 0, 2}, m);
  const EmbreeScene scene(mesh);
  const glm::vec3 origin(0.5f, 3.0f, 0.25f);
  const auto hit = scene.intersect(origin, glm::vec3(0.0f, -1.0f, 0.0f));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->triangle, 0u);
  EXPECT_NEAR(hit->t, 3.0f, 1e-6f);
  const glm::vec3 p = (1.0f - hit->barycentric.x - hit->barycentric.y) * mesh.vertex(0, 0) +
                      hit->barycentric.x * mesh.vertex(0, 1) + hit->barycentric.y * mesh.vertex(0, 2);
  EXPECT_NEAR(p.x, 0.5f, 1e-6f);
  EXPECT_NEAR(p.z, 0.25f, 1e-6f);
  // (2,0,0) x (0,0,2) = (0,-4,0): the front faces down, so a ray going down sees the back.
  EXPECT_NEAR(hit->normal.y, -1.0f, 1e-6f);
  EXPECT_TRUE(hit->backface);
}

TEST(EmbreeScene, OcclusionRespectsTheRayInterval) {
  const EmbreeScene scene(unitBox());
  const glm::vec3 o(-5.0f, 0.0f, 0.0f), d(1.0f, 0.0f, 0.0f);
  EXPECT_TRUE(scene.occluded(o, d));
  EXPECT_FALSE(scene.occluded(o, d, 0.0f, 3.9f));
  EXPECT_TRUE(scene.occluded(o, d, 0.0f, 4.1f));
  EXPECT_FALSE(scene.occluded(o, -d));
  EXPECT_FALSE(scene.intersect(o, -d).has_value());
  EXPECT_FALSE(scene.intersect(o, d, 0.0f, 3.9f).has_value());
  // tNear skips the first face: the far face of the box is at t = 6.
  const auto far = scene.intersect(o, d, 4.5f);
  ASSERT_TRUE(far.has_value());
  EXPECT_NEAR(far->t, 6.0f, 1e-6f);
}

TEST(EmbreeScene, EmptyMeshMissesEverything) {
  const EmbreeScene scene{worlds::TriangleMesh{}};
  EXPECT_FALSE(scene.intersect(glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f)).has_value());
  EXPECT_FALSE(scene.occluded(glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f)));
}

TEST(EmbreeScene, InvalidMeshIsAnError) {
  worlds::TriangleMesh mesh = unitBox();
  mesh.indices[4] = 999;
  EXPECT_THROW(EmbreeScene{mesh}, Error);
  mesh = unitBox();
  mesh.positions[0].x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(EmbreeScene{mesh}, Error);
}

TEST(EmbreeScene, MovedSceneStillTraces) {
  EmbreeScene a(unitBox());
  EmbreeScene b(std::move(a));
  EXPECT_TRUE(b.occluded(glm::vec3(-5.0f, 0.0f, 0.0f), glm::vec3(1.0f, 0.0f, 0.0f)));
}

}  // namespace
}  // namespace lfgi::bake
