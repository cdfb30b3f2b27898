// See leak_scene.h.
#include "worlds/leak_scene.h"

#include <cmath>

#include "core/error.h"

namespace lfgi::worlds {

LeakScene makeLeakScene(float t, glm::vec3 panelRadiance) {
  if (!(t > 0.0f && t < 4.0f)) fail("leak scene: partition thickness {} m outside (0, 4)", t);
  LeakScene s;
  Material groundM, wallM, roofM;
  groundM.name = "ground";
  groundM.albedo = glm::vec3(0.3f);
  groundM.category = SurfaceCategory::kTerrain;
  wallM.name = "wall";
  wallM.albedo = glm::vec3(0.7f, 0.65f, 0.6f);
  wallM.category = SurfaceCategory::kWall;
  roofM.name = "roof";
  roofM.albedo = glm::vec3(0.5f);
  roofM.category = SurfaceCategory::kRoof;
  auto& m = s.mesh;
  const uint32_t g = m.addMaterial(groundM), w = m.addMaterial(wallM), r = m.addMaterial(roofM);
  const float h = 0.5f * t, W = 0.3f, H = 3.0f, y0 = -0.1f, xo = 4.0f + h + W;
  m.addBox({-12.0f, -1.0f, -10.0f}, {12.0f, 0.0f, 10.0f}, g);
  // South wall (z in [-2.3, -2]) with the lit room's opening x in [-3.5 - h, -0.8 - h], y < 2.4.
  m.addBox({-xo, y0, -2.3f}, {-3.5f - h, H, -2.0f}, w);
  m.addBox({-0.8f - h, y0, -2.3f}, {xo, H, -2.0f}, w);
  m.addBox({-3.5f - h, 2.4f, -2.3f}, {-0.8f - h, H, -2.0f}, w);
  m.addBox({-xo, y0, 2.0f}, {xo, H, 2.3f}, w);          // north
  m.addBox({-xo, y0, -2.0f}, {-4.0f - h, H, 2.0f}, w);  // west
  m.addBox({4.0f + h, y0, -2.0f}, {xo, H, 2.0f}, w);    // east
  m.addBox({-h, y0, -2.0f}, {h, H, 2.0f}, w);           // the partition
  // Roof with a skylight over the lit room next to the partition (x in [-2 - h, -0.4 - h], z in [-1, 1]).
  m.addBox({-xo, H, -2.3f}, {-2.0f - h, H + 0.25f, 2.3f}, r);
  m.addBox({-2.0f - h, H, -2.3f}, {-0.4f - h, H + 0.25f, -1.0f}, r);
  m.addBox({-2.0f - h, H, 1.0f}, {-0.4f - h, H + 0.25f, 2.3f}, r);
  m.addBox({-0.4f - h, H, -2.3f}, {xo, H + 0.25f, 2.3f}, r);
  if (panelRadiance != glm::vec3(0.0f)) {
    Material panel;
    panel.name = "panel";
    panel.albedo = glm::vec3(0.8f);
    panel.emission = panelRadiance;
    panel.category = SurfaceCategory::kEmissive;
    m.addBox({1.5f + h, 2.85f, -0.5f}, {2.5f + h, 2.95f, 0.5f}, m.addMaterial(panel));
  }
  s.litAir.min = {-4.0f - h, 0.0f, -2.0f};
  s.litAir.max = {-h, H, 2.0f};
  s.darkAir.min = {h, 0.0f, -2.0f};
  s.darkAir.max = {4.0f + h, H, 2.0f};
  s.house.min = {-xo, 0.0f, -2.3f};
  s.house.max = {xo, H + 0.25f, 2.3f};
  return s;
}

ProbeGrid leakProbeGrid(const LeakScene& s, float spacing, bool inWall) {
  if (!(spacing > 0.0f && spacing <= 8.0f)) fail("leak scene: probe spacing {} m outside (0, 8]", spacing);
  ProbeGrid g;
  const int kx = int(std::ceil((s.house.max.x + spacing) / spacing));
  const int kz = int(std::ceil((s.house.max.z + spacing) / spacing));
  g.spacing = glm::vec3(spacing);
  g.origin = glm::vec3(-float(kx) * spacing + (inWall ? 0.0f : 0.5f * spacing), 0.4f, -float(kz) * spacing);
  g.dims = glm::ivec3(2 * kx + (inWall ? 1 : 0),
                      int(std::ceil((s.house.max.y + spacing - 0.4f) / spacing)) + 1, 2 * kz + 1);
  g.validate();
  return g;
}

}  // namespace lfgi::worlds
