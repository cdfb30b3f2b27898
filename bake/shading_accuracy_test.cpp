// Shading from captured probes against the path-traced reference: Cornell box indirect light
// error at the paper's 2 x 2 x 2 probes and a denser grid, colour bleeding, and the leak-test house of the
// synthetic world. Bounds are the measured values plus a margin (numbers printed by each test).
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>

#include "bake/embree_scene.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "core/error.h"
#include "worlds/gltf_io.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {
namespace {

// Midnight under full overcast: no disc, a sky ~1e-7 of the light: the ceiling light does everything.
worlds::SkyModel darkSky() {
  return worlds::makeSky(worlds::SkyState{0.0f, 45.0f, 172, 3.0f, 1.0f});
}

PinholeCamera cornellCamera() {
  PinholeCamera c;
  c.position = glm::vec3(-0.278f, 0.274f, 1.0f);
  c.target = glm::vec3(-0.278f, 0.274f, -0.28f);
  c.verticalFovDeg = 40.0f;
  return c;
}

struct Cornell {
  worlds::TriangleMesh mesh;
  std::unique_ptr<EmbreeScene> scene;
  worlds::SkyModel sky = darkSky();
  RenderResult reference;
  static constexpr int kSize = 32;
};

Cornell& cornell() {
  static Cornell* c = [] {
    auto* k = new Cornell;
    const worlds::ScenePreset& preset = worlds::findScenePreset("cornell");
    k->mesh = worlds::loadScenePreset(preset, LFGI_SCENES_DIR);
    k->scene = std::make_unique<EmbreeScene>(k->mesh, "cornell");
    RenderOptions ro;
    ro.width = ro.height = Cornell::kSize;
    ro.samplesPerPixel = 2048;  // the light is small: fewer samples leave the reference's own noise dominant
    k->reference = renderShadingReference(*k->scene, k->sky, cornellCamera(), ro);
    return k;
  }();
  return *c;
}

ProbeField cornellField(glm::ivec3 dims, int resolution) {
  Cornell& k = cornell();
  worlds::ScenePreset preset = worlds::findScenePreset("cornell");
  preset.probeDims = dims;
  const ProbeGrid grid = worlds::presetProbeGrid(preset, k.mesh.bounds());
  CaptureOptions co;
  co.resolution = resolution;
  co.samplesPerTexel = 64;
  return captureGridField(*k.scene, k.sky, grid, {}, {}, co);
}

// Pixels shaded from probes; with noEmitters also not the light itself (direct < 1 without a sun).
std::vector<uint8_t> surfaceMask(const Image& shaded, bool noEmitters = true) {
  std::vector<uint8_t> m(size_t(shaded.width) * size_t(shaded.height), 0);
  const int w = shaded.channelIndex("weight"), d = shaded.channelIndex("direct.G");
  for (int y = 0; y < shaded.height; ++y)
    for (int x = 0; x < shaded.width; ++x)
      m[size_t(y) * size_t(shaded.width) + size_t(x)] =
          shaded.at(x, y, w) > 0.0f && (!noEmitters || shaded.at(x, y, d) < 1.0f);
  return m;
}

double cornellIndirectError(glm::ivec3 dims, int resolution, const gpu::ShadingOptions& o = {}) {
  Cornell& k = cornell();
  const ProbeField f = cornellField(dims, resolution);
  auto ctx = gpu::createContext();
  ShadingRenderer r(*ctx, k.mesh);
  const ProbeField* fields[] = {&f};
  r.setProbes(fields);
  const ShadedView v = r.render(k.sky, cornellCamera(), Cornell::kSize, Cornell::kSize, o);
  const std::vector<uint8_t> mask = surfaceMask(v.image);
  size_t n = 0;
  for (uint8_t b : mask) n += b;
  EXPECT_GT(n, size_t(Cornell::kSize * Cornell::kSize / 2));
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
  double mine = 0.0, truth = 0.0;
  const int a = v.image.channelIndex("indirect.G"), b = k.reference.image.channelIndex("indirect.G");
  for (int y = 0; y < Cornell::kSize; ++y)
    for (int x = 0; x < Cornell::kSize; ++x)
      if (mask[size_t(y * Cornell::kSize + x)])
        mine += v.image.at(x, y, a), truth += k.reference.image.at(x, y, b);
  std::printf("cornell %dx%dx%d: mean indirect G over %zu surface pixels: probes %.4g, reference %.4g\n",
              dims.x, dims.y, dims.z, n, mine / double(n), truth / double(n));
  return layerRelativeRms(v.image, "indirect.", k.reference.image, "indirect.", &mask);
}

TEST(ShadingAccuracy, CornellIndirectAtPaperGrid) {
  const double e = cornellIndirectError(glm::ivec3(2), 16);
  std::printf("cornell 2x2x2, 16x16 maps: indirect relative RMS %.4f\n", e);
  // Measured 1.07 (probes' mean indirect 1.7x the reference): the ceiling light is a surface, so its direct
  // light on the floor comes from probes 0.4 m under it that see it much closer than the floor does
  // (irradiance probes have no parallax for near emitters); see the denser grid below.
  EXPECT_LT(e, 1.25);
}

TEST(ShadingAccuracy, CornellIndirectDenserGrid) {
  const double e = cornellIndirectError(glm::ivec3(4), 16);
  std::printf("cornell 4x4x4, 16x16 maps: indirect relative RMS %.4f\n", e);
  EXPECT_LT(e, 0.70);                                            // measured 0.59 (mean 1.3x the reference)
  EXPECT_LT(e, 0.75 * cornellIndirectError(glm::ivec3(2), 16));  // denser probes converge
}

// The red wall tints the floor next to it: on floor points 4 cm from each side wall, R/G of the
// indirect light is higher beside the red wall than beside the green one (and the reverse for G/R).
TEST(ShadingAccuracy, CornellColourBleeding) {
  Cornell& k = cornell();
  const ProbeField f = cornellField(glm::ivec3(2), 16);
  auto ctx = gpu::createContext();
  ShadingRenderer r(*ctx, k.mesh);
  const ProbeField* fields[] = {&f};
  r.setProbes(fields);
  // Which side is red: the mean x of the triangles of the most saturated red material.
  float redX = 0.0f, greenX = 0.0f;
  int nr = 0, ng = 0;
  for (size_t t = 0; t < k.mesh.triangleCount(); ++t) {
    const glm::vec3 a = k.mesh.materials[k.mesh.triangleMaterial[t]].albedo;
    const float x = (k.mesh.vertex(t, 0).x + k.mesh.vertex(t, 1).x + k.mesh.vertex(t, 2).x) / 3.0f;
    if (a.x > 0.3f && a.y < 0.1f) redX += x, ++nr;
    if (a.y > 0.3f && a.x < 0.1f) greenX += x, ++ng;
  }
  ASSERT_GT(nr, 0);
  ASSERT_GT(ng, 0);
  redX /= float(nr);
  greenX /= float(ng);
  const float toCentre = redX < greenX ? 1.0f : -1.0f;
  gpu::GBufferHost g;
  g.height = 1;
  for (int side = 0; side < 2; ++side)
    for (int j = 0; j < 4; ++j) {
      const float x = side == 0 ? redX + 0.04f * toCentre : greenX - 0.04f * toCentre;
      g.position.push_back(glm::vec4(x, 0.001f, -0.1f - 0.1f * float(j), 1.0f));
      g.normal.push_back(glm::vec4(0.0f, 1.0f, 0.0f, 1.0f));
      g.albedo.push_back(glm::vec4(0.4f, 0.4f, 0.4f, 0.0f));
      g.emission.push_back(glm::vec4(0.0f));
    }
  g.width = int(g.position.size());
  const gpu::ShadeOutputHost s = r.shadePoints(k.sky, g, cornellCamera().position);
  glm::vec3 nearRed(0.0f), nearGreen(0.0f);
  for (int j = 0; j < 4; ++j) {
    nearRed += glm::vec3(s.diffuse[size_t(j)]);
    nearGreen += glm::vec3(s.diffuse[size_t(4 + j)]);
  }
  const float rgRed = nearRed.x / nearRed.y, rgGreen = nearGreen.x / nearGreen.y;
  std::printf("floor indirect R/G: %.3f beside the red wall, %.3f beside the green wall\n", rgRed, rgGreen);
  EXPECT_GT(rgRed, 1.0f);
  EXPECT_LT(rgGreen, 1.0f);
  EXPECT_GT(rgRed / rgGreen, 1.15f);  // measured 1.23
}

// End to end where probe interpolation is exact: an open plane under the sky. Every probe above an
// infinite plane sees the same upper hemisphere of sky, so irradiance on the ground equals the probes' (up
// to the plane's finite size and capture noise): shading must match the reference. Under a clear noon sky
// the captured sun must be taken out of the probes (subtractDiscLight), else it counts twice.
void planeUnderSky(float overcast) {
  worlds::TriangleMesh mesh;
  worlds::Material m;
  m.albedo = glm::vec3(0.6f, 0.5f, 0.4f);
  const uint32_t mat = mesh.addMaterial(m);
  mesh.addQuad(glm::vec3(-500, 0, 500), glm::vec3(500, 0, 500), glm::vec3(500, 0, -500),
               glm::vec3(-500, 0, -500), mat);
  const EmbreeScene scene(mesh);
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, overcast});
  PinholeCamera cam;
  cam.position = glm::vec3(0.5f, 1.7f, 0.5f);
  cam.target = glm::vec3(0.5f, 0.0f, -4.0f);
  const ProbeGrid grid{glm::vec3(-4.0f, 1.0f, -8.0f), glm::vec3(4.0f, 2.0f, 4.0f), glm::ivec3(3, 2, 3)};
  CaptureOptions co;
  co.samplesPerTexel = 64;
  co.maxBounces = 4;
  const ProbeField f = captureGridField(scene, sky, grid, {}, {}, co);
  auto ctx = gpu::createContext();
  ShadingRenderer r(*ctx, mesh);
  const ProbeField* fields[] = {&f};
  r.setProbes(fields);
  const ShadedView v = r.render(sky, cam, 16, 16);
  RenderOptions ro;
  ro.width = ro.height = 16;
  ro.samplesPerPixel = 1024;
  ro.maxBounces = 4;
  const RenderResult ref = renderShadingReference(scene, sky, cam, ro);
  const std::vector<uint8_t> mask = surfaceMask(v.image, false);
  const double e = layerRelativeRms(v.image, "indirect.", ref.image, "indirect.", &mask);
  const double t = layerRelativeRms(v.image, "", ref.image, "");
  std::printf("plane, overcast %.0f: indirect relative RMS %.4f, total (sky pixels included) %.4f\n",
              double(overcast), e, t);
  EXPECT_LT(e, 0.05);
  EXPECT_LT(t, 0.05);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

TEST(ShadingAccuracy, PlaneUnderOvercastSkyMatchesReference) {
  planeUnderSky(1.0f);
}

TEST(ShadingAccuracy, PlaneUnderSunAndSkyMatchesReference) {
  planeUnderSky(0.0f);
}

// The reference's direct layer is exactly what the shading pass computes without probes: for a plane
// under the sun, direct = albedo / pi * E_sun * cos and indirect = the sky's share; total = direct +
// indirect.
TEST(ShadingReference, LayersAddUpAndDirectIsTheSunOnAPlane) {
  worlds::TriangleMesh mesh;
  worlds::Material m;
  m.albedo = glm::vec3(0.5f);
  const uint32_t mat = mesh.addMaterial(m);
  mesh.addQuad(glm::vec3(-50, 0, 50), glm::vec3(50, 0, 50), glm::vec3(50, 0, -50), glm::vec3(-50, 0, -50),
               mat);
  const EmbreeScene scene(mesh);
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{});
  PinholeCamera cam;
  cam.position = glm::vec3(0.0f, 2.0f, 0.0f);
  cam.target = glm::vec3(0.0f, 0.0f, -3.0f);
  RenderOptions o;
  o.width = o.height = 8;
  o.samplesPerPixel = 16;
  const RenderResult r = renderShadingReference(scene, sky, cam, o);
  const RenderResult ref = renderReference(scene, sky, cam, o);
  const glm::vec3 sunDirect = 0.5f / 3.14159265f * sky.sun.irradiance(glm::vec3(0, 1, 0));
  for (int y = 4; y < 8; ++y)  // lower half: the plane
    for (int x = 0; x < 8; ++x)
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(r.image.at(x, y, 3 + c), sunDirect[c], 1e-4f * sunDirect[c]);
        EXPECT_NEAR(r.image.at(x, y, c), r.image.at(x, y, 3 + c) + r.image.at(x, y, 6 + c),
                    1e-3f * r.image.at(x, y, c));
        EXPECT_NEAR(r.image.at(x, y, c), ref.image.at(x, y, c), 1e-4f * ref.image.at(x, y, c));
      }
}

// Leak test house of the default world (cell 1,1): lit room | thin wall | sealed room. Indirect light on
// the sealed room's floor must stay <= 1 % of the lit room's with Chebyshev visibility; without it the
// lit room's probes leak through the wall.
TEST(ShadingAccuracy, SealedRoomStaysDark) {
  worlds::WorldParams wp;
  wp.sizeM = 256;
  wp.cellM = 64;
  wp.seed = 1;
  const worlds::SyntheticWorld world(wp);
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
  CaptureOptions co;
  co.resolution = 16;
  co.samplesPerTexel = 16;
  co.maxBounces = 6;
  auto ctx = gpu::createContext();
  const LeakTestResult r = measureLeakTest(*ctx, world, {1, 1}, sky, co);
  std::printf(
      "leak test: %zu probes; sealed / lit floor indirect: Chebyshev on %.5f (%.4g / %.4g), off %.5f\n",
      r.probes, r.ratioOn(), r.sealedOn, r.litOn, r.ratioOff());
  EXPECT_GT(r.probes, size_t(8));
  EXPECT_GT(r.litOn, 0.0);
  EXPECT_LE(r.ratioOn(), 0.01);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::bake
