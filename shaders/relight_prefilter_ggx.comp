#version 450
// GGX-prefiltered radiance for specular lookups (split sum, Karis 2013, N = V = R), the GPU version of
// bake::prefilterRadianceGgx (bake/probe_capture.h): output texel with centre direction R holds
//   sum_w L(w) K(R, w) Omega_w / sum_w K(R, w) Omega_w,  K = D_GGX(R.h) max(0, R.w), h = normalize(R + w)
// over the N x N interior map, exact texel solid angles. D's denominator (R.h)^2 (a^2 - 1) + 1 is computed
// as |R x h|^2 + (R.h)^2 a^2, which keeps its precision in float for a mirror-like alpha (1e-3).
// One invocation per output texel, probes along z, no barriers; O(M^2 N^2) per probe.
#include "shared/octahedral.h"
#include "shared/relight.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Radiance { vec4 radiance[]; };
layout(std430, set = 0, binding = 1) readonly buffer SolidAngles { float solidAngle[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Prefiltered { vec4 prefiltered[]; };

layout(push_constant) uniform Push { RelightPrefilterParams params; };

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint m = params.outRes;
  uint n = params.radianceRes;
  if (id.x >= m || id.y >= m || id.z >= params.probeCount) return;
  vec3 r = octTexelDirection(id.xy, m);
  float a = max(params.roughness * params.roughness, 1e-3);
  float a2 = a * a;
  uint base = id.z * n * n;
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  for (uint y = 0; y < n; ++y) {
    for (uint x = 0; x < n; ++x) {
      uint t = y * n + x;
      vec3 w = octTexelDirection(uvec2(x, y), n);
      float rw = dot(r, w);
      if (rw <= 0.0) continue;
      vec3 h = normalize(r + w);
      float nh = dot(r, h);
      vec3 c = cross(r, h);
      float d = dot(c, c) + nh * nh * a2;
      // a2 / (pi d^2) with the constant a2 / pi dropped: it cancels in the normalisation.
      float k = rw * solidAngle[t] / (d * d);
      sum += radiance[base + t].rgb * k;
      wsum += k;
    }
  }
  prefiltered[id.z * m * m + id.y * m + id.x] = vec4(wsum > 0.0 ? sum / wsum : vec3(0.0), 0.0);
}
