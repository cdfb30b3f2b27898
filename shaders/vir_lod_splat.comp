#version 450
// VIR LOD splat: every node of a probe block's cut (vir_lod_cut.comp) into every probe of the block,
// with the depth test of vir_splat.comp (64-bit atomicMin on depth bits << 32 | node index; the texels
// whose centre ray hits the footprint disc, exact depth along that ray; back-facing discs culled).
//
// Work decomposition: probe-major. Invocation (lane, probe-in-block, block) walks the block's cut with
// stride `lanes`; the lanes of one subgroup share one probe map (atomics stay in a few KiB) and read
// consecutive cut entries (spatially close nodes, so nearby texels). No shared memory, no barriers.
// `lanes` grows with the cut so no invocation loops much more than ~1000 times (llvmpipe ends an
// invocation's loops after 65535 iterations in total).
//
// Footprint: a leaf is a disc (radius x footprintScale, as vir_splat.comp), a merged node the rectangle of
// VirLodTree::rects (tight on the city's axis-aligned walls; its half diagonal is the node radius).
// Window: cut nodes are about one texel wide, so instead of vir_splat.comp's square window around the
// containing texel, only the texels whose centres lie within the disc's angular radius of its projected
// centre (in texel units x LFGI_VIR_OCT_STRETCH, the octahedral map's largest per-axis stretch) are tested: 1-4
// ray/disc tests per node instead of 9. Near leaves keep the window cap maxFootprintRadius.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "shared/octahedral.h"
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Nodes { Surfel nodes[]; };
layout(std430, set = 0, binding = 1) readonly buffer Probes { vec4 probes[]; };
layout(std430, set = 0, binding = 2) readonly buffer Cut { uint cut[]; };
layout(std430, set = 0, binding = 3) readonly buffer CutCount { uint cutCount[]; };
layout(std430, set = 0, binding = 4) buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 5) buffer Stats { uint64_t stats[]; };
layout(std430, set = 0, binding = 6) readonly buffer Rects { vec4 rects[]; };  // gpu/vir_lod.h VirLodTree::rects

layout(push_constant) uniform Push { VirLodParams params; };

// As vir_splat.comp: texel index t (|t - [0, n)| < n) -> the interior texel it denotes across the fold.
ivec2 octWrap(ivec2 t, int n) {
  if (t.x < 0) {
    t = ivec2(-1 - t.x, n - 1 - t.y);
  } else if (t.x >= n) {
    t = ivec2(2 * n - 1 - t.x, n - 1 - t.y);
  }
  if (t.y < 0) {
    t = ivec2(n - 1 - t.x, -1 - t.y);
  } else if (t.y >= n) {
    t = ivec2(n - 1 - t.x, 2 * n - 1 - t.y);
  }
  return clamp(t, ivec2(0), ivec2(n - 1));
}

void main() {
  uint lane = gl_GlobalInvocationID.x;
  uint y = gl_GlobalInvocationID.y;
  uint block = params.blockFirst + gl_GlobalInvocationID.z;
  uint p = block * params.blockProbes + y;
  if (lane >= params.lanes || y >= params.blockProbes || p >= params.probeCount) return;
  vec3 o = probes[p].xyz;
  int n = int(params.res);
  float halfN = float(n) * 0.5;
  int kmax = int(params.maxFootprintRadius);
  uint base = p * params.res * params.res;
  uint count = min(cutCount[gl_GlobalInvocationID.z], params.cutCapacity);
  uint cutBase = gl_GlobalInvocationID.z * params.cutCapacity;
  uint atomics = 0u, visited = 0u, tests = 0u, windowPairs = 0u;
  for (uint i = lane; i < count; i += params.lanes) {
    ++visited;
    uint s = cut[cutBase + i];
    vec4 pr = nodes[s].positionRadius;
    vec3 nrm = nodes[s].normal.xyz;
    vec3 toS = pr.xyz - o;
    float d = length(toS);
    if (d > params.maxRange || d < 1e-6) continue;
    float facing = -dot(nrm, toS);  // dot(n, probe - centre)
    if (facing <= 0.0) continue;
    ++windowPairs;
    float r = pr.w * params.footprintScale;
    vec2 tc = (octEncode(toS) * 0.5 + vec2(0.5)) * float(n);  // continuous texel coordinates
    float rho = asin(min(r / d, 1.0)) * halfN * LFGI_VIR_OCT_STRETCH;
    vec4 rect = rects[s];
    bool isRect = rect.z >= 0.0;
    vec3 t1 = isRect ? octDecode(rect.xy) : vec3(0.0);
    vec3 t2 = cross(nrm, t1);
    ivec2 c = ivec2(floor(tc));
    ivec2 lo = max(ivec2(ceil(tc - vec2(0.5 + rho))), c - ivec2(kmax));
    ivec2 hi = min(ivec2(floor(tc + vec2(rho - 0.5))), c + ivec2(kmax));
    uint64_t low = uint64_t(s);
    for (int ty = lo.y; ty <= hi.y; ++ty) {
      for (int tx = lo.x; tx <= hi.x; ++tx) {
        ivec2 t = octWrap(ivec2(tx, ty), n);
        ++tests;
        vec3 td = octTexelDirection(uvec2(t), params.res);
        float denom = -dot(nrm, td);
        if (denom <= 1e-6) continue;
        float depth = facing / denom;
        vec3 h = o + depth * td - pr.xyz;
        bool hit = isRect ? (abs(dot(h, t1)) <= rect.z && abs(dot(h, t2)) <= rect.w) : dot(h, h) <= r * r;
        if (hit) {
          atomicMin(slots[base + uint(t.y) * params.res + uint(t.x)], (uint64_t(floatBitsToUint(depth)) << 32) | low);
          ++atomics;
        }
      }
    }
  }
  if (visited > 0u) atomicAdd(stats[0], uint64_t(visited));
  if (atomics > 0u) atomicAdd(stats[1], uint64_t(atomics));
  if (tests > 0u) atomicAdd(stats[4], uint64_t(tests));
  if (windowPairs > 0u) atomicAdd(stats[5], uint64_t(windowPairs));
}
