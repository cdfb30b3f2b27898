#version 450
// VIR hole fill: one pass in octahedral space. A hole texel (normal.w == 0) enclosed by valid neighbours
// (wrapped across the fold with octBorderSource; valid: covered, or filled by an earlier pass,
// 0 < w <= pass + 1) on two opposite sides (left and right, above and below, or the two ends of a
// diagonal) takes the average of its valid neighbours and is marked w = pass + 2 (VirPass counts the
// holes left from the read-back coverage). The enclosure test fills the gaps between surfel discs
// (cracks, pinholes) but never grows a silhouette into the sky: a plain dilation (any valid neighbour) put
// geometry into 75 % of the sky texels of the city cell's probes at N = 8 and 48 % at N = 16 with 2 passes
// (lfgi_bench_vir sky_filled_fraction). Enclosure alone cannot tell a crack from a window or skylight a
// texel or two wide (it closed the skylight of lfgi_bench_stability's leak scene: the sunlit room's probes
// saw a third of Embree's light), so with VirOptions::fillNearMiss > 0 only a hole the splat marked as a
// near miss (slot LFGI_VIR_NEAR_MISS_SLOT: its ray passed close to a disc) is filled. Only holes are written and only texels not written by this pass
// are averaged, so one buffer serves as input and output (a neighbour filled concurrently reads as invalid
// either way).
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/octahedral.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) buffer Distance { vec2 distanceMoments[]; };
layout(std430, set = 0, binding = 1) buffer Normal { vec4 normals[]; };
layout(std430, set = 0, binding = 2) buffer Albedo { vec4 albedos[]; };
layout(std430, set = 0, binding = 3) buffer Radiance { vec4 radiances[]; };
layout(std430, set = 0, binding = 4) readonly buffer Slots { uint64_t slots[]; };  // the splat's winners

layout(push_constant) uniform Push { VirParams params; };

// Texel j holds a value this pass may average: covered, or filled by an earlier pass (0 < w <= limit).
bool valid(uint j, float limit) {
  float w = normals[j].w;
  return w > 0.0 && w <= limit;
}

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint n = params.res;
  if (id.x >= n || id.y >= n || id.z >= params.probeCount) return;
  uint base = id.z * n * n;
  uint i = base + id.y * n + id.x;
  if (normals[i].w != LFGI_VIR_HOLE) return;
  if (params.fillNearMiss > 0.0 && slots[i] != LFGI_VIR_NEAR_MISS_SLOT) return;
  float limit = float(params.fillPass) + 1.0;
  // Coverage of the neighbours first (one word each): most holes of an outdoor probe are sky, not enclosed,
  // and skip the channel reads. Neighbour k's opposite is 7 - k: one end of each pair is read, the other
  // only when that end is valid, so a hole among holes reads 4 words, not 8.
  uint src[8];
  uint ok = 0u;  // bit k: neighbour k valid
  for (int k = 0; k < 8; ++k) {
    int d = k < 4 ? k : k + 1;  // the 3 x 3 neighbourhood without its centre
    uvec2 t = octBorderSource(uvec2(ivec2(id.xy) + ivec2(d % 3, d / 3)), n);
    src[k] = base + t.y * n + t.x;
  }
  for (int k = 0; k < 4; ++k)
    if (valid(src[k], limit)) ok |= 1u << k;
  for (int k = 0; k < 4; ++k)
    if ((ok & (1u << k)) != 0u && valid(src[7 - k], limit)) ok |= 1u << (7 - k);
  // Enclosed when some pair is valid at both ends; then the far ends of the other pairs count too.
  if ((ok & (bitfieldReverse(ok) >> 24u) & 0x0Fu) == 0u) return;
  for (int k = 0; k < 4; ++k)
    if ((ok & (1u << k)) == 0u && valid(src[7 - k], limit)) ok |= 1u << (7 - k);
  vec2 dist = vec2(0.0);
  vec3 nrm = vec3(0.0);
  vec4 alb = vec4(0.0);
  vec4 rad = vec4(0.0);
  float count = 0.0;
  for (int k = 0; k < 8; ++k) {
    if ((ok & (1u << k)) == 0u) continue;
    uint j = src[k];
    dist += distanceMoments[j];
    nrm += normals[j].xyz;
    alb += albedos[j];
    rad += radiances[j];
    count += 1.0;
  }
  float w = 1.0 / count;
  distanceMoments[i] = dist * w;
  float len = length(nrm);
  normals[i] = vec4(len > 0.0 ? nrm / len : vec3(0.0), limit + 1.0);
  albedos[i] = alb * w;
  radiances[i] = rad * w;
}
