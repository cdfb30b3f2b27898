#include "worlds/topdown_preview.h"

#include <gtest/gtest.h>

#include <numbers>

#include "core/error.h"

namespace lfgi::worlds {
namespace {

// A white ground plane with a tall box on it, noon sun: lit ground has the Lambertian radiance
// albedo / pi * (E_sun cos + E_sky), the ground in the box's shadow only the sky term.
TEST(TopDownPreview, LambertianRadianceAndShadow) {
  TriangleMesh m;
  Material ground;
  ground.albedo = glm::vec3(0.5f);
  uint32_t g = m.addMaterial(ground);
  m.addQuad({-20, 0, -20}, {-20, 0, 20}, {20, 0, 20}, {20, 0, -20}, g);
  m.addBox({-1, 0, -1}, {1, 30, 1}, g);
  TriangleBvh bvh(m);
  SkyState st;
  st.timeOfDayHours = 10.0f;
  SkyModel sky = makeSky(st);
  Aabb region;
  region.extend({-20, 0, -20});
  region.extend({20, 30, 20});
  TopDownOptions opt;
  opt.width = 80;
  Image img = renderTopDown(m, bvh, sky, region, opt);
  ASSERT_EQ(img.width, 80);
  ASSERT_EQ(img.height, 80);
  const glm::vec3 skyUp = skyIrradianceUp(sky);
  const float lit = 0.5f / std::numbers::pi_v<float> * (sky.sun.irradiance({0, 1, 0}).g + skyUp.g);
  const float shadow = 0.5f / std::numbers::pi_v<float> * skyUp.g;
  // Corner pixel: open ground, lit.
  EXPECT_NEAR(img.at(2, 2, 1), lit, 1e-3f * lit);
  // The shadow falls away from the sun: step from the box along -sun.xz.
  glm::vec2 away = -glm::normalize(glm::vec2(sky.sun.direction.x, sky.sun.direction.z));
  glm::vec2 q = away * 3.0f;  // 3 m from the box centre, well inside a 30 m tall box's shadow
  int px = int((q.x + 20.0f) / 40.0f * 80.0f), py = int((q.y + 20.0f) / 40.0f * 80.0f);
  EXPECT_NEAR(img.at(px, py, 1), shadow, 1e-3f * shadow);
  EXPECT_GT(lit, 2.0f * shadow);  // clear sky at 10 h: sun + sky is ~3x the sky alone
  EXPECT_THROW(renderTopDown(m, bvh, sky, Aabb{}, opt), Error);
}

}  // namespace
}  // namespace lfgi::worlds
