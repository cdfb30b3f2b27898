#include "gpu/cubemap_raster.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>

#include "core/error.h"
#include "shared/octahedral.h"
#include "test_util.h"

namespace lfgi::gpu {
namespace {

// Axis-aligned box [lo, hi] as 12 triangles whose normals face inward (room) or outward (solid).
void addBox(CubemapScene& scene, glm::vec3 lo, glm::vec3 hi, bool inward, glm::vec3 ceilingEmission) {
  const glm::vec3 centre = 0.5f * (lo + hi);
  for (int axis = 0; axis < 3; ++axis)
    for (int side = -1; side <= 1; side += 2) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;
      glm::vec3 q[4];
      for (int k = 0; k < 4; ++k) {
        q[k][axis] = side > 0 ? hi[axis] : lo[axis];
        q[k][a] = (k == 1 || k == 2) ? hi[a] : lo[a];
        q[k][b] = (k >= 2) ? hi[b] : lo[b];
      }
      const glm::vec3 albedo = inward ? test::roomWallAlbedo(axis, side) : glm::vec3(0.9f, 0.1f, 0.1f);
      const glm::vec3 emission = (inward && axis == 1 && side > 0) ? ceilingEmission : glm::vec3(0.0f);
      for (int t = 0; t < 2; ++t) {
        glm::vec3 v0 = q[0], v1 = q[1 + t], v2 = q[2 + t];
        const glm::vec3 nrm = glm::cross(v1 - v0, v2 - v0);
        const bool facesCentre = glm::dot(nrm, centre - v0) > 0.0f;
        if (facesCentre != inward) std::swap(v1, v2);
        scene.addTriangle(v0, v1, v2, albedo, emission);
      }
    }
}

// Nearest hit from o along unit d: the inside of the room [-h, h]^3 or the outside of the solid box
// [lo, hi] (slab test); returns the distance and the normal facing the probe.
float analyticHit(glm::vec3 o, glm::vec3 d, float h, glm::vec3 lo, glm::vec3 hi, glm::vec3* normal,
                  bool* solid) {
  float best = 1e30f;
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(d[axis]) < 1e-9f) continue;
    const float t = ((d[axis] > 0.0f ? h : -h) - o[axis]) / d[axis];
    if (t < best) {
      best = t;
      *normal = glm::vec3(0.0f);
      (*normal)[axis] = d[axis] > 0.0f ? -1.0f : 1.0f;
      *solid = false;
    }
  }
  float tNear = -1e30f, tFar = 1e30f;
  int nearAxis = -1;
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(d[axis]) < 1e-9f) {
      if (o[axis] < lo[axis] || o[axis] > hi[axis]) return best;
      continue;
    }
    float t0 = (lo[axis] - o[axis]) / d[axis], t1 = (hi[axis] - o[axis]) / d[axis];
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > tNear) {
      tNear = t0;
      nearAxis = axis;
    }
    tFar = std::min(tFar, t1);
  }
  if (nearAxis >= 0 && tNear <= tFar && tNear > 0.0f && tNear < best) {
    best = tNear;
    *normal = glm::vec3(0.0f);
    (*normal)[nearAxis] = d[nearAxis] > 0.0f ? -1.0f : 1.0f;
    *solid = true;
  }
  return best;
}

constexpr float kH = 5.0f;
const glm::vec3 kSolidLo{1.0f, -2.0f, -1.0f}, kSolidHi{2.5f, 0.5f, 1.5f};
const glm::vec3 kCeilingEmission{3.0f, 2.0f, 1.0f};

// Probes in a closed 10 m room with a solid box inside (the depth test must pick the box in front of
// the wall): per octahedral texel, distance vs the analytic ray/scene distance along the texel-centre
// direction, normals and albedo vs the surface hit, radiance = the ceiling's emission.
TEST(CubemapRaster, RoomWithBoxMatchesAnalyticDistanceNormalAlbedo) {
  auto ctx = createContext();
  CubemapRaster raster(*ctx);
  CubemapScene scene;
  addBox(scene, glm::vec3(-kH), glm::vec3(kH), true, kCeilingEmission);
  addBox(scene, kSolidLo, kSolidHi, false, glm::vec3(0.0f));
  const std::vector<glm::vec3> probes = {
      {0.0f, 0.0f, 0.0f}, {0.7f, -1.3f, 2.1f}, {-3.0f, 2.5f, -3.5f}, {4.0f, -4.0f, 4.2f}};
  CubemapRasterOptions options;
  options.resolution = 16;
  const CubemapCapture cap = raster.run(scene, probes, options);
  const ProbeAtlas& atlas = cap.atlas;
  const uint32_t n = 16;
  ASSERT_EQ(atlas.distance.size(), probes.size() * n * n);
  EXPECT_EQ(atlas.holeFractionAfterFill, 0.0);  // closed room: every direction hits something
  std::vector<double> relErr;
  size_t normalOff = 0, albedoOff = 0, radianceOff = 0, solidTexels = 0;
  for (size_t p = 0; p < probes.size(); ++p)
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) {
        const size_t t = (p * n + j) * n + i;
        const glm::vec3 dir = shared::octTexelDirection(glm::uvec2(i, j), n);
        glm::vec3 wallNormal(0.0f);
        bool solid = false;
        const float ref = analyticHit(probes[p], dir, kH, kSolidLo, kSolidHi, &wallNormal, &solid);
        solidTexels += solid ? 1 : 0;
        ASSERT_EQ(atlas.normal[t].w, 1.0f);
        relErr.push_back(std::abs(double(atlas.distance[t].x) - ref) / ref);
        EXPECT_FLOAT_EQ(atlas.distance[t].y, atlas.distance[t].x * atlas.distance[t].x);
        if (glm::dot(glm::vec3(atlas.normal[t]), wallNormal) < 0.9999f) {
          ++normalOff;  // the face texel saw another surface than the texel-centre ray (silhouette / edge)
          continue;
        }
        int axis = 0;
        while (wallNormal[axis] == 0.0f) ++axis;
        const glm::vec3 wantAlbedo = solid ? glm::vec3(0.9f, 0.1f, 0.1f)
                                           : test::roomWallAlbedo(axis, wallNormal[axis] < 0.0f ? 1 : -1);
        const glm::vec3 wantRadiance =
            (!solid && axis == 1 && wallNormal[axis] < 0.0f) ? kCeilingEmission : glm::vec3(0.0f);
        // FP16 attachments: 11-bit mantissa.
        if (glm::length(glm::vec3(atlas.albedo[t]) - wantAlbedo) > 2e-3f) ++albedoOff;
        if (glm::length(glm::vec3(atlas.radiance[t]) - wantRadiance) > 4e-3f) ++radianceOff;
      }
  const size_t total = relErr.size();
  const double med = test::quantile(relErr, 0.5), p90 = test::quantile(relErr, 0.9),
               worst = test::quantile(relErr, 1.0);
  size_t over1pct = 0;
  for (double e : relErr) over1pct += e > 0.01 ? 1 : 0;
  std::printf(
      "cubemap room+box: %zu texels (%zu on the box), N=%u F=%d: |dr|/r median %.2e p90 %.2e max %.3f, > 1 "
      "%%: %zu; "
      "normals off %zu, albedo off %zu, radiance off %zu; raster %.2f ms, copy %.2f ms, resample %.2f ms\n",
      total, solidTexels, n, cap.faceResolution, med, p90, worst, over1pct, normalOff, albedoOff, radianceOff,
      cap.rasterMs, cap.copyMs, cap.resampleMs);
  EXPECT_GT(solidTexels, total / 50);  // the box is really in view
  // Plane re-intersection makes texels whose face sample lies on the same plane exact (float rounding):
  EXPECT_LE(med, 1e-5);
  // Silhouette/edge texels (the face sample on another surface) keep the face sample's distance: bounded
  // by the parallax of one texel, and rare.
  // (Their error is unbounded in principle: a face sample on the box in front of a far wall.)
  EXPECT_LE(double(over1pct) / double(total), 0.05);
  EXPECT_LE(double(normalOff) / double(total), 0.05);
  EXPECT_EQ(albedoOff, 0u);
  EXPECT_EQ(radianceOff, 0u);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// One probe per batch (many render + copy + resample rounds in one command buffer) gives the same maps
// as a single batch, and sky texels (an open room: no ceiling) are counted as holes.
TEST(CubemapRaster, BatchingGivesTheSameMapsAndSkyIsAHole) {
  auto ctx = createContext();
  CubemapRaster raster(*ctx);
  CubemapScene full;
  addBox(full, glm::vec3(-kH), glm::vec3(kH), true, kCeilingEmission);
  CubemapScene open;  // drop the ceiling (the two triangles with normal -Y)
  for (size_t t = 0; t < full.triangles.size(); ++t)
    if (full.triangles[t].normal.y > -0.5f)
      open.addTriangle(glm::vec3(full.vertices[3 * t]), glm::vec3(full.vertices[3 * t + 1]),
                       glm::vec3(full.vertices[3 * t + 2]), glm::vec3(full.triangles[t].albedo));
  ASSERT_EQ(open.triangleCount(), 10u);
  std::vector<glm::vec3> probes;
  for (int k = 0; k < 5; ++k)
    probes.push_back({-3.0f + 1.3f * float(k), -2.0f + 0.5f * float(k), 1.0f - 0.7f * float(k)});
  CubemapRasterOptions options;
  options.resolution = 8;
  options.faceResolution = 12;
  const CubemapCapture one = raster.run(open, probes, options);
  options.maxAtlasTexels = 6 * 12 * 12;
  const CubemapCapture many = raster.run(open, probes, options);
  EXPECT_EQ(one.batches, 1);
  EXPECT_EQ(many.batches, int(probes.size()));
  ASSERT_EQ(one.atlas.distance.size(), many.atlas.distance.size());
  // Flat attributes are bit-identical; the interpolated distance may differ in the last bits because a
  // tile's absolute position in the atlas enters the rasterizer's interpolation.
  double maxRel = 0.0;
  for (size_t t = 0; t < one.atlas.distance.size(); ++t)
    if (one.atlas.distance[t].x > 0.0f)
      maxRel = std::max(maxRel, std::abs(double(one.atlas.distance[t].x) - many.atlas.distance[t].x) /
                                    double(one.atlas.distance[t].x));
  EXPECT_LE(maxRel, 1e-5);
  EXPECT_EQ(std::memcmp(one.atlas.normal.data(), many.atlas.normal.data(), one.atlas.normal.size() * 16), 0);
  EXPECT_EQ(std::memcmp(one.atlas.albedo.data(), many.atlas.albedo.data(), one.atlas.albedo.size() * 16), 0);
  // Sky texels: the texel-centre ray leaves through the open top (y = h) of the room.
  size_t sky = 0, skyAgree = 0;
  const uint32_t n = 8;
  for (size_t p = 0; p < probes.size(); ++p)
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) {
        const glm::vec3 d = shared::octTexelDirection(glm::uvec2(i, j), n);
        glm::vec3 nrm;
        bool solid = false;
        analyticHit(probes[p], d, kH, glm::vec3(100.0f), glm::vec3(101.0f), &nrm, &solid);
        const bool wantSky = nrm.y < -0.5f;
        sky += wantSky ? 1 : 0;
        skyAgree += (wantSky == (one.atlas.normal[(p * n + j) * n + i].w == 0.0f)) ? 1 : 0;
      }
  const size_t total = probes.size() * n * n;
  std::printf("cubemap open room: sky %zu of %zu texels, hole fraction %.4f, agreement %zu\n", sky, total,
              one.atlas.holeFractionAfterFill, skyAgree);
  EXPECT_GT(sky, total / 20);
  EXPECT_GE(double(skyAgree) / double(total), 0.97);  // disagreement only at the rim's silhouette
  EXPECT_NEAR(one.atlas.holeFractionAfterFill, double(sky) / double(total), 0.03);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// The baseline and VIR see the same room (triangles vs surfels of the same walls): per texel they agree
// on distance (median) and normal, so the benchmark compares like with like.
TEST(CubemapRaster, AgreesWithVirOnTheSameRoom) {
  auto ctx = createContext();
  if (!ctx->features.shaderBufferInt64Atomics) GTEST_SKIP() << "no 64-bit atomics for VIR";
  CubemapRaster raster(*ctx);
  VirPass vir(*ctx);
  CubemapScene scene;
  addBox(scene, glm::vec3(-kH), glm::vec3(kH), true, glm::vec3(0.0f));
  const std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(kH, 0.5f);
  const std::vector<glm::vec3> probes = {{0.0f, 0.0f, 0.0f}, {0.7f, -1.3f, 2.1f}, {-3.0f, 2.5f, -3.5f}};
  CubemapRasterOptions co;
  co.resolution = 16;
  VirOptions vo;
  vo.resolution = 16;
  vo.maxRange = 30.0f;
  const ProbeAtlas a = raster.run(scene, probes, co).atlas;
  const ProbeAtlas b = vir.run(surfels, probes, vo);
  std::vector<double> rel, angle;
  for (size_t t = 0; t < a.distance.size(); ++t) {
    if (a.normal[t].w == 0.0f || b.normal[t].w == 0.0f) continue;
    rel.push_back(std::abs(double(a.distance[t].x) - b.distance[t].x) / double(a.distance[t].x));
    const float c = std::clamp(glm::dot(glm::vec3(a.normal[t]), glm::vec3(b.normal[t])), -1.0f, 1.0f);
    angle.push_back(double(std::acos(c)) * 180.0 / std::numbers::pi);
  }
  std::printf(
      "cubemap vs VIR: %zu texels compared, |dr|/r median %.4f p90 %.4f, normal median %.2f deg p90 %.2f\n",
      rel.size(), test::quantile(rel, 0.5), test::quantile(rel, 0.9), test::quantile(angle, 0.5),
      test::quantile(angle, 0.9));
  ASSERT_GE(rel.size(), a.distance.size() * 99 / 100);
  EXPECT_LE(test::quantile(rel, 0.5), 0.02);
  EXPECT_LE(test::quantile(angle, 0.5), 1.0);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

TEST(CubemapRaster, RejectsBadInput) {
  auto ctx = createContext();
  CubemapRaster raster(*ctx);
  CubemapScene scene;
  scene.addTriangle({0, 0, 1}, {1, 0, 1}, {0, 1, 1}, glm::vec3(0.5f));
  const std::vector<glm::vec3> probe = {{0.0f, 0.0f, 0.0f}};
  CubemapRasterOptions o;
  EXPECT_THROW(raster.run(CubemapScene{}, probe, o), Error);
  EXPECT_THROW(raster.run(scene, {}, o), Error);
  CubemapScene broken = scene;
  broken.vertices.pop_back();
  EXPECT_THROW(raster.run(broken, probe, o), Error);
  o.resolution = 0;
  EXPECT_THROW(raster.run(scene, probe, o), Error);
  o.resolution = 16;
  o.nearPlane = 0.0f;
  EXPECT_THROW(raster.run(scene, probe, o), Error);
  o.nearPlane = 0.01f;
  o.maxAtlasTexels = 6 * 16 * 16 - 1;
  EXPECT_THROW(raster.run(scene, probe, o), Error);
  o.maxAtlasTexels = 1 << 20;
  const CubemapCapture ok = raster.run(scene, probe, o);  // and a valid call still works afterwards
  EXPECT_GT(ok.atlas.holeFractionAfterFill, 0.9);         // one small triangle: almost all sky
  EXPECT_LT(ok.atlas.holeFractionAfterFill, 1.0);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::gpu
