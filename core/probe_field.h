// ProbeField: one cell's light field on the CPU, in the one layout every probe source produces (Embree
// capture, VIR, codec decode, SH/raw baselines) and every consumer reads (shading, streaming, metrics).
// Octahedral maps use the core/octahedral.h interior layout (texel (i, j) at j * n + i), probe-major.
#pragma once

#include <cstdint>
#include <vector>

#include "core/probe_grid.h"

namespace lfgi {

// The irradiance map size m the streamed decode gives a field of n x n radiance maps (cells read by the
// streaming manager, and `lfgi render --probes codec`, which shows what streams): max(2, n / 2).
constexpr int streamedIrradianceResolution(int n) {
  return n / 2 > 2 ? n / 2 : 2;
}

struct ProbeField {
  ProbeGrid grid;                  // probe i sits at grid.probePosition(grid.probeCoord(i)) + offsets[i]
  int resolution = 16;             // n: radiance, distance (and optional normal/albedo) maps
  int irradianceResolution = 8;    // m: irradiance maps
  std::vector<glm::vec3> offsets;  // probeCount (relocation; may be empty = all zero)
  std::vector<uint8_t> active;     // probeCount: 1 probe exists, 0 disabled (may be empty = all active)
  std::vector<float> radiance;     // probeCount * n*n*3
  std::vector<float> distance;     // probeCount * n*n*2: mean r, mean r^2 (Chebyshev visibility)
  std::vector<float> irradiance;   // probeCount * m*m*3
  std::vector<float> normal;       // optional: probeCount * n*n*3, or empty
  std::vector<float> albedo;       // optional: probeCount * n*n*3, or empty

  int64_t probeCount() const { return grid.probeCount(); }
  glm::vec3 probePosition(int64_t i) const {
    glm::vec3 p = grid.probePosition(grid.probeCoord(i));
    return offsets.empty() ? p : p + offsets[size_t(i)];
  }
  bool isActive(int64_t i) const { return active.empty() || active[size_t(i)] != 0; }
  // Throws lfgi::Error naming the first array whose size disagrees with the grid and resolutions, or
  // the first non-finite value.
  void validate() const;
  // Bytes held by the arrays (what a resident cell costs).
  size_t bytes() const;
};

}  // namespace lfgi
