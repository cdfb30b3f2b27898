#version 450
// Probe distance moments for Chebyshev visibility (McGuire et al. 2017): the VIR map's (r, r^2) averaged
// over the 3 x 3 texel neighbourhood (octahedral fold respected), so depth edges get the variance that
// makes the Chebyshev bound soft instead of a binary depth test. A texel no surfel covered sees the sky
// and stores (missDistance, missDistance^2); so does a texel only the VIR hole fill covered when
// LFGI_RELIGHT_FILLED_SKY is set, as in relight_probe_irradiance.comp. Sky texels never enter a geometry
// texel's average: at (miss, miss^2) one of nine gives a mean of miss / 9 and sigma ~ miss / 3, and the
// probes above a roof then saw every surfel under it (lfgi_bench_stability leak). Sky counted as
// geometry would hide the surfels below a probe from it in the Chebyshev test and lose their gathered
// bounce light (streaming/vir_relight_source_test.cpp, plane under an overcast sky).
// One invocation per texel, probes along z; no barriers.
#include "shared/octahedral.h"
#include "shared/relight.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Distance { vec2 distanceMoments[]; };
layout(std430, set = 0, binding = 1) readonly buffer Normal { vec4 normals[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Moments { vec2 moments[]; };

layout(push_constant) uniform Push { RelightParams params; };

void main() {
  uvec3 id = gl_GlobalInvocationID;
  int n = int(params.distanceRes);
  if (id.x >= uint(n) || id.y >= uint(n) || id.z >= params.probeCount) return;
  uint base = id.z * uint(n * n);
  float miss = params.missDistance;
  if (relightTexelSeesSky(normals[base + id.y * uint(n) + id.x].w, params.flags)) {
    moments[base + id.y * uint(n) + id.x] = vec2(miss, miss * miss);
    return;
  }
  vec2 sum = vec2(0.0);
  float count = 0.0;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      ivec2 t = octWrap(ivec2(id.xy) + ivec2(dx, dy), n);
      uint i = base + uint(t.y * n + t.x);
      if (relightTexelSeesSky(normals[i].w, params.flags)) continue;
      sum += distanceMoments[i];
      count += 1.0;
    }
  }
  moments[base + id.y * uint(n) + id.x] = sum / count;
}
