#version 450
// Cubemap baseline, resample: per octahedral texel (shared/octahedral.h convention), the face texel
// that contains the texel-centre direction d (nearest, no filtering: VIR's maps are point samples too).
// Distance: the face texel stores r_f along its own centre ray; on the same plane (normal n) the hit
// along d is at r = r_f dot(n, d_f) / dot(n, d), exact for the flat-shaded mesh wherever both rays hit
// the same triangle plane; kept within [r_f / 2, 2 r_f] so a silhouette texel falls back to r_f.
// Moments (r, r^2) of that one sample; radiance = emission (no lighting: unlit geometry capture).
// Texels whose face texel saw no triangle (sky) are zeroed and counted in counters[0].
#include "shared/cubemap_raster.h"
#include "shared/octahedral.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer NormalDistance { vec4 normalDistance[]; };
layout(std430, set = 0, binding = 1) readonly buffer AlbedoHalf { uvec2 albedoHalf[]; };
layout(std430, set = 0, binding = 2) readonly buffer EmissionHalf { uvec2 emissionHalf[]; };
layout(std430, set = 0, binding = 3) writeonly buffer Distance { vec2 distanceMoments[]; };
layout(std430, set = 0, binding = 4) writeonly buffer Normal { vec4 normals[]; };
layout(std430, set = 0, binding = 5) writeonly buffer Albedo { vec4 albedos[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Radiance { vec4 radiances[]; };
layout(std430, set = 0, binding = 7) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push { CubemapResampleParams params; };

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint n = params.res;
  if (id.x >= n || id.y >= n || id.z >= params.probeCount) return;
  uint out_i = (id.z + params.probeOffset) * n * n + id.y * n + id.x;
  vec3 d = octTexelDirection(id.xy, n);
  uint f = cubeFaceOf(d);
  uint F = params.faceRes;
  uvec2 t = cubeFaceTexel(d, f, F);
  uint tile = id.z * 6u + f;
  uint ax = (tile % params.tilesX) * F + t.x;
  uint ay = (tile / params.tilesX) * F + t.y;
  uint a = ay * params.atlasWidth + ax;

  uvec2 alb = albedoHalf[a];
  vec2 albB = unpackHalf2x16(alb.y);
  if (albB.y == 0.0) {
    distanceMoments[out_i] = vec2(0.0);
    normals[out_i] = vec4(0.0, 0.0, 0.0, LFGI_VIR_HOLE);
    albedos[out_i] = vec4(0.0);
    radiances[out_i] = vec4(0.0);
    atomicAdd(counters[0], 1u);
    return;
  }
  vec4 nd = normalDistance[a];
  vec3 nrm = nd.xyz;
  float rf = nd.w;
  float r = rf;
  float denom = dot(nrm, d);
  if (abs(denom) > 1e-4) {
    float rr = rf * dot(nrm, cubeFaceTexelDirection(t, f, F)) / denom;
    if (rr > 0.5 * rf && rr < 2.0 * rf) r = rr;
  }
  uvec2 em = emissionHalf[a];
  distanceMoments[out_i] = vec2(r, r * r);
  normals[out_i] = vec4(nrm, LFGI_VIR_COVERED);
  albedos[out_i] = vec4(unpackHalf2x16(alb.x), albB.x, 1.0);
  radiances[out_i] = vec4(unpackHalf2x16(em.x), unpackHalf2x16(em.y).x, 1.0);
}
