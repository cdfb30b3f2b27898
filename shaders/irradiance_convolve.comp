#version 450
// Brute-force irradiance E(n) = sum_texels L(w) max(0, n.w) dOmega(w) for every texel centre n of an
// M x M octahedral irradiance map, from an N x N octahedral radiance map with exact texel solid angles.
// One invocation per output texel; probes along z. O(M^2 N^2) per probe: the reference, not the fast path.
#include "shared/octahedral.h"
#include "shared/irradiance.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Radiance { vec4 radiance[]; };
layout(std430, set = 0, binding = 1) readonly buffer SolidAngles { float solidAngle[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Irradiance { vec4 irradiance[]; };

layout(push_constant) uniform Push { IrradianceParams params; };

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint m = params.irradianceRes;
  uint n = params.radianceRes;
  if (id.x >= m || id.y >= m || id.z >= params.probeCount) return;
  vec3 normal = octTexelDirection(id.xy, m);
  uint base = id.z * n * n;
  vec3 sum = vec3(0.0);
  for (uint y = 0; y < n; ++y) {
    for (uint x = 0; x < n; ++x) {
      uint t = y * n + x;
      float c = max(0.0, dot(normal, octTexelDirection(uvec2(x, y), n)));
      sum += radiance[base + t].rgb * (c * solidAngle[t]);
    }
  }
  irradiance[id.z * m * m + id.y * m + id.x] = vec4(sum, 0.0);
}
