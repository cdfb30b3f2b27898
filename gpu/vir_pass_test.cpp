#include "gpu/vir_pass.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <string>

#include "core/error.h"
#include "shared/octahedral.h"
#include "test_util.h"

namespace lfgi::gpu {
namespace {

// Texels of two same-sized atlases that differ in any bit of any channel.
size_t differingTexels(const ProbeAtlas& a, const ProbeAtlas& b) {
  EXPECT_EQ(a.distance.size(), b.distance.size());
  size_t differ = 0;
  for (size_t t = 0; t < std::min(a.distance.size(), b.distance.size()); ++t)
    differ += std::memcmp(&a.distance[t], &b.distance[t], sizeof(glm::vec2)) != 0 ||
                      std::memcmp(&a.normal[t], &b.normal[t], sizeof(glm::vec4)) != 0 ||
                      std::memcmp(&a.albedo[t], &b.albedo[t], sizeof(glm::vec4)) != 0 ||
                      std::memcmp(&a.radiance[t], &b.radiance[t], sizeof(glm::vec4)) != 0
                  ? 1
                  : 0;
  return differ;
}

// Distance from o (inside) along unit d to the box [-h, h]^3, and the inward normal of the wall hit.
float boxDistance(glm::vec3 o, glm::vec3 d, float h, glm::vec3* normal) {
  float best = 1e30f;
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(d[axis]) < 1e-9f) continue;
    const float wall = d[axis] > 0.0f ? h : -h;
    const float t = (wall - o[axis]) / d[axis];
    if (t < best) {
      best = t;
      *normal = glm::vec3(0.0f);
      (*normal)[axis] = d[axis] > 0.0f ? -1.0f : 1.0f;
    }
  }
  return best;
}

// Probes inside a closed 10 m box whose walls are surfels at the default density (0.5 m): per-texel
// distance vs the analytic ray/box distance along the texel-centre direction, normals vs the wall normal.
TEST(VirPass, ClosedBoxMatchesAnalyticDistanceAndNormal) {
  auto ctx = createContext();
  VirPass pass(*ctx);
  const float h = 5.0f;
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(h, 0.5f);
  const std::vector<glm::vec3> probes = {{0.0f, 0.0f, 0.0f}, {0.7f, -1.3f, 2.1f}, {-3.0f, 2.5f, -3.5f}};
  VirOptions options;
  options.resolution = 16;
  options.maxRange = 30.0f;
  pass.run(surfels, probes, options);  // warm-up: lavapipe compiles pipelines on first dispatch
  ProbeAtlas atlas = pass.run(surfels, probes, options);
  const int n = options.resolution;
  ASSERT_EQ(atlas.distance.size(), probes.size() * size_t(n) * size_t(n));
  std::vector<double> relErr, angleDeg;
  for (size_t p = 0; p < probes.size(); ++p)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const size_t t = (p * size_t(n) + size_t(j)) * size_t(n) + size_t(i);
        if (atlas.normal[t].w == 0.0f) continue;
        const glm::vec3 dir = shared::octTexelDirection(glm::uvec2(i, j), uint32_t(n));
        glm::vec3 wallNormal(0.0f);
        const float ref = boxDistance(probes[p], dir, h, &wallNormal);
        relErr.push_back(std::abs(double(atlas.distance[t].x) - ref) / ref);
        if (atlas.normal[t].w == 1.0f)  // covered: r^2 of one surfel; filled: a mean of moments (>= mean^2)
          EXPECT_NEAR(atlas.distance[t].y, atlas.distance[t].x * atlas.distance[t].x,
                      1e-3f * atlas.distance[t].y + 1e-5f);
        else
          EXPECT_GE(atlas.distance[t].y, atlas.distance[t].x * atlas.distance[t].x * (1.0f - 1e-4f));
        const float c = std::clamp(glm::dot(glm::vec3(atlas.normal[t]), wallNormal), -1.0f, 1.0f);
        angleDeg.push_back(double(std::acos(c)) * 180.0 / std::numbers::pi);
      }
  const double medErr = test::median(relErr), medAngle = test::median(angleDeg);
  std::printf(
      "VIR box: %zu surfels, %zu probes, N=%d: median |dr|/r %.4f, median normal angle %.2f deg, holes %.4f "
      "-> "
      "%.4f, splat %.2f ms, resolve %.2f ms, fill %.2f ms\n",
      surfels.size(), probes.size(), n, medErr, medAngle, atlas.holeFractionBeforeFill,
      atlas.holeFractionAfterFill, atlas.splatMs, atlas.resolveMs, atlas.fillMs);
  EXPECT_LE(medErr, 0.02);
  EXPECT_LE(medAngle, 5.0);
  EXPECT_LE(atlas.holeFractionAfterFill, 0.01);
  EXPECT_LE(atlas.holeFractionBeforeFill, 0.05);
  EXPECT_GT(atlas.splatMs, 0.0);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// Discs shrunk to 0.8x their area-equal radius leave gaps between texel-centre rays at N = 32; the
// fill passes close them from covered neighbours (across the octahedral fold too) with plausible
// distances.
TEST(VirPass, HoleFillClosesGapsBetweenShrunkenDiscs) {
  auto ctx = createContext();
  VirPass pass(*ctx);
  const float h = 5.0f;
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(h, 0.5f);
  const glm::vec3 probe(0.5f, 0.2f, -0.4f);
  VirOptions options;
  options.resolution = 32;
  options.footprintScale = 0.8f;
  options.fillPasses = 3;
  ProbeAtlas atlas = pass.run(surfels, std::vector<glm::vec3>{probe}, options);
  std::printf("VIR box N=32, footprint 0.8: holes %.4f before fill -> %.4f after %d passes\n",
              atlas.holeFractionBeforeFill, atlas.holeFractionAfterFill, options.fillPasses);
  EXPECT_GT(atlas.holeFractionBeforeFill, 0.02);
  EXPECT_LE(atlas.holeFractionAfterFill, 0.01);
  const uint32_t n = 32;
  std::vector<double> filledErr;
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const size_t t = size_t(j) * n + i;
      if (atlas.normal[t].w < 2.0f) continue;  // only filled texels
      glm::vec3 wallNormal(0.0f);
      const float ref = boxDistance(probe, shared::octTexelDirection(glm::uvec2(i, j), n), h, &wallNormal);
      filledErr.push_back(std::abs(double(atlas.distance[t].x) - ref) / ref);
    }
  ASSERT_FALSE(filledErr.empty());
  std::printf("filled texels: %zu, median |dr|/r %.4f\n", filledErr.size(), test::median(filledErr));
  EXPECT_LE(test::median(filledErr), 0.05);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// A lone 6 m x 6 m panel 3 m in front of the probe, the rest of the sphere sky, with discs shrunk to 0.8x
// so there are gaps between them: the fill closes the gaps inside the panel's image but never grows its
// silhouette into the sky (a plain dilation, any covered neighbour, grows it by one texel per pass: 61 /
// 82 texels beyond the margin filled here with 2 passes, LOD off / on).
TEST(VirPass, HoleFillClosesGapsButNeverGrowsASilhouette) {
  auto ctx = createContext();
  VirPass pass(*ctx);
  const float spacing = 0.25f, half = 3.0f, z = 3.0f;
  const float radius = spacing / std::sqrt(std::numbers::pi_v<float>);
  std::vector<shared::Surfel> surfels;
  uint32_t k = 0;
  for (float y = -half + 0.5f * spacing; y < half; y += spacing)
    for (float x = -half + 0.5f * spacing; x < half; x += spacing, ++k)
      surfels.push_back({glm::vec4(x + 0.3f * spacing * (test::hash01(2 * k) - 0.5f),
                                   y + 0.3f * spacing * (test::hash01(2 * k + 1) - 0.5f), z, radius),
                         glm::vec4(0.0f, 0.0f, -1.0f, 0.0f), glm::vec4(0.5f, 0.5f, 0.5f, 1.0f),
                         glm::vec4(0.0f)});
  const uint32_t n = 32;
  for (const bool lod : {false, true}) {
    VirOptions options;
    options.resolution = int(n);
    options.footprintScale = 0.8f;
    options.fillPasses = 2;
    options.lod = lod;
    const ProbeAtlas atlas = pass.run(surfels, std::vector<glm::vec3>{glm::vec3(0.0f)}, options);
    // Texels by where their centre ray meets the panel's plane: well inside (margin: a disc radius plus
    // a texel's footprint at the plane), or well outside (sky).
    const float margin = radius + 2.0f * z * std::numbers::pi_v<float> / float(n);
    size_t inside = 0, insideHoles = 0, outside = 0, outsideGeometry = 0;
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) {
        const glm::vec3 d = shared::octTexelDirection(glm::uvec2(i, j), n);
        const float w = atlas.normal[size_t(j) * n + i].w;
        const glm::vec2 at = d.z > 0.0f ? glm::vec2(d) * (z / d.z) : glm::vec2(1e9f);
        const float edge = std::max(std::abs(at.x), std::abs(at.y));
        if (edge < half - margin) {
          ++inside;
          insideHoles += w == LFGI_VIR_HOLE ? 1 : 0;
        } else if (edge > half + margin) {
          ++outside;
          outsideGeometry += w != LFGI_VIR_HOLE ? 1 : 0;
        }
      }
    std::printf(
        "VIR panel N=32 lod=%d: holes %.4f before fill; inside %zu texels, %zu holes left; outside %zu, %zu "
        "with geometry\n",
        int(lod), atlas.holeFractionBeforeFill, inside, insideHoles, outside, outsideGeometry);
    ASSERT_GT(inside, 50u);
    ASSERT_GT(outside, 500u);
    EXPECT_EQ(outsideGeometry, 0u) << "lod " << lod;
    EXPECT_LE(double(insideHoles), 0.01 * double(inside)) << "lod " << lod;
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// The depth test keeps the nearest surfel: a small inward quad of surfels in front of the +x wall hides it.
TEST(VirPass, NearerSurfelWinsAndRadianceIsEmissionPlusAlbedoIrradiance) {
  auto ctx = createContext();
  VirPass pass(*ctx);
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(5.0f, 0.5f);
  const size_t wallCount = surfels.size();
  // A 2 m x 2 m occluder at x = 2 facing -x, emissive red.
  for (int j = 0; j < 8; ++j)
    for (int i = 0; i < 8; ++i)
      surfels.push_back(
          {glm::vec4(2.0f, -1.0f + (float(i) + 0.5f) * 0.25f, -1.0f + (float(j) + 0.5f) * 0.25f, 0.2f),
           glm::vec4(-1.0f, 0.0f, 0.0f, 0.0f), glm::vec4(0.5f, 0.5f, 0.5f, 1.0f),
           glm::vec4(3.0f, 0.0f, 0.0f, 0.0f)});
  std::vector<glm::vec4> irradiance(surfels.size(), glm::vec4(std::numbers::pi_v<float>));
  VirOptions options;
  options.resolution = 16;
  ProbeAtlas atlas = pass.run(surfels, std::vector<glm::vec3>{glm::vec3(0.0f)}, options, irradiance);
  const uint32_t n = 16;
  const glm::uvec2 t = shared::octDirectionTexel(glm::vec3(1.0f, 0.0f, 0.0f), n);
  const size_t i = size_t(t.y) * n + t.x;
  const glm::vec3 dir = shared::octTexelDirection(t, n);
  EXPECT_NEAR(atlas.distance[i].x, 2.0f / dir.x, 0.02f);
  EXPECT_EQ(atlas.normal[i].w, 1.0f);
  EXPECT_NEAR(atlas.radiance[i].x, 3.0f + 0.5f, 1e-4f);  // emission + albedo * E / pi with E = pi
  EXPECT_NEAR(atlas.radiance[i].y, 0.5f, 1e-4f);
  EXPECT_GT(wallCount, 0u);
  EXPECT_THROW(pass.run(surfels, std::vector<glm::vec3>{}, options), Error);
  EXPECT_THROW(pass.run(surfels, std::vector<glm::vec3>{glm::vec3(0.0f)}, options, std::vector<glm::vec4>(3)),
               Error);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// The LOD radiance of a leaf is its own surfel's emission + albedo E / pi (VirPass uploads E in the tree's
// leaf order, so a wrong permutation shows up as another surfel's E), and without irradiance every node's
// radiance is its emission (no radiance pass: the tree's area-weighted emission).
TEST(VirPass, LodRadianceUsesEachLeafsIrradianceAndEmissionWithoutIt) {
  auto ctx = createContext();
  VirPass pass(*ctx);
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(5.0f, 0.5f);
  std::vector<glm::vec4> irradiance(surfels.size());
  for (size_t i = 0; i < surfels.size(); ++i) {
    // Each disc a little off its wall's plane: coplanar overlapping discs tie in depth, and the two splats
    // break ties by different indices (surfel vs leaf).
    const float offset = 0.01f * test::hash01(uint32_t(7 * i));
    surfels[i].positionRadius += glm::vec4(offset * glm::vec3(surfels[i].normal), 0.0f);
    surfels[i].emission =
        glm::vec4(test::hash01(uint32_t(3 * i)), 0.0f, 0.5f * test::hash01(uint32_t(3 * i + 1)), 0.0f);
    irradiance[i] = glm::vec4(10.0f * test::hash01(uint32_t(3 * i + 2)), 1.0f + float(i % 5), 2.0f, 0.0f);
  }
  const std::vector<glm::vec3> probes = {{0.0f, 0.0f, 0.0f}, {1.0f, -2.0f, 0.5f}, {-3.0f, 2.5f, 1.0f}};
  VirOptions full;
  full.resolution = 16;
  full.lod = false;
  VirOptions leaves = full;  // a cut of leaves only: no merged node is ever narrow enough
  leaves.lod = true;
  leaves.lodTexels = 1e-3f;
  leaves.lodBlockProbes = 2;
  VirOptions merged = leaves;
  merged.lodTexels = 4.0f;
  const auto sameRadiance = [](const ProbeAtlas& a, const ProbeAtlas& b, float tol) {
    size_t same = 0, both = 0;
    for (size_t t = 0; t < a.radiance.size(); ++t) {
      if (a.normal[t].w != 1.0f || b.normal[t].w != 1.0f || a.distance[t].x != b.distance[t].x) continue;
      ++both;
      const glm::vec3 d = glm::abs(glm::vec3(a.radiance[t]) - glm::vec3(b.radiance[t]));
      if (std::max({d.x, d.y, d.z}) <= tol * (1.0f + std::abs(a.radiance[t].x) + std::abs(a.radiance[t].y)))
        ++same;
    }
    return std::pair(same, both);
  };
  {
    const ProbeAtlas a = pass.run(surfels, probes, full, irradiance);
    const ProbeAtlas b = pass.run(surfels, probes, leaves, irradiance);
    const auto [same, both] = sameRadiance(a, b, 1e-6f);
    std::printf("LOD leaves vs full splat: %zu of %zu texels with the same depth have the same radiance\n",
                same, both);
    EXPECT_GT(both, a.radiance.size() / 2);  // the same winner (depth) in most texels
    EXPECT_EQ(same, both);
  }
  for (const VirOptions& o : {leaves, merged}) {
    const ProbeAtlas unlit = pass.run(surfels, probes, o);
    const ProbeAtlas zero =
        pass.run(surfels, probes, o, std::vector<glm::vec4>(surfels.size(), glm::vec4(0.0f)));
    EXPECT_EQ(unlit.lodRadianceMs, 0.0);  // no radiance pass ran
    const auto [same, both] = sameRadiance(unlit, zero, 1e-5f);
    EXPECT_GT(both, unlit.radiance.size() * 9 / 10);  // the same splat: the same winners
    EXPECT_EQ(same, both);
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// LOD on vs off (VirOptions::lod) on a closed 40 m box at the default surfel density (at N <= 16 many
// surfels per texel, where the cut replaces them with merged discs): same distances, normals and coverage,
// radiance within a few % (merged discs carry the area-weighted mean), and far fewer (disc, probe) pairs. A
// second call with other irradiance reuses the resident tree and relights it.
TEST(VirPass, LodMatchesFullSplatWithFarFewerPairs) {
  auto ctx = createContext();
  VirPass pass(*ctx);
  const float h = 20.0f;
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(h, 0.5f);
  std::vector<glm::vec4> irradiance(surfels.size());
  for (size_t i = 0; i < surfels.size(); ++i) {
    const glm::vec3 p(surfels[i].positionRadius);
    irradiance[i] =
        glm::vec4(2.0f + std::sin(p.x), 1.0f + 0.1f * p.y, 3.0f * test::hash01(uint32_t(i)), 0.0f);
  }
  const std::vector<glm::vec3> probes = {{0.0f, 0.0f, 0.0f},
                                         {2.0f, 0.0f, 0.0f},
                                         {0.0f, 2.0f, 1.0f},
                                         {8.0f, -4.0f, 4.0f},
                                         {-12.0f, 10.0f, -14.0f}};
  for (int n : {8, 16}) {
    VirOptions full;
    full.resolution = n;
    full.maxRange = 100.0f;
    full.lod = false;
    VirOptions lod = full;
    lod.lod = true;
    lod.lodBlockProbes = 3;
    const ProbeAtlas a = pass.run(surfels, probes, full, irradiance);
    const ProbeAtlas b = pass.run(surfels, probes, lod, irradiance);
    ASSERT_EQ(a.distance.size(), b.distance.size());
    std::vector<double> distDiff, angle, refErr;
    double radA = 0.0, radB = 0.0;
    for (size_t t = 0; t < a.distance.size(); ++t) {
      if (a.normal[t].w == 0.0f || b.normal[t].w == 0.0f) continue;
      distDiff.push_back(std::abs(double(b.distance[t].x) - a.distance[t].x) / a.distance[t].x);
      const float c = std::clamp(glm::dot(glm::vec3(a.normal[t]), glm::vec3(b.normal[t])), -1.0f, 1.0f);
      angle.push_back(double(std::acos(c)) * 180.0 / std::numbers::pi);
      radA += a.radiance[t].x + a.radiance[t].y + a.radiance[t].z;
      radB += b.radiance[t].x + b.radiance[t].y + b.radiance[t].z;
      const size_t p = t / (size_t(n) * size_t(n)), j = (t / size_t(n)) % size_t(n), i = t % size_t(n);
      glm::vec3 wall(0.0f);
      const float ref =
          boxDistance(probes[p], shared::octTexelDirection(glm::uvec2(i, j), uint32_t(n)), h, &wall);
      refErr.push_back(std::abs(double(b.distance[t].x) - ref) / ref);
    }
    std::sort(distDiff.begin(), distDiff.end());
    const double p90 = distDiff[distDiff.size() * 9 / 10];
    std::printf(
        "VIR LOD vs full, box N=%d: %zu surfels, %llu nodes; pairs %llu vs %llu (%.1fx fewer), %llu atomics; "
        "dist "
        "diff median %.4f p90 %.4f, vs analytic median %.4f; normal median %.2f deg; radiance sum ratio "
        "%.4f; holes "
        "%.4f -> %.4f (full %.4f -> %.4f); splat %.2f vs %.2f ms, LOD build %.1f ms\n",
        n, surfels.size(), (unsigned long long)b.lodNodes, (unsigned long long)b.splatPairs,
        (unsigned long long)a.splatPairs, double(a.splatPairs) / double(b.splatPairs),
        (unsigned long long)b.splatAtomics, test::median(distDiff), p90, test::median(refErr),
        test::median(angle), radB / radA, b.holeFractionBeforeFill, b.holeFractionAfterFill,
        a.holeFractionBeforeFill, a.holeFractionAfterFill, b.splatMs, a.splatMs, b.lodBuildMs);
    EXPECT_LE(test::median(distDiff), 0.01);
    EXPECT_LE(p90, 0.05);
    EXPECT_LE(test::median(refErr), 0.02);
    EXPECT_LE(test::median(angle), 1.0);
    EXPECT_NEAR(radB / radA, 1.0, 0.03);
    EXPECT_LE(b.holeFractionAfterFill, 0.01);
    EXPECT_LE(b.holeFractionBeforeFill, a.holeFractionBeforeFill + 0.02);
    EXPECT_LT(b.splatPairs * 4, a.splatPairs);  // measured 44x (N = 8), 14x (N = 16) with lodTexels 4
    EXPECT_GT(b.splatAtomics, 0u);
    EXPECT_EQ(a.splatAtomics, 0u);
  }
  // Resident tree reused; the radiance follows the new irradiance (E doubled: albedo E / pi doubled).
  VirOptions lod;
  lod.maxRange = 100.0f;
  lod.lod = true;
  lod.lodBlockProbes = 3;
  const ProbeAtlas once = pass.run(surfels, probes, lod, irradiance);
  for (glm::vec4& e : irradiance) e *= 2.0f;
  const ProbeAtlas twice = pass.run(surfels, probes, lod, irradiance);
  EXPECT_EQ(twice.lodBuildMs, 0.0);
  double s1 = 0.0, s2 = 0.0;
  for (size_t t = 0; t < once.radiance.size(); ++t) {
    s1 += once.radiance[t].x;
    s2 += twice.radiance[t].x;
  }
  EXPECT_NEAR(s2 / s1, 2.0, 1e-3);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// Occlusion culling (VirOptions::lodOcclusionRange) changes no output bit: probes in a 12 m room with a
// 3 x 3 m window in its +x wall, among 1 m cubes on a 4 m grid out to 18 m that only the window shows (each
// cube face is its own plane, so the LOD tree cannot merge them: the far geometry of a city). Every channel
// and the hole fractions must equal a run without culling, while the far pass drops some of the cubes'
// pairs (a bound that is wrong, e.g. a sphere too small or a window that misses texels, shows as a
// differing texel).
TEST(VirPass, LodOcclusionCullingIsExactAndDropsHiddenSurfels) {
  std::vector<shared::Surfel> surfels;
  for (const shared::Surfel& sf : test::inwardBoxSurfels(6.0f, 0.5f)) {
    const glm::vec3 p(sf.positionRadius);
    if (!(p.x > 5.9f && std::abs(p.y) < 1.5f && std::abs(p.z) < 1.5f)) surfels.push_back(sf);
  }
  const size_t inner = surfels.size();
  const std::vector<shared::Surfel> cube = test::inwardBoxSurfels(0.5f, 0.5f);
  for (int k = 0; k < 1000; ++k) {
    const glm::vec3 c =
        glm::vec3(float(k % 10), float(k / 10 % 10), float(k / 100)) * 4.0f - glm::vec3(18.0f);
    if (glm::all(glm::lessThan(glm::abs(c), glm::vec3(8.0f)))) continue;
    for (shared::Surfel sf : cube) {
      sf.positionRadius += glm::vec4(c, 0.0f);
      sf.normal = -sf.normal;
      surfels.push_back(sf);
    }
  }
  std::vector<glm::vec4> irradiance(surfels.size());
  for (size_t i = 0; i < surfels.size(); ++i)
    irradiance[i] = glm::vec4(1.0f + 3.0f * test::hash01(uint32_t(i)), 2.0f, 0.5f, 0.0f);
  std::vector<glm::vec3> probes;
  for (int k = 0; k < 27; ++k)
    probes.push_back(glm::vec3(float(k % 3) - 1.0f, float(k / 3 % 3) - 1.0f, float(k / 9) - 1.0f) * 2.5f);
  auto ctx = createContext();
  VirPass pass(*ctx);
  for (int n : {8, 16}) {
    VirOptions off;
    off.resolution = n;
    off.maxRange = 100.0f;
    VirOptions on = off;
    on.lodOcclusionRange = 8.0f;
    const ProbeAtlas a = pass.run(surfels, probes, off, irradiance);
    const ProbeAtlas b = pass.run(surfels, probes, on, irradiance);
    ASSERT_EQ(a.distance.size(), b.distance.size());
    const size_t differ = differingTexels(a, b);
    size_t covered = 0;
    for (size_t t = 0; t < a.distance.size(); ++t) covered += a.normal[t].w == LFGI_VIR_COVERED ? 1 : 0;
    std::printf(
        "VIR LOD occlusion culling, N=%d: %zu + %zu surfels, %zu probes; pairs %llu -> %llu (%llu nodes "
        "and %llu pairs dropped as occluded), atomics %llu -> %llu; %zu of %zu texels differ; splat %.1f "
        "-> %.1f ms\n",
        n, inner, surfels.size() - inner, probes.size(), (unsigned long long)a.splatPairs,
        (unsigned long long)b.splatPairs, (unsigned long long)b.occludedNodes,
        (unsigned long long)b.occludedPairs, (unsigned long long)a.splatAtomics,
        (unsigned long long)b.splatAtomics, differ, a.distance.size(), a.splatMs, b.splatMs);
    EXPECT_EQ(differ, 0u);
    EXPECT_EQ(a.holeFractionBeforeFill, b.holeFractionBeforeFill);
    EXPECT_EQ(a.holeFractionAfterFill, b.holeFractionAfterFill);
    EXPECT_GT(covered, a.distance.size() * 9 / 10);
    EXPECT_EQ(a.occludedNodes + a.occludedPairs, 0u);
    EXPECT_GT(b.occludedNodes, 0u);
    EXPECT_GT(b.occludedPairs, 0u);
    // Measured 9 % (N = 8) and 19 % (N = 16) fewer pairs splatted, 13-17 % fewer atomics: the room's own
    // far corners (beyond 8 m) and the window leave holes in the near pass's HiZ, so coarse levels rarely
    // cull.
    EXPECT_LT(double(b.splatPairs - b.occludedPairs), 0.95 * double(a.splatPairs));
    EXPECT_LT(b.splatAtomics, a.splatAtomics);
  }
  VirOptions bad;
  bad.lodOcclusionRange = -1.0f;
  EXPECT_THROW(pass.run(surfels, probes, bad), Error);
  bad = VirOptions{};
  bad.lodBlockProbes = LFGI_VIR_LOD_MAX_BLOCK_PROBES + 1;
  EXPECT_THROW(pass.run(surfels, probes, bad), Error);
  for (const float elongation : {0.5f, 8.5f, std::nanf("")}) {
    bad = VirOptions{};
    bad.lodElongation = elongation;
    EXPECT_THROW(pass.run(surfels, probes, bad), Error) << elongation;
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// VirOptions::reuseSplat: a run whose surfels, probes and splat options equal the previous run's keeps its
// winners and only resolves again. With new irradiance the result must be bit-identical to a fresh splat
// (a second VirPass with reuse off), for the LOD and the full splat; changing a probe, a surfel or a splat
// option must splat again, and so must a run after another surfel set (one cache, as relightFrame's NEE
// runs would alternate if they shared a VirPass); fillPasses alone does not.
TEST(VirPass, ReusedSplatIsBitIdenticalToAFreshSplat) {
  auto ctx = createContext();
  VirPass pass(*ctx), fresh(*ctx);
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(6.0f, 0.5f);
  for (const shared::Surfel& sf : test::inwardBoxSurfels(1.0f, 0.25f)) {  // an occluder inside
    shared::Surfel o = sf;
    o.normal = -o.normal;
    o.positionRadius += glm::vec4(2.0f, 0.5f, 1.0f, 0.0f);
    surfels.push_back(o);
  }
  const auto irradianceFor = [&](uint32_t seed) {
    std::vector<glm::vec4> e(surfels.size());
    for (size_t i = 0; i < e.size(); ++i)
      e[i] = glm::vec4(4.0f * test::hash01(uint32_t(i) * 3 + seed), 1.0f + float(seed), 0.5f, 0.0f);
    return e;
  };
  const std::vector<glm::vec3> probes = {{0, 0, 0}, {-2, 1, 0}, {1, -2, -3}, {3, 3, 3}, {-4, -1, 2}};
  for (const bool lod : {true, false}) {
    VirOptions o;
    o.resolution = 16;
    o.maxRange = 50.0f;
    o.lod = lod;
    VirOptions noReuse = o;
    noReuse.reuseSplat = false;
    const ProbeAtlas first = pass.run(surfels, probes, o, irradianceFor(1));
    EXPECT_FALSE(first.splatReused);
    const ProbeAtlas again = pass.run(surfels, probes, o, irradianceFor(2));
    EXPECT_TRUE(again.splatReused) << lod;
    const ProbeAtlas ref = fresh.run(surfels, probes, noReuse, irradianceFor(2));
    EXPECT_FALSE(ref.splatReused);
    EXPECT_EQ(differingTexels(again, ref), 0u) << lod;
    EXPECT_EQ(again.splatPairs, ref.splatPairs);
    EXPECT_EQ(again.holeFractionAfterFill, ref.holeFractionAfterFill);
    EXPECT_GT(differingTexels(first, again), 0u);  // the radiance did change

    VirOptions fill = o;
    fill.fillPasses = 0;
    VirOptions fillRef = noReuse;
    fillRef.fillPasses = 0;
    const ProbeAtlas unfilled = pass.run(surfels, probes, fill, irradianceFor(3));
    EXPECT_TRUE(unfilled.splatReused);
    EXPECT_EQ(differingTexels(unfilled, fresh.run(surfels, probes, fillRef, irradianceFor(3))), 0u);

    std::vector<glm::vec3> moved = probes;
    moved[2].x += 0.25f;
    EXPECT_FALSE(pass.run(surfels, moved, o, irradianceFor(4)).splatReused);
    const ProbeAtlas back = pass.run(surfels, probes, o, irradianceFor(2));
    EXPECT_FALSE(back.splatReused);  // the moved probes' splat replaced the cached one
    EXPECT_EQ(differingTexels(back, ref), 0u);
    VirOptions finer = o;
    finer.footprintScale = 1.4f;
    EXPECT_FALSE(pass.run(surfels, probes, finer, irradianceFor(2)).splatReused);
    std::vector<shared::Surfel> shifted = surfels;
    shifted.back().positionRadius.y += 0.01f;
    EXPECT_FALSE(pass.run(shifted, probes, o, irradianceFor(2)).splatReused);
    EXPECT_FALSE(pass.run(surfels, probes, o, irradianceFor(2)).splatReused);
    EXPECT_TRUE(pass.run(surfels, probes, o, irradianceFor(5)).splatReused);
    EXPECT_FALSE(pass.run(surfels, probes, noReuse, irradianceFor(5)).splatReused);
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// The LOD splat tests only the texels inside each footprint's projected outline (vir_lod_splat.comp). Against
// a brute-force CPU splat of the same cut (gpu::virLodCut, every node against every texel-centre ray of the
// map): every texel whose ray hits a cut footprint shrunk by 0.1 % is covered at the nearest such depth, and
// no texel is covered whose ray misses every footprint grown by 0.1 %. Axis-aligned walls of a box (merged
// rectangles, many crossing the octant planes through the probe) and a tilted panel (back-facing from some
// probes); a span that dropped the texels along a footprint's edges would leave covered texels uncovered.
TEST(VirPass, LodSplatCoversExactlyTheFootprintsOfItsCut) {
  std::vector<shared::Surfel> surfels = test::inwardBoxSurfels(8.0f, 0.25f);
  const std::vector<shared::Surfel> panel =
      test::panelSurfels(glm::vec3(1.0f, -3.0f, 0.5f), glm::normalize(glm::vec3(0.35f, 1.0f, 0.2f)), 20, 0.2f,
                         0.2f / std::sqrt(std::numbers::pi_v<float>));
  surfels.insert(surfels.end(), panel.begin(), panel.end());
  const std::vector<glm::vec3> probes = {{0.0f, 0.0f, 0.0f},
                                         {2.5f, -1.0f, 1.5f},
                                         {-5.0f, 4.0f, -3.0f},
                                         {1.0f, -1.5f, 0.5f},
                                         {0.5f, -4.5f, 2.5f}};
  VirOptions o;
  o.resolution = 32;
  o.maxRange = 100.0f;
  o.maxFootprintRadius = 8;  // no footprint here reaches the cap
  o.fillPasses = 0;
  auto ctx = createContext();
  VirPass pass(*ctx);

  VirLodBuildOptions bo;
  bo.footprintScale = o.footprintScale;
  const VirLodTree tree = buildVirLodTree(surfels, bo);
  const shared::VirLodParams lp = virLodClassifyParams(o);
  const uint32_t n = uint32_t(o.resolution);
  // Depth along unit ray td from the probe to node i's footprint scaled by `grow`; +inf: no hit.
  const auto hitDepth = [&](uint32_t i, glm::vec3 probe, glm::vec3 td, float grow) {
    const glm::vec3 pos(tree.nodes[i].positionRadius), nrm(tree.nodes[i].normal);
    const float facing = -glm::dot(nrm, pos - probe), denom = -glm::dot(nrm, td);
    if (facing <= 0.0f || denom <= 1e-6f) return INFINITY;
    const float depth = facing / denom;
    const glm::vec3 h = probe + depth * td - pos;
    const glm::vec4 rect = tree.rects[i];
    bool hit = false;
    if (rect.z >= 0.0f) {
      const glm::vec3 t1 = shared::octDecode(glm::vec2(rect.x, rect.y)), t2 = glm::cross(nrm, t1);
      hit = std::abs(glm::dot(h, t1)) <= rect.z * grow && std::abs(glm::dot(h, t2)) <= rect.w * grow;
    } else {
      const float r = tree.nodes[i].positionRadius.w * o.footprintScale * grow;
      hit = glm::dot(h, h) <= r * r;
    }
    return hit ? depth : INFINITY;
  };
  // One probe per block, blocks of 2 (runs of the Morton order, VirPass's virLodBlock bounds), then one block
  // of all: every probe of a block splats the block's cut (vir_lod_splat.comp is node-major within a block).
  for (const int blockProbes : {1, 2, LFGI_VIR_LOD_MAX_BLOCK_PROBES}) {
    o.lodBlockProbes = blockProbes;
    const ProbeAtlas atlas = pass.run(surfels, probes, o);
    std::vector<shared::VirLodBlock> block(probes.size());  // of each probe's block
    const std::vector<uint32_t> order = virProbeBlockOrder(probes);
    for (size_t b0 = 0; b0 < order.size(); b0 += size_t(blockProbes)) {
      const size_t b1 = std::min(order.size(), b0 + size_t(blockProbes));
      std::vector<glm::vec3> members;
      for (size_t k = b0; k < b1; ++k) members.push_back(probes[order[k]]);
      const shared::VirLodBlock bounds = virLodBlock(members);
      for (size_t k = b0; k < b1; ++k) block[order[k]] = bounds;
    }
    size_t covered = 0, missed = 0, extra = 0, badDepth = 0, cutNodes = 0, rectNodes = 0;
    for (size_t p = 0; p < probes.size(); ++p) {
      const std::vector<uint32_t> cut = virLodCut(tree, block[p], lp);
      cutNodes += cut.size();
      for (uint32_t i : cut) rectNodes += tree.rects[i].z >= 0.0f ? 1 : 0;
      for (uint32_t j = 0; j < n; ++j)
        for (uint32_t i = 0; i < n; ++i) {
          const glm::vec3 td = shared::octTexelDirection(glm::uvec2(i, j), n);
          float inner = INFINITY, outer = INFINITY;  // nearest hit of the shrunk / grown footprints
          for (uint32_t c : cut) {
            inner = std::min(inner, hitDepth(c, probes[p], td, 0.999f));
            outer = std::min(outer, hitDepth(c, probes[p], td, 1.001f));
          }
          const size_t t = (p * n + j) * n + i;
          const bool gpu = atlas.normal[t].w == LFGI_VIR_COVERED;
          covered += gpu ? 1 : 0;
          if (std::isfinite(inner) && !gpu) ++missed;
          if (!std::isfinite(outer) && gpu) ++extra;
          if (gpu && std::isfinite(outer) &&
              !(atlas.distance[t].x >= outer * (1.0f - 1e-5f) &&
                atlas.distance[t].x <= inner * (1.0f + 1e-5f)))
            ++badDepth;
        }
    }
    std::printf(
        "VIR LOD splat vs brute force, N=%u, %d probes per block: %zu cut nodes (%zu rectangles) over %zu "
        "probes, %zu texels "
        "covered; %zu missed, %zu extra, %zu off in depth; %llu texel tests for %llu atomics, %llu of %llu "
        "pairs through the square window\n",
        n, blockProbes, cutNodes, rectNodes, probes.size(), covered, missed, extra, badDepth,
        (unsigned long long)atlas.splatTexelTests, (unsigned long long)atlas.splatAtomics,
        (unsigned long long)atlas.splatWindowPairs, (unsigned long long)atlas.splatPairs);
    EXPECT_GT(covered, probes.size() * n * n * 9 / 10);
    EXPECT_EQ(missed, 0u);
    EXPECT_EQ(extra, 0u);
    EXPECT_EQ(badDepth, 0u);
    if (blockProbes == LFGI_VIR_LOD_MAX_BLOCK_PROBES) continue;  // one wide block: a cut of mostly leaves
    EXPECT_GT(rectNodes, cutNodes / 2);
    // Tight spans: measured 6.0 ray tests per hit here with the default near-miss zone (4.5 without it,
    // VirOptions::fillNearMiss = 0; the square windows alone: 17.4), most of them in the pairs whose
    // footprint crosses an octant plane through the probe (19 % here, square windows).
    EXPECT_LT(atlas.splatTexelTests, 7 * atlas.splatAtomics);
    EXPECT_LT(atlas.splatWindowPairs * 3, atlas.splatPairs);
  }
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

// No device: the option ranges VirPass::run takes, each bad field rejected by a message naming it.
TEST(VirOptions, DefaultsValidateAndEachBadFieldIsRejectedByName) {
  EXPECT_NO_THROW(VirOptions{}.validate());
  struct Bad {
    const char* field;
    void (*set)(VirOptions&);
  };
  const Bad bad[] = {
      {"resolution", [](VirOptions& o) { o.resolution = 0; }},
      {"resolution", [](VirOptions& o) { o.resolution = 1025; }},
      {"maxRange", [](VirOptions& o) { o.maxRange = 0.0f; }},
      {"maxRange", [](VirOptions& o) { o.maxRange = std::numeric_limits<float>::infinity(); }},
      {"footprintScale", [](VirOptions& o) { o.footprintScale = -1.0f; }},
      {"footprintScale", [](VirOptions& o) { o.footprintScale = std::numeric_limits<float>::quiet_NaN(); }},
      {"maxFootprintRadius", [](VirOptions& o) { o.maxFootprintRadius = -1; }},
      {"maxFootprintRadius", [](VirOptions& o) { o.maxFootprintRadius = 9; }},
      {"fillPasses", [](VirOptions& o) { o.fillPasses = -1; }},
      {"fillPasses", [](VirOptions& o) { o.fillPasses = VirOptions::kMaxFillPasses + 1; }},
      {"fillNearMiss", [](VirOptions& o) { o.fillNearMiss = -0.5f; }},
      {"fillNearMiss", [](VirOptions& o) { o.fillNearMiss = std::numeric_limits<float>::quiet_NaN(); }},
      {"lodTexels", [](VirOptions& o) { o.lodTexels = 0.0f; }},
      {"lodTexels", [](VirOptions& o) { o.lodTexels = 16.5f; }},
      {"lodElongation", [](VirOptions& o) { o.lodElongation = 0.5f; }},
      {"lodElongation", [](VirOptions& o) { o.lodElongation = 9.0f; }},
      {"lodDepthTolerance", [](VirOptions& o) { o.lodDepthTolerance = -0.01f; }},
      {"lodDepthTolerance", [](VirOptions& o) { o.lodDepthTolerance = 1.5f; }},
      {"lodBlockProbes", [](VirOptions& o) { o.lodBlockProbes = 0; }},
      {"lodBlockProbes", [](VirOptions& o) { o.lodBlockProbes = LFGI_VIR_LOD_MAX_BLOCK_PROBES + 1; }},
      {"lodOcclusionRange", [](VirOptions& o) { o.lodOcclusionRange = -1.0f; }},
      {"lodOcclusionRange",
       [](VirOptions& o) { o.lodOcclusionRange = std::numeric_limits<float>::infinity(); }},
  };
  for (const Bad& b : bad) {
    VirOptions o;
    b.set(o);
    try {
      o.validate();
      ADD_FAILURE() << b.field << ": accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("VIR: ") + b.field + " "), std::string::npos)
          << b.field << ": " << e.what();
    }
  }
  // The ends of each range are accepted.
  VirOptions edge;
  edge.resolution = 1024;
  edge.maxFootprintRadius = 8;
  edge.fillPasses = VirOptions::kMaxFillPasses;
  edge.fillNearMiss = 0.0f;
  edge.lodTexels = 16.0f;
  edge.lodElongation = 8.0f;
  edge.lodDepthTolerance = 1.0f;
  edge.lodBlockProbes = LFGI_VIR_LOD_MAX_BLOCK_PROBES;
  edge.lodOcclusionRange = 0.0f;
  EXPECT_NO_THROW(edge.validate());
  edge.resolution = 1;
  edge.maxFootprintRadius = 0;
  edge.fillPasses = 0;
  edge.lodElongation = 1.0f;
  edge.lodDepthTolerance = 0.0f;
  edge.lodBlockProbes = 1;
  edge.lodOcclusionRange = 1e6f;
  EXPECT_NO_THROW(edge.validate());
}

}  // namespace
}  // namespace lfgi::gpu
