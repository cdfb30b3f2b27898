// Relight pass (gpu/relight_pass.h): per-frame lighting of a cell's surfels, shared by GLSL and C++.
// RelightFrame is one storage buffer per frame (too big for push constants); RelightParams are the push
// constants of every relight_*.comp shader.
#ifndef LFGI_SHARED_RELIGHT_H
#define LFGI_SHARED_RELIGHT_H

#include "lfgi_shared.h"
#include "sky.h"
#include "vir.h"

LFGI_SHARED_BEGIN

// Shadow map frame: orthographic along the key light. A world point p has map coordinates
// u = dot(p, axisU.xyz) - axisU.w, v = dot(p, axisV.xyz) - axisV.w (metres from the map's corner) and
// depth = depth.x - dot(p, keyDirection.xyz) (metres from the map's plane on the light's side, > 0).
struct RelightFrame {
  SkyParams sky;       // the sky/sun/moon state (worlds::makeSky)
  vec4 keyDirection;   // xyz: unit direction towards the shadowed disc (sun, or moon at night); w: 0 none
  vec4 keyIrradiance;  // rgb: that disc's irradiance on a surface facing it (kilolux); w unused
  vec4 shadowAxisU;    // xyz: unit map axis (perpendicular to keyDirection); w: u of the map's corner (m)
  vec4 shadowAxisV;    // xyz: unit map axis; w: v of the map's corner (m)
  vec4 shadowDepth;    // x: depth origin (m); y: texel size (m); z: bias constant (m); w: bias slope (texels)
  vec4 gridOrigin;     // xyz: probe (0, 0, 0) of the grid (before relocation), core/probe_grid.h order
  vec4 gridSpacing;    // xyz: metres between probes; w: normal bias for the Chebyshev test (m)
  ivec4 gridDims;      // xyz: probes per axis; w: probe count
  uvec4 emitters;      // x: emitter samples, y: emitter clusters, z: cluster shadow map resolution; w: 0
  vec4 emitterBias;    // x: normal offset of the receiver (m); y: constant depth bias (m); z: depth bias
                       //    per metre of distance (slope x texel angle); w: unused
};
LFGI_CHECK_SIZE(RelightFrame, 416)
LFGI_CHECK_OFFSET(RelightFrame, keyDirection, 256)
LFGI_CHECK_OFFSET(RelightFrame, gridDims, 368)

#define LFGI_RELIGHT_SUN 1u        // add the key disc's irradiance, shadowed by the shadow map
#define LFGI_RELIGHT_BOUNCE 2u     // add last frame's probe irradiance (sky + bounces)
#define LFGI_RELIGHT_CHEBYSHEV 4u  // weight probes by Chebyshev visibility from their distance moments
#define LFGI_RELIGHT_SKY 8u        // probe convolution: texels no surfel covered see the sky (no disc)
#define LFGI_RELIGHT_FILLED_SKY \
  16u                              // probe convolution: texels only the hole fill covered count as uncovered
#define LFGI_RELIGHT_EMITTERS 32u  // add emitter next-event estimation (RelightEmitter samples)

// Whether a probe texel of coverage `coverage` (the VIR normal.w) sees the sky in the probe convolution and
// the distance moments: no surfel covered it, or, with LFGI_RELIGHT_FILLED_SKY in flags, only the hole fill.
LFGI_INLINE bool relightTexelSeesSky(float coverage, uint flags) {
  return coverage == LFGI_VIR_HOLE ||
         ((flags & LFGI_RELIGHT_FILLED_SKY) != 0u && coverage != LFGI_VIR_COVERED);
}

// One emitter sample for next-event estimation: a disc standing for `area` of emissive surface (the
// sampled surfel's own area scaled up when its cluster has more surfels than samples).
struct RelightEmitter {
  vec4 positionArea;   // xyz: disc centre (m); w: area it stands for (m^2)
  vec4 normalCluster;  // xyz: unit emitting normal; w: uintBitsToFloat(cluster index)
  vec4 radiance;       // rgb: emitted radiance; w: unused
};
LFGI_CHECK_SIZE(RelightEmitter, 48)

struct RelightParams {
  uint surfelCount;
  uint probeCount;
  uint shadowRes;           // shadow map texels per side
  uint maxFootprintRadius;  // shadow splat window half-size in texels
  uint irradianceRes;       // M: probe irradiance maps (octahedral, no border)
  uint distanceRes;         // N: probe radiance / distance maps (the VIR resolution)
  uint flags;               // LFGI_RELIGHT_* bits
  uint pad0;
  float footprintScale;  // shadow splat disc radius multiplier (as VirParams.footprintScale)
  float missDistance;    // distance moment of a texel that sees no surfel (the sky), m
  float pad1;
  float pad2;
};
LFGI_CHECK_SIZE(RelightParams, 48)
LFGI_CHECK_OFFSET(RelightParams, footprintScale, 32)

// Push constants of relight_prefilter_ggx.comp.
struct RelightPrefilterParams {
  uint radianceRes;  // N of the input radiance maps (vec4 per texel, rgb used)
  uint outRes;       // M of the prefiltered maps
  uint probeCount;
  float roughness;  // perceptual roughness in [0, 1]; GGX alpha = max(roughness^2, 1e-3)
};
LFGI_CHECK_SIZE(RelightPrefilterParams, 16)

LFGI_SHARED_END

#endif  // LFGI_SHARED_RELIGHT_H
