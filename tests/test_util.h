// Small helpers shared by the GPU and bake tests: order statistics, a counter-based hash for jitter, and
// the inward-facing surfel room the VIR / cubemap / relight tests splat (one definition, so the analytic
// rooms of those tests cannot drift apart).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <glm/glm.hpp>

#include "shared/surfel.h"

namespace lfgi::test {

// The q-quantile (0..1) of v: element floor(q * size), clamped to the last (0 for an empty vector).
inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}
inline double median(std::vector<double> v) {
  return quantile(std::move(v), 0.5);
}

// lowbias32 (Chris Wellons' integer hash) -> [0, 1) with 24 bits.
inline float hash01(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return float(x >> 8) * (1.0f / 16777216.0f);
}

// Albedo of the room wall facing -side along `axis` (the same in the surfel room and the triangle room).
inline glm::vec3 roomWallAlbedo(int axis, int side) {
  return {0.2f + 0.1f * float(axis), 0.5f, side > 0 ? 0.8f : 0.3f};
}

// The six walls of the box [-h, h]^3 as inward-facing surfels on a jittered grid of the given spacing,
// each of radius spacing / sqrt(pi) (disc areas sum to the wall area, like worlds::sampleSurfels),
// albedo roomWallAlbedo, no emission.
inline std::vector<shared::Surfel> inwardBoxSurfels(float h, float spacing) {
  std::vector<shared::Surfel> out;
  const int cells = int(std::lround(2.0f * h / spacing));
  const float radius = spacing / std::sqrt(std::numbers::pi_v<float>);
  uint32_t k = 0;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = -1; side <= 1; side += 2)
      for (int j = 0; j < cells; ++j)
        for (int i = 0; i < cells; ++i, ++k) {
          const int a = (axis + 1) % 3, b = (axis + 2) % 3;
          glm::vec3 p(0.0f), n(0.0f);
          p[axis] = float(side) * h;
          p[a] = -h + (float(i) + hash01(2 * k)) * spacing;
          p[b] = -h + (float(j) + hash01(2 * k + 1)) * spacing;
          n[axis] = -float(side);
          out.push_back({glm::vec4(p, radius), glm::vec4(n, 0.0f),
                         glm::vec4(roomWallAlbedo(axis, side), 1.0f), glm::vec4(0.0f)});
        }
  return out;
}

// A square panel of cells x cells surfels (radius r, albedo 0.5) on a lattice of the given spacing, centred
// on `centre` in the plane of unit normal n (lattice axes: n x z normalised, and n x that), facing along n.
inline std::vector<shared::Surfel> panelSurfels(glm::vec3 centre, glm::vec3 n, int cells, float spacing,
                                                float r) {
  const glm::vec3 u = glm::normalize(glm::cross(n, glm::vec3(0.0f, 0.0f, 1.0f))), v = glm::cross(n, u);
  const float half = 0.5f * float(cells - 1);
  std::vector<shared::Surfel> out;
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i)
      out.push_back({glm::vec4(centre + (float(i) - half) * spacing * u + (float(j) - half) * spacing * v, r),
                     glm::vec4(n, 0.0f), glm::vec4(0.5f), glm::vec4(0.0f)});
  return out;
}

}  // namespace lfgi::test
