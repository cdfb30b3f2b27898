#include "bake/reference_render.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <csignal>
#include <cstdio>
#include <vector>

#include "core/error.h"
#include "core/progress.h"
#include "core/sh.h"

namespace lfgi::bake {
namespace {

worlds::Material material(glm::vec3 albedo, glm::vec3 emission) {
  worlds::Material m;
  m.albedo = albedo;
  m.emission = emission;
  return m;
}

float channel(const Image& img, int x, int y, const char* name) {
  return img.at(x, y, img.channelIndex(name));
}

// Mean over the image of a channel, and the pooled standard error of that mean from std_error.<ch>.
struct ImageMean {
  double mean = 0.0;
  double se = 0.0;       // of the mean
  double pixelSe = 0.0;  // RMS per-pixel std error
};
ImageMean imageMean(const Image& img, const char* name, const char* seName) {
  const int c = img.channelIndex(name);
  const int e = img.channelIndex(seName);
  double sum = 0.0, var = 0.0;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      sum += img.at(x, y, c);
      var += double(img.at(x, y, e)) * img.at(x, y, e);
    }
  }
  const double count = double(img.width) * img.height;
  return {sum / count, std::sqrt(var) / count, std::sqrt(var / count)};
}

void expectLayersSumExactly(const Image& img) {
  const char* ch[3] = {"R", "G", "B"};
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      for (int k = 0; k < 3; ++k) {
        const std::string s(ch[k]);
        const float sum = channel(img, x, y, ("direct." + s).c_str()) +
                          channel(img, x, y, ("indirect_diffuse." + s).c_str()) +
                          channel(img, x, y, ("indirect_specular." + s).c_str());
        ASSERT_EQ(sum, channel(img, x, y, ch[k])) << x << "," << y << " " << s;
      }
    }
  }
}

// Furnace seen by the camera: inside a closed box of albedo a and emission E, emission collected at
// hits 0..D gives every pixel E (1 - a^(D+1)) / (1 - a). Direct = E (first hit's emission) + a E (the
// second hit's emission through the first bounce, weight exactly a): no noise at all. Indirect diffuse
// = the rest, indirect specular = 0 (Lambertian).
TEST(ReferenceRender, FurnaceSplitsIntoDirectAndIndirect) {
  const float a = 0.5f;
  const float E = 1.0f;
  worlds::TriangleMesh mesh;
  mesh.addInwardBox(glm::vec3(-5.0f), glm::vec3(5.0f),
                    mesh.addMaterial(material(glm::vec3(a), glm::vec3(E))));
  const EmbreeScene scene(mesh);
  RenderOptions o;
  o.width = 32;
  o.height = 24;
  o.samplesPerPixel = 32;
  PinholeCamera cam;
  cam.position = glm::vec3(1.0f, 0.5f, -2.0f);
  cam.target = glm::vec3(3.0f, -1.0f, 4.0f);
  cam.verticalFovDeg = 90.0f;
  const RenderResult r = renderReference(scene, worlds::makeSky(worlds::SkyState{}), cam, o);
  ASSERT_FALSE(r.interrupted);
  ASSERT_EQ(r.tilesDone, r.tiles);
  const double D = o.maxBounces;
  const double total = E * (1.0 - std::pow(a, D + 1.0)) / (1.0 - a);
  const double direct = E + a * E;
  expectLayersSumExactly(r.image);
  for (int y = 0; y < o.height; ++y) {
    for (int x = 0; x < o.width; ++x) {
      ASSERT_EQ(channel(r.image, x, y, "direct.G"), float(direct));
      ASSERT_EQ(channel(r.image, x, y, "indirect_specular.G"), 0.0f);
    }
  }
  const ImageMean m = imageMean(r.image, "G", "std_error.G");
  const ImageMean id = imageMean(r.image, "indirect_diffuse.G", "std_error.G");
  EXPECT_NEAR(m.mean, total, 4.0 * m.se);
  EXPECT_NEAR(id.mean, total - direct, 4.0 * m.se);
  int outliers = 0;
  for (int y = 0; y < o.height; ++y) {
    for (int x = 0; x < o.width; ++x)
      outliers += std::abs(channel(r.image, x, y, "G") - total) > 5.0 * m.pixelSe;
  }
  EXPECT_EQ(outliers, 0);
  std::printf(
      "furnace (camera): image mean %.5f +- %.5f (expected %.5f; error %.2f sigma), indirect diffuse "
      "%.5f (expected %.5f), per-pixel sigma %.4f, %.2f M rays/s\n",
      m.mean, m.se, total, (m.mean - total) / m.se, id.mean, total - direct, m.pixelSe,
      r.raysPerSecond() * 1e-6);
}

// A pure metal has no diffuse lobe (diffuseBrdf = 0): all indirect light goes to the specular layer.
// White rough metal in a closed emissive box: direct = E + rho E with rho <= 1 the single-scatter GGX
// reflectance of the first bounce, so direct lies in [E, 2E] on average (single samples of f cos / pdf
// can exceed 1: h is sampled by D, not by visible normals), and each further bounce adds at most E.
TEST(ReferenceRender, MetalFurnaceIsAllSpecular) {
  worlds::Material metal = material(glm::vec3(1.0f), glm::vec3(1.0f));
  metal.metallic = 1.0f;
  metal.roughness = 0.3f;
  worlds::TriangleMesh mesh;
  mesh.addInwardBox(glm::vec3(-5.0f), glm::vec3(5.0f), mesh.addMaterial(metal));
  const EmbreeScene scene(mesh);
  RenderOptions o;
  o.width = 16;
  o.height = 16;
  o.samplesPerPixel = 16;
  o.maxBounces = 4;
  PinholeCamera cam;
  cam.position = glm::vec3(1.0f, 0.5f, -2.0f);
  cam.target = glm::vec3(3.0f, -1.0f, 4.0f);
  cam.verticalFovDeg = 90.0f;
  const RenderResult r = renderReference(scene, worlds::makeSky(worlds::SkyState{}), cam, o);
  expectLayersSumExactly(r.image);
  for (int y = 0; y < o.height; ++y) {
    for (int x = 0; x < o.width; ++x) {
      ASSERT_EQ(channel(r.image, x, y, "indirect_diffuse.G"), 0.0f);
      ASSERT_GE(channel(r.image, x, y, "direct.G"), 1.0f);
    }
  }
  const ImageMean d = imageMean(r.image, "direct.G", "std_error.G");
  const ImageMean t = imageMean(r.image, "G", "std_error.G");
  const ImageMean sp = imageMean(r.image, "indirect_specular.G", "std_error.G");
  EXPECT_LT(d.mean, 2.0 + 4.0 * t.se);
  EXPECT_LT(t.mean, o.maxBounces + 1.0 + 4.0 * t.se);
  EXPECT_GT(sp.mean, 0.5 * (t.mean - d.mean));
  EXPECT_NEAR(sp.mean, t.mean - d.mean, 1e-4 * t.mean);
  std::printf("metal furnace: direct %.4f, indirect specular %.4f, total %.4f +- %.4f\n", d.mean, sp.mean,
              t.mean, t.se);
}

// A white Lambertian plane under the noon sun, nothing else: every pixel sees the plane, and its radiance
// is albedo / pi (E_sun cos theta + E_sky) with E_sky the upper-hemisphere irradiance of skyRadiance
// (the first bounce always escapes). All of it is direct; indirect is exactly 0.
TEST(ReferenceRender, LambertianPlaneUnderTheSunIsAllDirect) {
  const float albedo = 0.8f;
  worlds::TriangleMesh mesh;
  const uint32_t m = mesh.addMaterial(material(glm::vec3(albedo), glm::vec3(0.0f)));
  const float h = 1000.0f;
  mesh.addQuad(glm::vec3(-h, 0.0f, -h), glm::vec3(-h, 0.0f, h), glm::vec3(h, 0.0f, h), glm::vec3(h, 0.0f, -h),
               m);
  const EmbreeScene scene(mesh);
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{});
  PinholeCamera cam;
  cam.position = glm::vec3(0.0f, 2.0f, 0.0f);
  cam.target = glm::vec3(0.0f, 0.0f, -2.0f);
  cam.verticalFovDeg = 40.0f;
  RenderOptions o;
  o.width = 32;
  o.height = 32;
  o.samplesPerPixel = 16;
  const RenderResult r = renderReference(scene, sky, cam, o);
  const glm::vec3 up(0.0f, 1.0f, 0.0f);
  const int refN = 64;
  const glm::vec3 skyE = bruteForceIrradiance(worlds::skyOctahedralMap(sky, refN, false), refN, up);
  const glm::vec3 sunE = sky.sun.irradiance(up) + sky.moon.irradiance(up);
  expectLayersSumExactly(r.image);
  for (int y = 0; y < o.height; ++y) {
    for (int x = 0; x < o.width; ++x) {
      ASSERT_EQ(channel(r.image, x, y, "indirect_diffuse.R"), 0.0f);
      ASSERT_EQ(channel(r.image, x, y, "indirect_specular.R"), 0.0f);
    }
  }
  const char* names[3][2] = {
      {"direct.R", "std_error.R"}, {"direct.G", "std_error.G"}, {"direct.B", "std_error.B"}};
  for (int ch = 0; ch < 3; ++ch) {
    const double expected = albedo / std::numbers::pi * (sunE[ch] + skyE[ch]);
    const ImageMean d = imageMean(r.image, names[ch][0], names[ch][1]);
    // Noise from the sky's variation over the bounce directions, plus the 64 x 64 brute-force sum's own
    // discretisation (well under 0.5 % for a smooth sky).
    EXPECT_NEAR(d.mean, expected, 4.0 * d.se + 0.005 * expected) << names[ch][0];
    std::printf(
        "plane under the noon sun, %s: %.4f +- %.4f, expected %.4f (sun %.4f + sky %.4f); error %.3f %%\n",
        names[ch][0], d.mean, d.se, expected, albedo / std::numbers::pi * sunE[ch],
        albedo / std::numbers::pi * skyE[ch], 100.0 * (d.mean - expected) / expected);
  }
}

worlds::TriangleMesh courtyard() {
  worlds::TriangleMesh mesh;
  const uint32_t ground = mesh.addMaterial(material(glm::vec3(0.4f, 0.35f, 0.3f), glm::vec3(0.0f)));
  const uint32_t wall = mesh.addMaterial(material(glm::vec3(0.7f), glm::vec3(0.0f)));
  worlds::Material metal = material(glm::vec3(0.9f, 0.7f, 0.4f), glm::vec3(0.0f));
  metal.metallic = 1.0f;
  metal.roughness = 0.3f;
  const uint32_t glossy = mesh.addMaterial(metal);
  worlds::Material plastic = material(glm::vec3(0.2f, 0.5f, 0.8f), glm::vec3(0.0f));
  plastic.roughness = 0.4f;
  const uint32_t shiny = mesh.addMaterial(plastic);
  worlds::Material lampMaterial = material(glm::vec3(0.0f), glm::vec3(50.0f, 40.0f, 30.0f));
  lampMaterial.doubleSided = true;
  const uint32_t lamp = mesh.addMaterial(lampMaterial);
  mesh.addBox(glm::vec3(-20.0f, -1.0f, -20.0f), glm::vec3(20.0f, 0.0f, 20.0f), ground);
  mesh.addBox(glm::vec3(-6.0f, 0.0f, -6.0f), glm::vec3(-4.0f, 8.0f, 6.0f), wall);
  mesh.addBox(glm::vec3(4.0f, 0.0f, -6.0f), glm::vec3(6.0f, 5.0f, 6.0f), glossy);
  mesh.addBox(glm::vec3(-4.0f, 6.0f, -6.0f), glm::vec3(4.0f, 6.5f, 0.0f), wall);
  mesh.addBox(glm::vec3(-1.0f, 0.0f, -3.0f), glm::vec3(1.0f, 1.0f, -1.0f), shiny);
  mesh.addBox(glm::vec3(-0.5f, 3.0f, 2.0f), glm::vec3(0.5f, 3.2f, 3.0f), lamp);
  return mesh;
}

TEST(ReferenceRender, SameSeedIsBitIdenticalForAnyThreadCount) {
  const EmbreeScene scene(courtyard());
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{16.5f, 45.0f, 172, 3.0f, 0.0f});
  PinholeCamera cam;
  cam.position = glm::vec3(0.0f, 2.0f, 9.0f);
  cam.target = glm::vec3(0.0f, 1.5f, -3.0f);
  RenderOptions o;
  o.width = 40;
  o.height = 24;
  o.samplesPerPixel = 4;
  o.tileSize = 8;
  o.seed = 7;
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    return renderReference(scene, sky, cam, o);
  };
  const RenderResult one = run(1);
  const RenderResult two = run(2);
  EXPECT_EQ(one.image.pixels, two.image.pixels);
  EXPECT_EQ(one.rays, two.rays);
  expectLayersSumExactly(one.image);
  // The glossy materials put light into the specular layer; everything is finite and >= 0 except that a
  // specular part may be slightly negative where the sampled weight w0 rounds below its diffuse part.
  double specular = 0.0, diffuse = 0.0;
  for (int y = 0; y < o.height; ++y) {
    for (int x = 0; x < o.width; ++x) {
      for (float v : one.image.pixel(x, y)) ASSERT_TRUE(std::isfinite(v));
      specular += channel(one.image, x, y, "indirect_specular.G");
      diffuse += channel(one.image, x, y, "indirect_diffuse.G");
      EXPECT_GE(channel(one.image, x, y, "direct.G"), 0.0f);
    }
  }
  EXPECT_GT(specular, 0.0);
  EXPECT_GT(diffuse, 0.0);
  o.seed = 8;
  EXPECT_NE(run(2).image.pixels, one.image.pixels);
}

TEST(ReferenceRender, CameraRaysFollowThePinholeModel) {
  PinholeCamera cam;
  cam.position = glm::vec3(1.0f, 2.0f, 3.0f);
  cam.target = glm::vec3(1.0f, 2.0f, -7.0f);
  cam.verticalFovDeg = 90.0f;
  const glm::vec3 centre = cameraRayDirection(cam, 200, 100, 100.0f, 50.0f);
  EXPECT_NEAR(centre.z, -1.0f, 1e-6f);
  const glm::vec3 top = cameraRayDirection(cam, 200, 100, 100.0f, 0.0f);  // 45 deg up at the top edge
  EXPECT_NEAR(top.y, std::sqrt(0.5f), 1e-6f);
  const glm::vec3 right = cameraRayDirection(cam, 200, 100, 200.0f, 50.0f);  // aspect 2: tan = 2
  EXPECT_NEAR(right.x / -right.z, 2.0f, 1e-5f);
}

TEST(ReferenceRender, BadOptionsAndCamerasAreErrors) {
  const EmbreeScene scene{worlds::TriangleMesh{}};
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{});
  RenderOptions o;
  o.width = 0;
  EXPECT_THROW(renderReference(scene, sky, PinholeCamera{}, o), Error);
  o = RenderOptions{};
  o.samplesPerPixel = 0;
  EXPECT_THROW(validateRenderOptions(o), Error);
  PinholeCamera cam;
  cam.target = cam.position;
  EXPECT_THROW(validateCamera(cam), Error);
  cam.target = cam.position + glm::vec3(0.0f, -1.0f, 0.0f);
  EXPECT_THROW(validateCamera(cam), Error);
  cam = PinholeCamera{};
  cam.verticalFovDeg = 180.0f;
  EXPECT_THROW(validateCamera(cam), Error);
  try {
    cam.verticalFovDeg = 60.0f;
    cam.position.x = std::nanf("");
    validateCamera(cam);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not finite"), std::string::npos) << e.what();
  }
}

TEST(ReferenceRender, InterruptStopsBeforeTheNextTile) {
  const EmbreeScene scene(courtyard());
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{});
  RenderOptions o;
  o.width = 16;
  o.height = 16;
  o.samplesPerPixel = 1;
  o.tileSize = 4;
  {
    InterruptGuard guard;
    std::raise(SIGINT);
    ASSERT_TRUE(InterruptGuard::interrupted());
    const RenderResult r = renderReference(scene, sky, PinholeCamera{}, o);
    EXPECT_TRUE(r.interrupted);
    EXPECT_EQ(r.tilesDone, 0u);
    for (float v : r.image.pixels) EXPECT_EQ(v, 0.0f);
    InterruptGuard::reset();
  }
  const RenderResult r = renderReference(scene, sky, PinholeCamera{}, o, /*showProgress=*/true);
  EXPECT_FALSE(r.interrupted);
  EXPECT_EQ(r.tilesDone, 16u);
}

}  // namespace
}  // namespace lfgi::bake
