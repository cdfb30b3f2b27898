#include "worlds/probe_placement.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.h"

namespace lfgi::worlds {

glm::vec3 PlacedProbes::position(int64_t i) const {
  return grid.probePosition(grid.probeCoord(i)) + offsets[size_t(i)];
}

std::vector<glm::vec3> fibonacciSphere(int n) {
  std::vector<glm::vec3> dirs(size_t(std::max(n, 1)));
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    double y = 1.0 - (2.0 * i + 1.0) / n;
    double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    double phi = golden * i;
    dirs[size_t(i)] = glm::normalize(glm::vec3(float(r * std::cos(phi)), float(y), float(r * std::sin(phi))));
  }
  return dirs;
}

float chooseProbeSpacing(double surfaceArea, double footprintArea) {
  if (!(footprintArea > 0.0)) fail("probe spacing: footprint area must be > 0 (got {})", footprintArea);
  const double density = std::max(surfaceArea / footprintArea, 1e-3);
  // 8 m at density 1, halving per 4x density (spacing ~ 1/sqrt(density): probes per surface area stay
  // roughly constant); snapped to a power of two so it divides power-of-two cell sizes.
  double s = 8.0 / std::sqrt(density);
  s = std::exp2(std::round(std::log2(std::clamp(s, 1.0, 8.0))));
  return float(s);
}

ProbeGrid cellProbeGrid(glm::vec2 cellMinXZ, float cellSize, float spacing, float bottomY, float topY,
                        int minLayers) {
  if (!(spacing > 0.0f) || !(cellSize > 0.0f) || std::fmod(cellSize, spacing) != 0.0f)
    fail("probe grid: spacing {} must be > 0 and divide the cell size {}", spacing, cellSize);
  if (!std::isfinite(bottomY) || !std::isfinite(topY) || topY < bottomY)
    fail("probe grid: bad vertical range [{}, {}]", bottomY, topY);
  ProbeGrid g;
  g.origin = glm::vec3(cellMinXZ.x, bottomY + 0.5f, cellMinXZ.y);
  g.spacing = glm::vec3(spacing);
  const int n = int(cellSize / spacing);
  const int layers = std::max(minLayers, int(std::ceil((topY + spacing - g.origin.y) / spacing)) + 1);
  g.dims = glm::ivec3(n, layers, n);
  g.validate();
  return g;
}

namespace {

struct RayStats {
  int hits = 0, backHits = 0;
  bool upwardEscapes = true, onlyTerrain = true;
  float nearestBack = INFINITY, nearestFront = INFINITY;
  glm::vec3 nearestBackDir{0.0f}, nearestFrontDir{0.0f};
};

RayStats castRays(const TriangleMesh& mesh, const TriangleBvh& bvh, glm::vec3 p,
                  const std::vector<glm::vec3>& dirs, float range) {
  RayStats s;
  for (const glm::vec3& d : dirs) {
    auto hit = bvh.intersect(p, d, range);
    if (!hit) continue;
    ++s.hits;
    if (d.y > 0.0f) s.upwardEscapes = false;
    if (mesh.materials[mesh.triangleMaterial[hit->triangle]].category != SurfaceCategory::kTerrain)
      s.onlyTerrain = false;
    if (hit->backface) {
      ++s.backHits;
      if (hit->t < s.nearestBack) s.nearestBack = hit->t, s.nearestBackDir = d;
    } else if (hit->t < s.nearestFront) {
      s.nearestFront = hit->t, s.nearestFrontDir = d;
    }
  }
  return s;
}

// RTXGI divides back-face hits by all rays; we divide by hits, because open scenes (a terrain heightfield
// seen from below, with rays escaping downwards) would otherwise pass as free space. A handful of back
// hits (a single-sided sliver seen from behind) does not make a probe "inside".
bool insideSolid(const RayStats& s, int rays, float threshold) {
  return s.backHits >= std::max(2, rays / 16) && float(s.backHits) > threshold * float(s.hits);
}

}  // namespace

PlacedProbes placeProbes(const TriangleMesh& mesh, const TriangleBvh& bvh, const ProbeGrid& grid,
                         const ProbePlacementOptions& opt) {
  grid.validate();
  const std::vector<glm::vec3> dirs = fibonacciSphere(opt.raysPerProbe);
  const float spacing = std::min(grid.spacing.x, std::min(grid.spacing.y, grid.spacing.z));
  const float maxOffset = opt.maxOffset * spacing, minFront = opt.minFrontDistance * spacing;
  PlacedProbes out;
  out.grid = grid;
  const size_t count = size_t(grid.probeCount());
  out.offsets.assign(count, glm::vec3(0.0f));
  out.flags.assign(count, 0);
  for (size_t i = 0; i < count; ++i) {
    const glm::vec3 base = grid.probePosition(grid.probeCoord(int64_t(i)));
    glm::vec3 offset(0.0f);
    RayStats s = castRays(mesh, bvh, base, dirs, opt.skyTestRange);
    // Up to three moves: out of solid through the nearest back face, then away from a too-close front face.
    for (int attempt = 0; attempt < 3; ++attempt) {
      glm::vec3 move(0.0f);
      if (insideSolid(s, opt.raysPerProbe, opt.backfaceFraction)) {
        move = s.nearestBackDir * (s.nearestBack + minFront);
      } else if (s.nearestFront < minFront) {
        move = -s.nearestFrontDir * (minFront - s.nearestFront);
      } else {
        break;
      }
      offset += move;
      if (glm::length(offset) > maxOffset) break;
      s = castRays(mesh, bvh, base + offset, dirs, opt.skyTestRange);
    }
    uint8_t& f = out.flags[i];
    if (glm::length(offset) > maxOffset || insideSolid(s, opt.raysPerProbe, opt.backfaceFraction)) {
      f = kProbeDisabledSolid;
      out.offsets[i] = glm::vec3(0.0f);
      ++out.disabled;
      continue;
    }
    out.offsets[i] = offset;
    if (offset != glm::vec3(0.0f)) f |= kProbeRelocated, ++out.relocated;
    if (s.upwardEscapes && s.onlyTerrain) f |= kProbeSkyOnly, ++out.skyOnly;
    ++out.active;
  }
  return out;
}

}  // namespace lfgi::worlds
