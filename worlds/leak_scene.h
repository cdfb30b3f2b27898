// The light-leak test scene (procedural): a 4 x 4 x 3 m sunlit room (a big south opening and a skylight
// next to the partition) and a sealed 4 x 4 x 3 m room, sharing a partition of thickness t centred on
// x = 0; 0.3 m outer walls, a 0.25 m roof, on a ground slab. Optional emissive ceiling panel in the sealed
// room. Used by lfgi_bench_stability (leak, unseen lighting) and by the leak tests of every probe source:
// the sealed room's indirect light over the sunlit room's is the leak ratio (bench/stability.cpp).
#pragma once

#include <glm/glm.hpp>

#include "core/probe_grid.h"
#include "worlds/mesh.h"

namespace lfgi::worlds {

struct LeakScene {
  TriangleMesh mesh;
  Aabb litAir, darkAir, house;  // the two rooms' air volumes, the house's outer box
};

// t: partition thickness (m), > 0. panelRadiance: the sealed room's ceiling panel (none when 0).
LeakScene makeLeakScene(float t, glm::vec3 panelRadiance = glm::vec3(0.0f));

// Probe lattice over the house + one spacing, y layers from 0.4 m. inWall: the plane x = 0 (the partition's
// mid-plane) is a lattice plane, so without relocation a probe layer sits inside the wall; else the planes
// x = +-spacing / 2 straddle it (the classic leak set-up: a dark-room point interpolates between a probe
// on each side).
ProbeGrid leakProbeGrid(const LeakScene& s, float spacing, bool inWall = false);

}  // namespace lfgi::worlds
