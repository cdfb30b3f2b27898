#version 450
// Probe irradiance for the next relight frame: E(n) = sum_texels L(w) max(0, n.w) dOmega(w) (exact
// cosine convolution, as irradiance_convolve.comp) over each probe's N x N VIR radiance map, where a
// texel that no surfel covered (coverage 0 after hole fill) sees the sky: skyRadiance without the discs
// (LFGI_RELIGHT_SKY; the discs reach surfels through the shadow map, never through the probes). With
// LFGI_RELIGHT_FILLED_SKY, texels that only the hole fill covered count as uncovered too: dilation cannot
// tell a gap between surfels from the sky, and grows every silhouette into the sky by fillPasses texels
// (measured on a city cell vs Embree: probe irradiance median error 17 % with filled texels as geometry,
// 1.7 % as sky).
// One invocation per output texel, probes along z; no barriers.
#include "shared/octahedral.h"
#include "shared/relight.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Frame { RelightFrame frame; };
layout(std430, set = 0, binding = 1) readonly buffer Radiance { vec4 radiance[]; };
layout(std430, set = 0, binding = 2) readonly buffer Normal { vec4 normals[]; };
layout(std430, set = 0, binding = 3) readonly buffer SolidAngles { float solidAngle[]; };
layout(std430, set = 0, binding = 4) writeonly buffer Irradiance { vec4 irradiance[]; };

layout(push_constant) uniform Push { RelightParams params; };

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint m = params.irradianceRes;
  uint n = params.distanceRes;
  if (id.x >= m || id.y >= m || id.z >= params.probeCount) return;
  vec3 normal = octTexelDirection(id.xy, m);
  bool sky = (params.flags & LFGI_RELIGHT_SKY) != 0u;
  bool filledSky = (params.flags & LFGI_RELIGHT_FILLED_SKY) != 0u;
  uint base = id.z * n * n;
  vec3 sum = vec3(0.0);
  for (uint y = 0; y < n; ++y) {
    for (uint x = 0; x < n; ++x) {
      uint t = y * n + x;
      vec3 w = octTexelDirection(uvec2(x, y), n);
      float c = dot(normal, w);
      if (c <= 0.0) continue;
      vec3 l = radiance[base + t].rgb;
      float coverage = normals[base + t].w;
      if (coverage == LFGI_VIR_HOLE || (filledSky && coverage != LFGI_VIR_COVERED))
        l = sky ? skyRadiance(frame.sky, w) : vec3(0.0);
      sum += l * (c * solidAngle[t]);
    }
  }
  irradiance[id.z * m * m + id.y * m + id.x] = vec4(sum, 0.0);
}
