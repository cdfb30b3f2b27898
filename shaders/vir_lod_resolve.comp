#version 450
// VIR LOD resolve: as vir_resolve.comp, but the slot names a node of the surfel LOD tree and its radiance
// comes from vir_lod_radiance.comp (a leaf's equals vir_resolve.comp's emission + albedo E / pi), or,
// when the run has no irradiance (VirParams::emissionOnly), is the node's area-weighted emission.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 1) readonly buffer Nodes { Surfel nodes[]; };
layout(std430, set = 0, binding = 2) readonly buffer NodeRadiance { vec4 nodeRadiance[]; };
layout(std430, set = 0, binding = 3) writeonly buffer Distance { vec2 distanceMoments[]; };
layout(std430, set = 0, binding = 4) writeonly buffer Normal { vec4 normals[]; };
layout(std430, set = 0, binding = 5) writeonly buffer Albedo { vec4 albedos[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Radiance { vec4 radiances[]; };

layout(push_constant) uniform Push { VirParams params; };

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint n = params.res;
  if (id.x >= n || id.y >= n || id.z >= params.probeCount) return;
  uint i = id.z * n * n + id.y * n + id.x;
  uint64_t v = slots[i];
  if (v >= LFGI_VIR_NEAR_MISS_SLOT) return;  // a hole: VirPass cleared the channels to 0 (LFGI_VIR_HOLE)
  uint s = uint(v & 0xFFFFFFFFUL);
  float r = uintBitsToFloat(uint(v >> 32));
  distanceMoments[i] = vec2(r, r * r);
  normals[i] = vec4(nodes[s].normal.xyz, LFGI_VIR_COVERED);
  albedos[i] = vec4(nodes[s].albedo.rgb, 1.0);
  radiances[i] = vec4(params.emissionOnly != 0u ? nodes[s].emission.rgb : nodeRadiance[s].rgb, 1.0);
}
