#version 450
// VIR splat (Marrs, Watson & Healey 2017): every surfel into every probe within range, keeping the
// nearest per texel with a 64-bit atomicMin on (depth bits << 32 | surfel index).
//
// Work decomposition: one invocation per (surfel, probe) pair, surfels along x, probes along y. No shared
// memory, no barriers, no binning: on lavapipe (CPU) barriers and shared memory are the expensive part
// and the per-pair work (a <= (2k+1)^2 texel window) is small and uniform, so the flat pair grid is the
// fastest barrier-free layout; on a GPU adjacent invocations read adjacent surfels (coalesced) and hit
// the same probe map (cache-friendly atomics).
//
// Footprint: the texels whose centre ray hits the surfel disc (radius scaled by footprintScale, 1.3 by
// default, so the discs of a surface overlap and leave no gaps between texel-centre rays: the lattice of
// worlds::sampleSurfels needs >= 1.1, a square grid 1.25; more overhangs edges: at 1.5 the Cornell box's
// small lamp looked 13 % brighter), found in a
// window of half-size k = min(maxFootprintRadius, ceil(atan(r/d) N/2)) texels around the texel that
// contains the surfel direction (indices wrapped across the octahedral fold). The stored depth is the
// exact distance along the texel-centre ray to the disc plane. A disc that no texel-centre ray hits
// writes nothing (no point splat: writing the containing texel anyway put surfaces in front of their
// silhouettes and over the sky; measured in bake/vir_accuracy_test.cpp).
// Back-facing surfels (normal away from the probe) are culled. A ray that misses the disc but passes within
// the near-miss radius marks an empty slot LFGI_VIR_NEAR_MISS_SLOT (shared/vir.h): the hole fill closes
// only such holes.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "shared/octahedral.h"
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Surfels { Surfel surfels[]; };
layout(std430, set = 0, binding = 1) readonly buffer Probes { vec4 probes[]; };
layout(std430, set = 0, binding = 2) buffer Slots { uint64_t slots[]; };

layout(push_constant) uniform Push { VirParams params; };

void main() {
  uint s = gl_GlobalInvocationID.x;
  uint p = gl_GlobalInvocationID.y;
  if (s >= params.surfelCount || p >= params.probeCount) return;
  vec4 pr = surfels[s].positionRadius;
  vec3 nrm = surfels[s].normal.xyz;
  vec3 o = probes[p].xyz;
  vec3 toS = pr.xyz - o;
  float d = length(toS);
  if (d > params.maxRange || d < 1e-6) return;
  float facing = -dot(nrm, toS);  // dot(n, probe - surfel)
  if (facing <= 0.0) return;

  vec3 dir = toS / d;
  float r = pr.w * params.footprintScale;
  float nearR = r * virNearMissRatio(params.fillNearMiss, params.footprintScale);
  int n = int(params.res);
  int k = min(int(params.maxFootprintRadius), int(ceil(atan(nearR, d) * float(n) * 0.5)));
  ivec2 c = ivec2(octDirectionTexel(dir, params.res));
  uint base = p * params.res * params.res;
  uint64_t low = uint64_t(s);
  for (int dy = -k; dy <= k; ++dy) {
    for (int dx = -k; dx <= k; ++dx) {
      ivec2 t = octWrap(c + ivec2(dx, dy), n);
      vec3 td = octTexelDirection(uvec2(t), params.res);
      float denom = -dot(nrm, td);
      if (denom <= 1e-6) continue;  // texel ray parallel to or away from the disc plane
      float depth = facing / denom;  // o + depth td lies on the disc plane
      vec3 h = o + depth * td - pr.xyz;
      float h2 = dot(h, h);
      uint slot = base + uint(t.y) * params.res + uint(t.x);
      if (h2 <= r * r)
        atomicMin(slots[slot], (uint64_t(floatBitsToUint(depth)) << 32) | low);
      else if (h2 <= nearR * nearR)
        atomicMin(slots[slot], LFGI_VIR_NEAR_MISS_SLOT);
    }
  }
}
