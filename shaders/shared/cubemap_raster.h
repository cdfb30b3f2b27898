// Cubemap rasterization baseline (gpu/cubemap_raster.h): the cube-face frames used by the raster shaders
// and the octahedral resample, the per-triangle attributes and the push constants, shared by GLSL and C++.
//
// Face f (0..5) looks along +X, -X, +Y, -Y, +Z, -Z. A point at offset v from the probe lands on face f
// at face coordinates (dot(v, right) / dot(v, forward), dot(v, up) / dot(v, forward)) in [-1, 1]^2;
// texel (x, y) of an F x F face covers [x, x+1) x [y, y+1) of ((c + 1) / 2) F. The raster's clip space
// is (right, up, near, forward) so the rasterizer and the resample agree without any viewport flip.
#ifndef LFGI_SHARED_CUBEMAP_RASTER_H
#define LFGI_SHARED_CUBEMAP_RASTER_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

LFGI_INLINE vec3 cubeFaceForward(uint f) {
  float s = (f % 2u) == 0u ? 1.0f : -1.0f;
  uint axis = f / 2u;
  return vec3(axis == 0u ? s : 0.0f, axis == 1u ? s : 0.0f, axis == 2u ? s : 0.0f);
}

LFGI_INLINE vec3 cubeFaceRight(uint f) {
  uint axis = (f / 2u + 1u) % 3u;
  return vec3(axis == 0u ? 1.0f : 0.0f, axis == 1u ? 1.0f : 0.0f, axis == 2u ? 1.0f : 0.0f);
}

LFGI_INLINE vec3 cubeFaceUp(uint f) {
  uint axis = (f / 2u + 2u) % 3u;
  return vec3(axis == 0u ? 1.0f : 0.0f, axis == 1u ? 1.0f : 0.0f, axis == 2u ? 1.0f : 0.0f);
}

// The face whose frustum contains direction d (largest |component|; ties go to the lower axis).
LFGI_INLINE uint cubeFaceOf(vec3 d) {
  vec3 a = abs(d);
  if (a.x >= a.y && a.x >= a.z) return d.x >= 0.0f ? 0u : 1u;
  if (a.y >= a.z) return d.y >= 0.0f ? 2u : 3u;
  return d.z >= 0.0f ? 4u : 5u;
}

// Texel of an F x F face containing direction d (d inside face f's frustum).
LFGI_INLINE uvec2 cubeFaceTexel(vec3 d, uint f, uint faceRes) {
  float z = dot(d, cubeFaceForward(f));
  vec2 c = vec2(dot(d, cubeFaceRight(f)), dot(d, cubeFaceUp(f))) * (1.0f / z);
  vec2 t = (c * 0.5f + vec2(0.5f)) * float(faceRes);
  ivec2 i = clamp(ivec2(int(floor(t.x)), int(floor(t.y))), ivec2(0), ivec2(int(faceRes) - 1));
  return uvec2(uint(i.x), uint(i.y));
}

// Unit direction through the centre of texel t of face f.
LFGI_INLINE vec3 cubeFaceTexelDirection(uvec2 t, uint f, uint faceRes) {
  vec2 c = (vec2(float(t.x), float(t.y)) + vec2(0.5f)) * (2.0f / float(faceRes)) - vec2(1.0f);
  return normalize(cubeFaceForward(f) + c.x * cubeFaceRight(f) + c.y * cubeFaceUp(f));
}

// Per-triangle attributes (flat shading: the mesh has face normals and per-triangle materials).
struct CubemapTriangle {
  vec4 normal;    // xyz: unit geometric normal (front side); w: 0
  vec4 albedo;    // rgb: linear albedo; a: 1
  vec4 emission;  // rgb: emitted radiance (clamped to the FP16 range by the raster); a: 0
};
LFGI_CHECK_SIZE(CubemapTriangle, 48)

// Push constants of cubemap_raster_face.vert / cubemap_raster_gbuffer.frag: one draw = one probe's face.
struct CubemapRasterParams {
  vec4 probe;  // xyz: probe position (m); w: near plane distance (m)
  uint face;   // 0..5, see cubeFaceForward
  uint pad0, pad1, pad2;
};
LFGI_CHECK_SIZE(CubemapRasterParams, 32)
LFGI_CHECK_OFFSET(CubemapRasterParams, face, 16)

// Push constants of cubemap_raster_resample.comp: one batch of probes, face tiles in a row-major atlas.
struct CubemapResampleParams {
  uint res;          // N: octahedral texels per side
  uint faceRes;      // F: face texels per side
  uint probeCount;   // probes in this batch
  uint probeOffset;  // index of the batch's first probe in the output maps
  uint tilesX;       // face tiles per atlas row; tile of (probe p, face f) = p * 6 + f
  uint atlasWidth;   // texels per atlas row (tilesX * F)
  uint pad0, pad1;
};
LFGI_CHECK_SIZE(CubemapResampleParams, 32)

LFGI_SHARED_END

#endif  // LFGI_SHARED_CUBEMAP_RASTER_H
