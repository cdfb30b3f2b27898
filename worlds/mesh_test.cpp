#include "worlds/mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/error.h"

namespace lfgi::worlds {
namespace {

TEST(TriangleMesh, BoxHasOutwardNormalsAndExactArea) {
  TriangleMesh m;
  uint32_t mat = m.addMaterial({});
  m.addBox({0, 0, 0}, {1, 2, 3}, mat);
  EXPECT_EQ(m.triangleCount(), 12u);
  EXPECT_DOUBLE_EQ(m.totalArea(), 2.0 * (1 * 2 + 2 * 3 + 1 * 3));
  glm::vec3 centre(0.5f, 1.0f, 1.5f);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    glm::vec3 mid = (m.vertex(t, 0) + m.vertex(t, 1) + m.vertex(t, 2)) / 3.0f;
    EXPECT_GT(glm::dot(m.faceNormal(t), mid - centre), 0.0f) << "triangle " << t << " faces inward";
  }
  m.validate("box");
}

TEST(TriangleMesh, InwardBoxFacesTheInside) {
  TriangleMesh m;
  m.addInwardBox({0, 0, 0}, {2, 2, 2}, m.addMaterial({}));
  EXPECT_EQ(m.triangleCount(), 12u);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    glm::vec3 mid = (m.vertex(t, 0) + m.vertex(t, 1) + m.vertex(t, 2)) / 3.0f;
    EXPECT_LT(glm::dot(m.faceNormal(t), mid - glm::vec3(1.0f)), 0.0f) << "triangle " << t << " faces outward";
  }
}

TEST(TriangleMesh, AppendReindexesMaterialsAndTextures) {
  TriangleMesh a, b;
  a.addTriangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, a.addMaterial({.name = "a"}));
  b.textures.push_back(Texture{1, 1, {255, 0, 0, 255}});
  Material mb{.name = "b"};
  mb.albedoTexture = 0;
  b.addTriangle({0, 0, 1}, {1, 0, 1}, {0, 1, 1}, b.addMaterial(mb));
  a.append(b);
  EXPECT_EQ(a.triangleCount(), 2u);
  EXPECT_EQ(a.triangleMaterial[1], 1u);
  EXPECT_EQ(a.materials[1].albedoTexture, 0);
  EXPECT_EQ(a.indices[3], 3u);
  a.validate("appended");
  EXPECT_FLOAT_EQ(a.textures[0].sampleLinear({0.3f, 0.7f}).r, 1.0f);
}

TEST(TriangleMesh, HashChangesWithAnyBitOfGeometry) {
  TriangleMesh m;
  m.addBox({0, 0, 0}, {1, 1, 1}, m.addMaterial({}));
  TriangleMesh same = m;
  EXPECT_EQ(m.contentHash(), same.contentHash());
  same.positions[5].y = std::nextafter(same.positions[5].y, 2.0f);
  EXPECT_NE(m.contentHash(), same.contentHash());
  TriangleMesh recoloured = m;
  recoloured.materials[0].albedo.g = 0.51f;
  EXPECT_NE(m.contentHash(), recoloured.contentHash());
}

TEST(TriangleMesh, ValidateNamesTheProblem) {
  TriangleMesh m;
  m.addTriangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, m.addMaterial({}));
  m.indices[2] = 7;
  try {
    m.validate("scene.glb");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("scene.glb: index 7"), std::string::npos) << e.what();
  }
  m.indices[2] = 2;
  m.triangleMaterial[0] = 3;
  EXPECT_THROW(m.validate("x"), Error);
  m.triangleMaterial[0] = 0;
  m.positions[0].x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(m.validate("x"), Error);
}

TEST(TriangleMesh, CategoryCounts) {
  TriangleMesh m;
  Material roadMat, roofMat;
  roadMat.category = SurfaceCategory::kRoad;
  roofMat.category = SurfaceCategory::kRoof;
  uint32_t road = m.addMaterial(roadMat);
  uint32_t roof = m.addMaterial(roofMat);
  m.addQuad({0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}, road);
  m.addTriangle({0, 1, 0}, {1, 1, 0}, {0, 1, 1}, roof);
  auto counts = m.categoryTriangleCounts();
  EXPECT_EQ(counts[size_t(SurfaceCategory::kRoad)], 2u);
  EXPECT_EQ(counts[size_t(SurfaceCategory::kRoof)], 1u);
  EXPECT_EQ(categoryName(SurfaceCategory::kRoof), "roof");
}

}  // namespace
}  // namespace lfgi::worlds
