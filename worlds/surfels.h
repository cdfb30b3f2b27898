// Surfels: an area-proportional point cloud of a mesh (position, normal, albedo, emission, radius) — the
// input of View-Independent Rasterization (Marrs, Watson & Healey 2017), which splats every surfel into
// every nearby probe. Stored compressed with Draco.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "shared/surfel.h"
#include "worlds/mesh.h"

namespace lfgi::worlds {

using Surfel = shared::Surfel;

// Surfel spacing for a probe spacing: a 16x16 octahedral texel subtends ~0.22 rad, i.e. a footprint of
// ~0.22 * d at distance d; the nearest surfaces of a probe are ~1 spacing away, so surfels 1/4 of the probe
// spacing apart keep about two surfels per texel there. Clamped to [0.05 m, 2 m].
float surfelSpacingForProbeSpacing(float probeSpacingM);

struct SurfelOptions {
  float spacing = 0.5f;  // mean distance between neighbouring surfels, m (density 1 / spacing^2 per m^2)
  uint64_t seed = 1;
};

// Samples the mesh: triangle t with A_t >= s^2 gets the points of a hexagonal lattice of cell area s^2
// that fall inside it (k ~ A_t / s^2), of radius sqrt(A_t / (k pi)), so their disc areas sum to A_t exactly.
// The lattice lies in the triangle's plane along in-plane axes from the world origin (first axis: world x
// projected for floors and roofs, world y for walls), offset by a hash of (seed, quantised plane), so
// coplanar triangles share one lattice and their surfels tile across shared edges. An isotropic lattice
// matters for VIR, which point-samples the discs along texel rays: per-triangle low-discrepancy points
// (R2 in the triangle's barycentric square) were stretched with the triangle, and long street and
// pavement triangles left ~half of their plane uncovered even with footprintScale 1.5 (rays fell
// through to the ground below). A sliver that holds no lattice point gets floor(A_t / s^2 + u_t)
// randomly offset R2 points (Roberts 2018) instead; smaller triangles are sampled systematically in
// mesh order (a running sum of A_t / s^2; one surfel of area s^2 each time it crosses an integer), so the
// total disc area is within s^2 of the mesh area.
// Albedo = material albedo x texture at the interpolated uv; emission = material emission; normal =
// geometric normal. Deterministic: same mesh + options => identical output. Throws lfgi::Error if
// spacing is not finite and > 0, or the mesh fails validate().
std::vector<Surfel> sampleSurfels(const TriangleMesh& mesh, const SurfelOptions& options);

// Sum of disc areas (pi r^2).
double surfelArea(std::span<const Surfel> surfels);

// Draco point-cloud encoding: position quantized to `positionBits` over the cloud's bounds (error <=
// extent / 2^bits), normal to 10 bits, albedo as 8-bit linear, emission as FP16 bits (clamped to 65504,
// see core/half.h) and radius in units of 0.1 mm as uint16 (both lossless integer streams). Point order is
// not preserved (kd-tree coding). Deterministic bytes for the same input.
struct SurfelCodecStats {
  size_t rawBytes = 0;      // surfels * 13 floats (pos, normal, albedo, emission, radius)
  size_t encodedBytes = 0;  // Draco bytes
  double ratio() const { return encodedBytes ? double(rawBytes) / double(encodedBytes) : 0.0; }
};
std::vector<std::byte> encodeSurfels(std::span<const Surfel> surfels, int positionBits = 16,
                                     SurfelCodecStats* stats = nullptr);

// Decodes Draco bytes. `what` names the source (file or cell) in errors. Throws lfgi::Error on truncated
// or corrupt data or a missing attribute; never returns partial data. At most 2^24 surfels (the encoder
// refuses more); the Draco stream's own point count is checked against the header before Draco allocates.
std::vector<Surfel> decodeSurfels(std::span<const std::byte> bytes, std::string_view what);

}  // namespace lfgi::worlds
