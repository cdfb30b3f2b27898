#version 450
// Relight shadow map: the same VIR splat (Marrs, Watson & Healey 2017) as vir_splat.comp, but into one
// orthographic depth map looking down the key light (sun, or moon at night). One invocation per surfel,
// no barriers. Footprint: the texels whose centre ray (parallel to the light) hits the surfel's disc,
// radius scaled by footprintScale so the discs of a surface overlap and leave no gaps; the window is
// ceil(scaled radius / texel) texels each way, capped at maxFootprintRadius. Stored value per texel:
// (depth bits << 32 | surfel index), 64-bit atomicMin keeps the disc nearest the light. Both faces of a
// disc occlude (the back of a wall casts the shadow as well as its front); discs edge-on to the light
// (|n.L| < 1e-3) cover no texel centre in a meaningful way and are skipped.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "shared/relight.h"
#include "shared/surfel.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Surfels { Surfel surfels[]; };
layout(std430, set = 0, binding = 1) readonly buffer Frame { RelightFrame frame; };
layout(std430, set = 0, binding = 2) buffer Slots { uint64_t slots[]; };

layout(push_constant) uniform Push { RelightParams params; };

void main() {
  uint s = gl_GlobalInvocationID.x;
  if (s >= params.surfelCount) return;
  vec4 pr = surfels[s].positionRadius;
  vec3 nrm = surfels[s].normal.xyz;
  vec3 L = frame.keyDirection.xyz;
  vec3 U = frame.shadowAxisU.xyz;
  vec3 V = frame.shadowAxisV.xyz;
  float nl = dot(nrm, L);
  if (abs(nl) < 1e-3) return;
  float ts = frame.shadowDepth.y;
  float r = pr.w * params.footprintScale;
  int res = int(params.shadowRes);
  float cu = dot(pr.xyz, U) - frame.shadowAxisU.w;
  float cv = dot(pr.xyz, V) - frame.shadowAxisV.w;
  float ch = dot(pr.xyz, L);
  ivec2 c = ivec2(floor(cu / ts), floor(cv / ts));
  int k = min(int(params.maxFootprintRadius), int(ceil(r / ts)));
  // Ray of texel centre (u, v): p = u' U + v' V + h L (u' = u + corner); on the disc plane
  // h = ch - (n.U du + n.V dv) / n.L with (du, dv) the offset from the disc centre in the map plane.
  float nu = dot(nrm, U) / nl;
  float nv = dot(nrm, V) / nl;
  for (int dy = -k; dy <= k; ++dy) {
    int ty = c.y + dy;
    if (ty < 0 || ty >= res) continue;
    for (int dx = -k; dx <= k; ++dx) {
      int tx = c.x + dx;
      if (tx < 0 || tx >= res) continue;
      float du = (float(tx) + 0.5) * ts - cu;
      float dv = (float(ty) + 0.5) * ts - cv;
      float dh = -(nu * du + nv * dv);
      if (du * du + dv * dv + dh * dh > r * r) continue;
      float depth = max(frame.shadowDepth.x - (ch + dh), 0.0);
      uint slot = uint(ty) * params.shadowRes + uint(tx);
      atomicMin(slots[slot], (uint64_t(floatBitsToUint(depth)) << 32) | uint64_t(s));
    }
  }
}
