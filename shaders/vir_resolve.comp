#version 450
// VIR resolve: per texel, unpack the nearest surfel of the splat and write the probe channels:
// distance moments (r, r^2) with r the stored texel-ray depth, normal (w = coverage, see shared/vir.h),
// albedo, and radiance = emission + albedo * E / pi (Lambertian; E = the surfel's irradiance input).
// Texels no surfel reached are left as VirPass cleared them (all 0: LFGI_VIR_HOLE).
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 1) readonly buffer Surfels { Surfel surfels[]; };
layout(std430, set = 0, binding = 2) readonly buffer Irradiance { vec4 irradiance[]; };
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
  vec3 a = surfels[s].albedo.rgb;
  distanceMoments[i] = vec2(r, r * r);
  normals[i] = vec4(surfels[s].normal.xyz, LFGI_VIR_COVERED);
  albedos[i] = vec4(a, 1.0);
  radiances[i] = vec4(surfels[s].emission.rgb + a * irradiance[s].rgb * 0.31830988618, 1.0);
}
