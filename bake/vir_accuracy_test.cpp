// VIR (gpu/vir_pass.h) against Embree ground truth on a synthetic-world cell: per texel, the VIR distance
// and normal vs a closest-hit ray cast from the probe along the texel-centre direction (one ray per texel,
// not probe_capture's stratified texel means, so both sides sample the same direction).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "bake/embree_scene.h"
#include "gpu/vir_pass.h"
#include "shared/octahedral.h"
#include "test_util.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {
namespace {

TEST(VirAccuracy, CityCellMatchesEmbreeTexelCentreRays) {
  const worlds::SyntheticWorld world(worlds::WorldParams::smallDefault(1));
  worlds::CellCoord cell{0, 0};
  bool found = false;
  for (int z = 0; z < world.cellsZ() && !found; ++z)
    for (int x = 0; x < world.cellsX() && !found; ++x)
      if (world.cellKind({x, z}) == worlds::CellKind::kCity) {
        cell = {x, z};
        found = true;
      }
  const worlds::BuiltCell built = worlds::buildCell(world, cell);
  std::vector<glm::vec3> probes;
  std::vector<size_t> active;
  const worlds::Aabb box = built.mesh.bounds();
  for (size_t i = 0; i < built.probes.flags.size(); ++i) {
    // Active probes at least 6 m inside the cell, so most of each probe's view is this cell's geometry.
    const glm::vec3 q = built.probes.position(int64_t(i));
    const bool inner =
        q.x > box.min.x + 6.0f && q.x < box.max.x - 6.0f && q.z > box.min.z + 6.0f && q.z < box.max.z - 6.0f;
    if (!(built.probes.flags[i] & worlds::kProbeDisabledSolid) && inner) active.push_back(i);
  }
  ASSERT_FALSE(active.empty());
  const size_t want = std::min<size_t>(8, active.size());
  for (size_t k = 0; k < want; ++k)
    probes.push_back(built.probes.position(int64_t(active[k * active.size() / want])));

  auto ctx = gpu::createContext();
  gpu::VirPass pass(*ctx);
  gpu::VirOptions options;
  options.resolution = 16;
  options.maxRange = 1000.0f;
  pass.run(built.surfels, probes, options);  // warm-up: lavapipe compiles pipelines on first dispatch
  const gpu::ProbeAtlas atlas = pass.run(built.surfels, probes, options);
  EmbreeScene scene(built.mesh, "cell");

  const uint32_t n = uint32_t(options.resolution);
  std::vector<double> relErr, angleDeg;
  size_t nearer = 0, farther = 0;  // texels off by > 5 %: VIR in front of / behind the ray hit
  size_t hits = 0, hitHoles = 0, missCovered = 0, misses = 0;
  for (size_t p = 0; p < probes.size(); ++p)
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) {
        const size_t t = (p * n + j) * n + i;
        const glm::vec3 dir = shared::octTexelDirection(glm::uvec2(i, j), n);
        const std::optional<RayHit> hit = scene.intersect(probes[p], dir);
        const bool covered = atlas.normal[t].w > 0.0f;
        if (!hit) {
          ++misses;
          missCovered += atlas.normal[t].w == 1.0f ? 1 : 0;
          continue;
        }
        ++hits;
        if (!covered) {
          ++hitHoles;
          continue;
        }
        relErr.push_back(std::abs(double(atlas.distance[t].x) - hit->t) / double(hit->t));
        if (relErr.back() > 0.05) (atlas.distance[t].x < hit->t ? nearer : farther) += 1;
        if (!hit->backface) {
          const float c = std::clamp(glm::dot(glm::vec3(atlas.normal[t]), hit->normal), -1.0f, 1.0f);
          angleDeg.push_back(double(std::acos(c)) * 180.0 / std::numbers::pi);
        }
      }
  const double medErr = test::quantile(relErr, 0.5), medAngle = test::quantile(angleDeg, 0.5);
  std::printf(
      "VIR vs Embree, cell %d,%d: %zu surfels, %zu probes, N=%u: median |dr|/r %.4f (p90 %.4f), median "
      "normal "
      "angle %.2f deg (p90 %.2f), holes among hit texels %.4f, sky texels covered %zu of %zu; holes %.4f -> "
      "%.4f; splat %.2f "
      "ms, resolve %.2f ms, fill %.2f ms\n",
      cell.x, cell.z, built.surfels.size(), probes.size(), n, medErr, test::quantile(relErr, 0.9), medAngle,
      test::quantile(angleDeg, 0.9), hits ? double(hitHoles) / double(hits) : 0.0, missCovered, misses,
      atlas.holeFractionBeforeFill, atlas.holeFractionAfterFill, atlas.splatMs, atlas.resolveMs,
      atlas.fillMs);
  std::printf("off by > 5 %%: %zu nearer, %zu farther of %zu compared texels\n", nearer, farther,
              relErr.size());
  ASSERT_GT(hits, probes.size() * n * n / 4);
  EXPECT_LE(medErr, 0.02);
  EXPECT_LE(test::quantile(relErr, 0.9), 0.05);
  EXPECT_LE(double(nearer + farther) / double(relErr.size()), 0.1);
  EXPECT_LE(medAngle, 5.0);
  EXPECT_LE(double(hitHoles) / double(hits), 0.01);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

}  // namespace
}  // namespace lfgi::bake
