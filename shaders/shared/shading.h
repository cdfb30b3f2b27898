// Structs of the G-buffer ray cast (gbuffer_raycast.comp) and the probe shading pass (probe_shade.comp),
// shared by GLSL and C++. All std430 with vec4-aligned members.
#ifndef LFGI_SHARED_SHADING_H
#define LFGI_SHARED_SHADING_H

#include "lfgi_shared.h"
#include "sky.h"

LFGI_SHARED_BEGIN

// One node of the flattened GPU BVH (depth-first order: an inner node's left child is the next node).
struct GpuBvhNode {
  vec4 lo;  // xyz: box min; w: uintBitsToFloat(inner: index of the right child; leaf: first triangle)
  vec4 hi;  // xyz: box max; w: uintBitsToFloat(triangle count; 0 for an inner node)
};
LFGI_CHECK_SIZE(GpuBvhNode, 32)

// One triangle in BVH leaf order (Moller-Trumbore form).
struct GpuTriangle {
  vec4 v0;  // xyz: vertex 0; w: uintBitsToFloat(material index)
  vec4 e1;  // xyz: v1 - v0; w: uintBitsToFloat(original triangle index)
  vec4 e2;  // xyz: v2 - v0
};
LFGI_CHECK_SIZE(GpuTriangle, 48)

struct GpuMaterial {
  vec4 albedo;    // rgb: linear albedo (texture mean folded in by the CPU side); w: roughness
  vec4 emission;  // rgb: emitted radiance (sky unit); w: metallic
  vec4 flags;     // x: 1 if double-sided
  vec4 pad;
};
LFGI_CHECK_SIZE(GpuMaterial, 64)

// Pinhole camera exactly as bake/reference_render.h (up = +Y, verticalFovDeg over the height).
struct GpuCamera {
  vec4 position;  // xyz; w: tan(fov / 2)
  vec4 forward;   // xyz unit; w: width / height
  vec4 right;     // xyz unit
  vec4 up;        // xyz unit
};
LFGI_CHECK_SIZE(GpuCamera, 64)

// G-buffer layout: four vec4 per pixel, one array each (pixel y * width + x, y = 0 the top row).
//   positionDepth: xyz world position of the first hit; w: hit distance (< 0: the ray escaped)
//   normalRoughness: xyz unit normal facing the viewer (back faces of single-sided materials: as hit, see
//                    flags.y); w: roughness
//   albedoMetallic: rgb albedo; w: metallic
//   emissionFlags: rgb emission; w: 1 = hit a back face of a single-sided material (inside solid: black)
struct GBufferParams {
  GpuCamera camera;
  uvec4 size;  // x: width, y: height, z: BVH node count, w: triangle count
  vec4 ray;    // x: maximum distance
  vec4 pad0;
  vec4 pad1;
};
LFGI_CHECK_SIZE(GBufferParams, 128)

// One cell of the shading pass, in one of two states (the streaming manager's,
// streaming/streaming_manager.h):
//   full: its probe grid; probe k of the cell is global probe firstProbe + k, whose maps start at
//     (firstProbe + k) * texels of the map kind (bordered octahedral maps, see ShadeParams); its fade in
//     [0, 1] weighs the probes against the fallback (1: fully faded in);
//   fallback-only (spacing.w = 1): a cell that is not resident; only its box (origin, spacing, dims: its
//     probe grid, whose probes are not uploaded) and its SH L1 fallback.
// Every cell carries its fallback as irradiance E(n) = fallback[0] + fallback[1] n.x + fallback[2] n.y +
// fallback[3] n.z (rgb: shIrradiance of the SH L1 radiance, linear in n). The fallback at a point is
// bilinear between the fallbacks of the 4 cell centres around it in xz, as StreamingManager::sample():
// fallbackCells[(dz + 1) * 3 + dx + 1] (flattened over the 3 ivec4) is the cell whose fallback stands at
// this cell's centre + (dx, dz) x box size; a missing neighbour is clamped per axis like the world edge
// there (entry 4 is the cell itself).
struct ShadeCell {
  vec4 origin;   // xyz: ProbeGrid::origin; w: fade (0 for a fallback-only cell)
  vec4 spacing;  // xyz: ProbeGrid::spacing; w: 1 fallback-only, 0 full
  ivec4 dims;    // xyz: ProbeGrid::dims; w: firstProbe (full cells; -1 fallback-only)
  ivec4 fallbackCells[3];
  vec4 fallback[4];
};
LFGI_CHECK_SIZE(ShadeCell, 160)
LFGI_CHECK_OFFSET(ShadeCell, fallbackCells, 48)
LFGI_CHECK_OFFSET(ShadeCell, fallback, 96)

struct ShadeParams {
  SkyParams sky;
  GpuCamera camera;
  uvec4 size;    // x: width, y: height, z: cell count, w: BVH node count
  uvec4 maps;    // x: irradiance res m, y: distance/radiance res n, z: specular levels L (>= 1), w: flags
                 //    (bit 0: Chebyshev visibility, bit 1: backface weight, bit 2: sun shadow rays)
  vec4 bias;     // x: normal bias (m), y: view bias (m), z: Chebyshev floor, w: max ray distance
  vec4 weights;  // x: 1 to shade direct light; y: 1 indirect diffuse; z: 1 indirect specular; w: AO radius
                 // (m, 0 off)
};
LFGI_CHECK_SIZE(ShadeParams, 256 + 64 + 64)

// Ambient-occlusion rays per pixel (probe_shade.comp).
#define LFGI_SHADE_AO_RAYS 16u

LFGI_INLINE uint shadeBorderedRes(uint n) {
  return n + 2u;
}

LFGI_SHARED_END

#endif  // LFGI_SHARED_SHADING_H
