// ProbeGrid: the index space of one cell's probes (docs/DESIGN.md §2). Probe (x, y, z) sits at
// origin + (x, y, z) * spacing, metres, +Y up. Linear indices run x fastest, then y, then z.
//
// Ownership is half-open: a grid owns the box [origin, origin + dims * spacing) on each axis, so the
// probes at origin + i * spacing, 0 <= i < dims, are its own and a point on a face shared with the next
// cell (whose origin is this grid's boxMax()) belongs to exactly one of them. Shading near that face
// reads the neighbour's probes; within one grid, lookups clamp to the grid's own probes.
#pragma once

#include <array>
#include <cstdint>

#include <glm/glm.hpp>

namespace lfgi {

// The 8 probes around a world point and their trilinear weights. Corner k (0..7) is
// base + (k & 1, (k >> 1) & 1, (k >> 2) & 1), clamped into the grid (so on an axis with dims == 1 both
// corners are probe 0 and the weights still sum to 1).
struct TrilinearProbes {
  glm::ivec3 base{0};
  std::array<glm::ivec3, 8> corners{};
  std::array<std::int64_t, 8> indices{};  // linear indices of corners
  std::array<float, 8> weights{};         // each in [0, 1], sum to 1 (up to rounding)
};

struct ProbeGrid {
  glm::vec3 origin{0.0f};
  glm::vec3 spacing{1.0f};  // metres between neighbouring probes, > 0 on each axis
  glm::ivec3 dims{1};       // probes per axis, >= 1

  // Throws lfgi::Error unless dims >= 1, spacing > 0 and finite, origin finite, and the probe count
  // fits in int64. The other members assume a valid grid.
  void validate() const;

  std::int64_t probeCount() const {
    return std::int64_t(dims.x) * std::int64_t(dims.y) * std::int64_t(dims.z);
  }
  // Precondition: 0 <= coord < dims.
  std::int64_t linearIndex(glm::ivec3 coord) const {
    return (std::int64_t(coord.z) * dims.y + coord.y) * dims.x + coord.x;
  }
  // Precondition: 0 <= index < probeCount().
  glm::ivec3 probeCoord(std::int64_t index) const;
  // World position (metres) of probe coord; any coord, also outside the grid.
  glm::vec3 probePosition(glm::ivec3 coord) const { return origin + glm::vec3(coord) * spacing; }
  // Far corner of the owned box: origin + dims * spacing (the next cell's origin).
  glm::vec3 boxMax() const { return origin + glm::vec3(dims) * spacing; }
  // True if p lies in the half-open box [origin, boxMax()) on every axis.
  bool owns(glm::vec3 p) const;
  // The 8 probes and trilinear weights for world point p (finite). Points outside the probes' hull
  // (also between the last probe and boxMax()) clamp to the nearest point of the hull.
  TrilinearProbes trilinear(glm::vec3 p) const;
};

}  // namespace lfgi
