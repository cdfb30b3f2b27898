// Probe sources besides the capture (bake/probe_sources.h) and the shading pass's ambient occlusion:
// - VIR probes shade a simple sunlit scene like captured probes do (indirect layer, stated tolerance);
// - codec probes decoded from a freshly baked world cell reproduce the capture's irradiance within the
//   error the bake stored for the cell;
// - AO on analytic configurations: open plane (exactly 1), the foot of a wall (1/2), a corner of two
//   walls (1/4), a point farther from the walls than the AO radius (exactly 1); AO scales indirect diffuse.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "bake/embree_scene.h"
#include "bake/probe_sources.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "bake/world_bake.h"
#include "core/cell_file.h"
#include "core/error.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/quantize.h"
#include "core/sh.h"
#include "streaming/cell_file_source.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {
namespace {

// A 24 m ground plane with a 2 m box on it, both grey-brown Lambertian.
worlds::TriangleMesh yardWithBox() {
  worlds::TriangleMesh mesh;
  worlds::Material m;
  m.albedo = glm::vec3(0.6f, 0.5f, 0.4f);
  const uint32_t ground = mesh.addMaterial(m);
  m.albedo = glm::vec3(0.7f, 0.3f, 0.2f);
  const uint32_t box = mesh.addMaterial(m);
  mesh.addQuad(glm::vec3(-12, 0, 12), glm::vec3(12, 0, 12), glm::vec3(12, 0, -12), glm::vec3(-12, 0, -12),
               ground);
  mesh.addBox(glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 2.0f, 1.0f), box);
  return mesh;
}

std::vector<uint8_t> shadedMask(const Image& img) {
  std::vector<uint8_t> m(size_t(img.width) * size_t(img.height), 0);
  const int w = img.channelIndex("weight");
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) m[size_t(y) * size_t(img.width) + size_t(x)] = img.at(x, y, w) > 0.0f;
  return m;
}

TEST(ProbeSources, VirProbesShadeLikeCapturedProbes) {
  const worlds::TriangleMesh mesh = yardWithBox();
  const EmbreeScene scene(mesh, "yard");
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{15.0f, 45.0f, 172, 3.0f, 0.0f});
  // Every probe outside the box (coordinates -5, -1.5, 2, 5.5 on x and z).
  const ProbeGrid grid{glm::vec3(-5.0f, 0.75f, -5.0f), glm::vec3(3.5f, 2.0f, 3.5f), glm::ivec3(4, 2, 4)};
  CaptureOptions co;
  co.samplesPerTexel = 32;
  co.maxBounces = 4;
  const ProbeField captured = captureGridField(scene, sky, grid, {}, {}, co);
  auto ctx = gpu::createContext();
  const std::vector<worlds::Surfel> surfels = worlds::sampleSurfels(mesh, {0.15f, 1});
  VirProbeOptions vo;
  vo.frames = 4;
  vo.maxRange = 40.0f;
  VirProbeStats st;
  const ProbeField vir = virProbeField(*ctx, surfels, grid, {}, {}, sky, vo, &st);
  EXPECT_EQ(st.probes, size_t(32));
  EXPECT_EQ(st.surfels, surfels.size());

  PinholeCamera cam;
  cam.position = glm::vec3(5.0f, 3.0f, 6.0f);
  cam.target = glm::vec3(0.0f, 0.5f, 0.0f);
  ShadingRenderer r(*ctx, mesh);
  const ProbeField* c[] = {&captured};
  r.setProbes(c);
  const ShadedView a = r.render(sky, cam, 24, 24);
  const ProbeField* v[] = {&vir};
  r.setProbes(v);
  const ShadedView b = r.render(sky, cam, 24, 24);
  const std::vector<uint8_t> mask = shadedMask(a.image);
  size_t n = 0;
  for (uint8_t k : mask) n += k;
  ASSERT_GT(n, size_t(24 * 24 / 3));
  const double indirect = layerRelativeRms(b.image, "indirect_diffuse.", a.image, "indirect_diffuse.", &mask);
  // Probe irradiance itself, texel by texel.
  std::vector<float> ei(vir.irradiance.begin(), vir.irradiance.end()),
      ec(captured.irradiance.begin(), captured.irradiance.end());
  const double irr = relativeRms(ei, ec);
  std::printf(
      "[ measure  ] yard + box at 15:00, 4x2x4 probes: VIR (%zu surfels, %d frames, %.2f s) vs capture (%d "
      "spp): "
      "probe irradiance rel RMS %.4f, shaded indirect diffuse rel RMS %.4f over %zu pixels\n",
      st.surfels, vo.frames, st.seconds, co.samplesPerTexel, irr, indirect, n);
  // Measured 0.018 / 0.013 (4 frames, N = 16); the bounds leave ~2x.
  EXPECT_LE(irr, 0.04);
  EXPECT_LE(indirect, 0.03);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

TEST(ProbeSources, VirProbesRefuseBadInput) {
  auto ctx = gpu::createContext();
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{});
  const ProbeGrid grid{glm::vec3(0.0f), glm::vec3(1.0f), glm::ivec3(2)};
  EXPECT_THROW(virProbeField(*ctx, {}, grid, {}, {}, sky, {}), Error);
  const std::vector<worlds::Surfel> s = worlds::sampleSurfels(yardWithBox(), {1.0f, 1});
  const std::vector<uint8_t> wrongActive(3, 1);
  EXPECT_THROW(virProbeField(*ctx, s, grid, {}, wrongActive, sky, {}), Error);
  VirProbeOptions bad;
  bad.frames = 0;
  EXPECT_THROW(virProbeField(*ctx, s, grid, {}, {}, sky, bad), Error);
  // No active probe: an all-inactive field, nothing run.
  const std::vector<uint8_t> none(8, 0);
  const ProbeField f = virProbeField(*ctx, s, grid, {}, none, sky, {});
  EXPECT_FALSE(f.isActive(0));
}

// The tiny bake both world-cell tests use (the generator codec, resolution 8, 2 spp, 1 bounce, 40 training
// steps).
WorldBakeSettings tinyBakeSettings(const std::string& keys, double errorTarget) {
  WorldBakeSettings s;
  s.codec = "per-cell";
  s.resolution = 8;
  s.spp = 2;
  s.bounces = 1;
  s.maxSteps = 40;
  s.keys = keys;
  s.errorTarget = errorTarget;
  return s;
}

TEST(ProbeSources, CodecProbesMatchTheCaptureWithinTheBakedError) {
  const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
  // Noon sun: the bake trains without the directly seen disc, so the decoded maps match the capture
  // with its disc taken out (what shading reads); a target no SH meets forces a generator.
  const WorldBakeSettings s = tinyBakeSettings("12", 0.001);
  const worlds::CellCoord cell{1, 0};
  CellBakeInputs in = prepareCellBake(world, cell, s);
  const worlds::BuiltCell built = in.built;
  const EmbreeScene scene(in.sceneMesh, "cell 1,0 + neighbours");
  const CellFile cf = bakeCell(world, std::move(in), s);
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{12.0f, 45.0f, 172, 3.0f, 0.0f});
  const ProbeField decoded = codecProbeField(cf, "cell 1,0", sky, s.resolution);
  // The bake's own capture (same options, same per-probe seeds), disc light taken out the same way.
  CaptureOptions co = worldBakeCaptureOptions(world, s);
  co.irradianceResolution = decoded.irradianceResolution;
  const ProbeField truth =
      captureGridField(scene, sky, built.probes.grid, built.probes.offsets, cf.active, co);
  ASSERT_EQ(decoded.irradiance.size(), truth.irradiance.size());
  std::vector<float> a, b;
  for (int64_t i = 0; i < decoded.probeCount(); ++i) {
    if (!decoded.isActive(i)) continue;
    const size_t m2 = size_t(decoded.irradianceResolution * decoded.irradianceResolution) * 3;
    a.insert(a.end(), decoded.irradiance.begin() + ptrdiff_t(size_t(i) * m2),
             decoded.irradiance.begin() + ptrdiff_t(size_t(i + 1) * m2));
    b.insert(b.end(), truth.irradiance.begin() + ptrdiff_t(size_t(i) * m2),
             truth.irradiance.begin() + ptrdiff_t(size_t(i + 1) * m2));
  }
  ASSERT_FALSE(a.empty());
  const double e = relativeRms(a, b);
  std::printf(
      "[ measure  ] codec cell 1,0 (%s): decoded irradiance vs capture rel RMS %.4f (bake stored %.4f)\n",
      cf.stats.model.c_str(), e, cf.stats.errorAchieved);
  // Same operator on both sides as the bake's stored error (irradiance of the decoded radiance vs the
  // capture's), so they agree up to FP16 and the clamp of negative radiance. (The tiny bake picks SH L1:
  // the generator path is checked below.)
  EXPECT_NEAR(e, cf.stats.errorAchieved, 0.1 * cf.stats.errorAchieved + 0.005);
}

// The fallback of a baked tiny-world cell: one SH L1 per lighting key, sorted by hour whatever the
// --keys order, and streamed at the time of day (CellFileSource): real captures move between keys.
TEST(WorldBake, FallbackHasOneShPerKeyAndStreamsWithTheTimeOfDay) {
  const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});
  const WorldBakeSettings s = tinyBakeSettings("17.5,8,12", 1.0);  // SH L1 meets the target: no training
  const worlds::CellCoord cell{1, 0};
  const CellFile cf = bakeCell(world, prepareCellBake(world, cell, s), s);
  ASSERT_EQ(cf.fallback.kind, CellFallback::Kind::PerCell);
  EXPECT_EQ(cf.fallback.keyHours, (std::vector<float>{8.0f, 12.0f, 17.5f}));
  EXPECT_EQ(cf.fallback.keyOvercast, (std::vector<float>{0.0f, 0.0f, 0.0f}));
  ASSERT_EQ(cf.fallback.shHalf.size(), 36u);
  // Written and streamed: a world directory holding this one cell (the others stream its fallback).
  const std::filesystem::path dir = std::filesystem::path(LFGI_TEST_TMP_DIR) / "world_bake_fallback_keys";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "baked" / "cells");
  worlds::writeWorldManifest(dir, world.params());
  writeCellFile(cellFilePath(dir / "baked", cell), cf);
  streaming::CellFileSourceOptions o;
  o.worldDir = dir;
  streaming::CellFileSource source(o);
  ASSERT_EQ(source.validCells(), 1);
  EXPECT_TRUE(source.fallbackFollowsTimeOfDay());
  auto stored = [&](size_t key) {
    ShL1 sh;
    for (int k = 0; k < 4; ++k)
      for (int c = 0; c < 3; ++c)
        sh.c[size_t(k)][c] = halfToFloat(cf.fallback.shHalf[key * 12 + size_t(k) * 3 + size_t(c)]);
    return sh;
  };
  const glm::ivec2 c{cell.x, cell.z};
  source.setTimeOfDay(8.0f);
  const ShL1 morning = source.fallback(c);
  source.setTimeOfDay(17.5f);
  const ShL1 evening = source.fallback(c);
  double diff = 0.0, norm = 0.0;
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(morning.c[size_t(k)], stored(0).c[size_t(k)]);
    EXPECT_EQ(evening.c[size_t(k)], stored(2).c[size_t(k)]);
    const glm::vec3 d = evening.c[size_t(k)] - morning.c[size_t(k)];
    diff += double(glm::dot(d, d));
    norm += double(glm::dot(morning.c[size_t(k)], morning.c[size_t(k)]));
  }
  std::printf(
      "[ measure  ] baked cell 1,0 fallback: DC red 8 h %.4g, 12 h %.4g, 17.5 h %.4g; |SH 17.5 - SH 8| / |SH "
      "8| = %.3f\n",
      double(morning.c[0].x), double(stored(1).c[0].x), double(evening.c[0].x), std::sqrt(diff / norm));
  EXPECT_GT(std::sqrt(diff / norm), 0.05);  // the sun moved from east to west and sank
}

// The generator path: a cell file with random int8 weights and latents over a 2 x 2 x 2 grid with one
// probe missing decodes exactly as decodeProbeField on the active probes (negative radiance clamped),
// scattered to their grid indices; the missing probe stays inactive; irradiance is the texel sum.
TEST(ProbeSources, CodecGeneratorCellDecodesLikeTheCpuDecoder) {
  GeneratorArch arch;
  arch.latentDim = 8;
  arch.convChannels = {16, 8, kGeneratorChannels};
  CellFile cf;
  cf.grid = ProbeGrid{glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(2.0f), glm::ivec3(2)};
  cf.active.assign(8, 1);
  cf.active[5] = 0;
  CellGenerator g;
  g.weights = quantizeWeights(randomGeneratorWeights(arch, 7), WeightPrecision::Int8);
  std::vector<float> z(7 * 8);
  for (size_t i = 0; i < z.size(); ++i) z[i] = std::sin(0.7f * float(i));
  g.latents = quantizeLatents(z, 8, 8);
  cf.generator = g;
  cf.fallback.shHalf.assign(12, 0);
  worlds::TriangleMesh ground;
  const uint32_t mat = ground.addMaterial(worlds::Material{});
  ground.addQuad(glm::vec3(-9, 0, 9), glm::vec3(9, 0, 9), glm::vec3(9, 0, -9), glm::vec3(-9, 0, -9), mat);
  const EmbreeScene scene(ground, "ground");
  const worlds::SkyModel night = worlds::makeSky(worlds::SkyState{0.0f, 45.0f, 172, 3.0f, 1.0f});  // no disc
  const ProbeField f = codecProbeField(cf, "random cell", night, 99);
  ASSERT_EQ(f.resolution, 16);
  EXPECT_FALSE(f.isActive(5));
  GeneratorCpu decoder(dequantizeWeights(cf.generator->weights));
  ProbeField dense;
  dense.grid.dims = glm::ivec3(7, 1, 1);
  dense.resolution = 16;
  const auto c = conditioningVector(0.0f, 1.0f);
  decodeProbeField(decoder, dequantizeLatents(cf.generator->latents), c, cf.outputScale, dense);
  const size_t t3 = 16 * 16 * 3;
  double worst = 0.0;
  for (size_t k = 0, i = 0; i < 8; ++i) {
    if (i == 5) {
      for (size_t t = 0; t < t3; ++t) EXPECT_EQ(f.radiance[i * t3 + t], 0.0f);
      continue;
    }
    for (size_t t = 0; t < t3; ++t)
      worst = std::max(worst,
                       double(std::abs(f.radiance[i * t3 + t] - std::max(dense.radiance[k * t3 + t], 0.0f))));
    ++k;
  }
  EXPECT_EQ(worst, 0.0);
  // Irradiance texel (0, 0) of probe 0 == the exact texel sum of its decoded radiance.
  const glm::vec3 e =
      bruteForceIrradiance(std::span(f.radiance).subspan(0, t3), 16,
                           octTexelDirection(0, 0, f.irradianceResolution), octTexelSolidAngles(16));
  EXPECT_NEAR(f.irradiance[1], e.y, 1e-5 * (1.0 + std::abs(e.y)));
}

// Ambient occlusion: floor y = 0 with walls x = 0 (facing +x) and z = 0 (facing +z).
TEST(ShadingAmbientOcclusion, AnalyticCornerAndOpenPlane) {
  worlds::TriangleMesh mesh;
  worlds::Material m;
  const uint32_t mat = mesh.addMaterial(m);
  mesh.addQuad(glm::vec3(0, 0, 20), glm::vec3(20, 0, 20), glm::vec3(20, 0, 0), glm::vec3(0, 0, 0), mat);
  mesh.addQuad(glm::vec3(0, 0, 0), glm::vec3(0, 0, 20), glm::vec3(0, 5, 20), glm::vec3(0, 5, 0), mat);
  mesh.addQuad(glm::vec3(0, 0, 0), glm::vec3(0, 5, 0), glm::vec3(20, 5, 0), glm::vec3(20, 0, 0), mat);
  // Constant probes: irradiance pi everywhere, open distance moments, so indirect diffuse = albedo x AO.
  ProbeField f;
  f.grid = ProbeGrid{glm::vec3(-1.0f), glm::vec3(30.0f), glm::ivec3(2)};
  f.resolution = 4;
  f.irradianceResolution = 4;
  f.radiance.assign(8 * 16 * 3, 1.0f);
  f.irradiance.assign(8 * 16 * 3, std::numbers::pi_v<float>);
  for (int i = 0; i < 8 * 16; ++i) {
    f.distance.push_back(1e4f);
    f.distance.push_back(1e8f);
  }
  auto ctx = gpu::createContext();
  ShadingRenderer r(*ctx, mesh);
  const ProbeField* fields[] = {&f};
  r.setProbes(fields, 1);
  const float eps = 1e-3f;
  // open plane, foot of the x wall, corner, 1.5 m from both walls (radius 1 m: no ray reaches them)
  const std::vector<glm::vec3> points = {{10, 0, 10}, {eps, 0, 10}, {eps, 0, eps}, {1.5f, 0, 1.5f}};
  gpu::GBufferHost g;
  const int copies = 16;  // each point at 16 pixels: different per-pixel ray rotations
  g.width = int(points.size()) * copies;
  g.height = 1;
  for (const glm::vec3& p : points)
    for (int k = 0; k < copies; ++k) {
      g.position.push_back(glm::vec4(p, 1.0f));
      g.normal.push_back(glm::vec4(0, 1, 0, 1));
      g.albedo.push_back(glm::vec4(0.5f, 0.5f, 0.5f, 0.0f));
      g.emission.push_back(glm::vec4(0.0f));
    }
  gpu::ShadingOptions o;
  o.aoRadius = 1.0f;
  o.sunShadows = false;
  const worlds::SkyModel sky = worlds::makeSky(worlds::SkyState{});
  const gpu::ShadeOutputHost on = r.shadePoints(sky, g, glm::vec3(10, 2, 10), o);
  o.aoRadius = 0.0f;
  const gpu::ShadeOutputHost off = r.shadePoints(sky, g, glm::vec3(10, 2, 10), o);
  double mean[4] = {0, 0, 0, 0}, lo[4] = {1, 1, 1, 1}, hi[4] = {0, 0, 0, 0};
  double worstScale = 0.0;
  for (size_t p = 0; p < points.size(); ++p)
    for (int k = 0; k < copies; ++k) {
      const size_t i = p * size_t(copies) + size_t(k);
      const double ao = on.specular[i].w;
      mean[p] += ao / copies;
      lo[p] = std::min(lo[p], ao);
      hi[p] = std::max(hi[p], ao);
      EXPECT_EQ(off.specular[i].w, 1.0f);
      worstScale = std::max(worstScale, std::abs(double(on.diffuse[i].y) - ao * double(off.diffuse[i].y)));
    }
  std::printf(
      "[ measure  ] AO (radius 1 m, %u rays): open plane %.4f, wall foot %.4f [%.3f, %.3f], corner %.4f "
      "[%.3f, %.3f], 1.5 m from both walls %.4f\n",
      LFGI_SHADE_AO_RAYS, mean[0], mean[1], lo[1], hi[1], mean[2], lo[2], hi[2], mean[3]);
  EXPECT_EQ(lo[0], 1.0);  // nothing above an open plane
  EXPECT_EQ(lo[3], 1.0);  // the walls are beyond the radius
  // A vertical half-plane through the point hides exactly half of the cosine-weighted hemisphere, two hide
  // three quarters; 16 rays per pixel estimate it to within one or two rays.
  EXPECT_NEAR(mean[1], 0.5, 0.05);
  EXPECT_NEAR(mean[2], 0.25, 0.05);
  EXPECT_GE(lo[1], 0.5 - 2.0 / 16.0 - 1e-6);
  EXPECT_LE(hi[1], 0.5 + 2.0 / 16.0 + 1e-6);
  EXPECT_LE(hi[2], 0.25 + 2.0 / 16.0 + 1e-6);
  EXPECT_NEAR(off.diffuse[0].y, 0.5f, 1e-4f);  // albedo x pi / pi
  EXPECT_LE(worstScale, 1e-5);                 // AO multiplies indirect diffuse
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::bake
