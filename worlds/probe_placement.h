// Probe placement for one cell: a regular grid (spacing chosen from geometry density), then per probe a
// ray classification in the spirit of RTXGI's probe relocation/classification (Majercik et al. 2021,
// "Scaling Probe-Based Real-Time Dynamic Global Illumination for Production", JCGT 10(2)): a probe whose
// rays hit back faces too often is inside solid and is moved out along its nearest back-face hit, or
// disabled if that needs more than a fraction of the spacing; a probe too close to a front face is pushed
// away; a probe that sees nothing but sky and terrain is flagged so the codec can skip it.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

#include "core/probe_grid.h"
#include "worlds/mesh.h"
#include "worlds/triangle_bvh.h"

namespace lfgi::worlds {

enum ProbeFlag : uint8_t {
  kProbeRelocated = 1 << 0,      // moved away from the grid position (offset != 0)
  kProbeDisabledSolid = 1 << 1,  // inside solid and could not be moved out within the limit: no probe
  kProbeSkyOnly = 1 << 2,        // every upward ray escapes and every hit is terrain: sky + ground only
};

struct ProbePlacementOptions {
  int raysPerProbe = 64;           // Fibonacci-sphere directions (same set for every probe)
  float backfaceFraction = 0.25f;  // > this fraction of hits on back faces => inside solid (RTXGI's
                                   // threshold, but of hits, not of rays; see placeProbes)
  float minFrontDistance = 0.1f;   // fraction of spacing: closer front faces push the probe away
  float maxOffset = 0.45f;         // fraction of spacing: a larger move disables the probe instead
  float skyTestRange = 1e4f;       // m: rays longer than this count as escaping to the sky
};

struct PlacedProbes {
  ProbeGrid grid;
  std::vector<glm::vec3> offsets;  // per probe: final position = grid.position(i) + offsets[i]
  std::vector<uint8_t> flags;      // per probe: ProbeFlag bits
  size_t active = 0, relocated = 0, disabled = 0, skyOnly = 0;
  glm::vec3 position(int64_t i) const;
};

// Probe spacing for a cell from its geometry density (surface area per m^2 of footprint): about 8 m for
// open land (density ~1), 4 m for sparse buildings, 2 m for dense interiors, 1 m for very dense ones;
// always a power of two in [1, 8] m so it divides the cell size.
float chooseProbeSpacing(double surfaceArea, double footprintArea);

// The probe grid of a cell: probes at cellMin + i * spacing in x/z, i < cellSize / spacing, so the grid
// owns exactly the cell's half-open box (ProbeGrid::owns) and cells of equal spacing form one seamless
// world lattice; y layers from bottomY + 0.5 m up to topY + one spacing (at least `minLayers`).
ProbeGrid cellProbeGrid(glm::vec2 cellMinXZ, float cellSize, float spacing, float bottomY, float topY,
                        int minLayers = 3);

// Classifies and relocates every probe of grid against the geometry in bvh (which should include the
// neighbouring cells, so rays near the border see what is there). mesh is the mesh the BVH was built
// from (for hit categories). Deterministic.
PlacedProbes placeProbes(const TriangleMesh& mesh, const TriangleBvh& bvh, const ProbeGrid& grid,
                         const ProbePlacementOptions& options = {});

// Fibonacci sphere (Gonzalez 2010): n well-spread unit directions.
std::vector<glm::vec3> fibonacciSphere(int n);

}  // namespace lfgi::worlds
