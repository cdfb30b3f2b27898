// The body of vir_lod_splat.comp and vir_lod_splat_far.comp (the far pass of occlusion culling, with
// LFGI_VIR_LOD_SPLAT_FAR defined: the per-pair HiZ test and its Hiz binding 7). Two programs rather than a
// branch on VirLodParams::cutPass: llvmpipe runs both sides of every branch under an execution mask (it
// jumps only out of loops, gallivm/lp_bld_nir_soa.c), so an untaken test still costs its instructions for
// every (node, probe) pair: 5-10 % of the splat without occlusion culling.
// VIR LOD splat: every node of a probe block's cut (vir_lod_cut.comp) into every probe of the block,
// with the depth test of vir_splat.comp (64-bit atomicMin on depth bits << 32 | node index; the texels
// whose centre ray hits the footprint, exact depth along that ray; back-facing footprints culled).
//
// Work decomposition: node-major within a probe block. Invocation (lane, block) walks the block's cut with
// stride `lanes` and splats each node it reads into every probe of the block in turn: a node's fields
// (position, normal, rectangle: 12 words) are read once per block, not once per (node, probe) pair, and
// the probe's position is the same for every lane (a uniform load). On llvmpipe, where every buffer word
// an invocation reads costs ~10 ns, this made the splat ~1.4x faster at N = 8 than one invocation per
// (lane, probe). Consecutive lanes read consecutive cut entries (spatially close nodes). No
// shared memory, no barriers. `lanes` grows with the cut so no invocation splats more than ~512 (node,
// probe) pairs (llvmpipe ends an invocation's loops after 65535 iterations in total).
//
// Footprint: a leaf is a disc (radius x footprintScale, as vir_splat.comp), a merged node the rectangle of
// VirLodTree::rects (tight on the city's axis-aligned walls; its half diagonal is the node radius).
// Texels tested: first the square window of half-size angular radius x LFGI_VIR_OCT_STRETCH (the map's
// largest per-axis stretch) around the centre's image rejects a pair whose window holds no texel centre
// (most sub-texel nodes). Within one octant (fixed signs of the probe-relative coordinates) the octahedral
// map is a gnomonic projection onto an octahedron face followed by an affine map, so straight edges stay
// straight: a rectangle (a leaf disc's bounding square in the frame of shared/vir.h virRectAxis) whose
// corners lie in one octant maps to the quad of its corner images, and each texel row tests only that
// quad's span (widened by kEdgeEps texels against rounding) instead of the window (~28 tests per hit at
// N = 64 before). A footprint across an octant plane (3-18 % of pairs in the city cell) tests the window,
// its indices wrapped across the fold (shared/octahedral.h octWrap). Unlike vir_splat.comp's window, neither
// caps a footprint at maxFootprintRadius texels: the spans cost only the texels they cover, and a capped
// near disc (a pavement 0.4 m below a probe spans most of a hemisphere) let its texels fall through to
// the surface behind it (at N = 64, 2 % holes and 10 % of texels > 5 % too far before).
// Near misses (shared/vir.h LFGI_VIR_NEAR_MISS_SLOT): the spans and the window cover the footprint grown to
// its near-miss zone; a ray inside the zone but off the footprint marks an empty slot.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "shared/octahedral.h"
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Nodes { Surfel nodes[]; };
layout(std430, set = 0, binding = 1) readonly buffer Probes { vec4 probes[]; };  // block order; w: map index
layout(std430, set = 0, binding = 2) readonly buffer Cut { uint cut[]; };
layout(std430, set = 0, binding = 3) readonly buffer CutCount { uint cutCount[]; };
layout(std430, set = 0, binding = 4) buffer Slots { uint64_t slots[]; };
// [1] atomicMin calls, [4] texel ray tests, [5] pairs through the wrapped window, [7] pairs dropped as
// occluded (vir_lod_cut.comp lists all)
layout(std430, set = 0, binding = 5) buffer Stats { uint64_t stats[]; };
layout(std430, set = 0, binding = 6) readonly buffer Rects { vec4 rects[]; };  // gpu/vir_lod.h VirLodTree::rects
layout(push_constant) uniform Push { VirLodParams params; };

#ifdef LFGI_VIR_LOD_SPLAT_FAR
layout(std430, set = 0, binding = 7) readonly buffer Hiz { uint hiz[]; };  // vir_lod_hiz.comp
#include "vir_lod_occlusion.glsl"
#endif

const float kEdgeEps = 1.0 / 256.0;  // texels: outline spans widened against rounding (ray test decides)

// The current (node, probe) pair: the node set by main(), the probe by splatPair(), read by splatTexel().
vec3 o, nrm, pos, t1, t2;  // probe, node normal, centre, footprint frame (t2 = n x t1)
vec2 ext;                  // half extents along t1, t2 (leaves: the disc's bounding square)
vec2 nearExt;              // the near-miss zone's half extents (rectangles) or radius (leaves: x)
vec3 e1, e2;               // t1 ext.x, t2 ext.y
float radius;              // footprint radius (m): disc radius x footprintScale, a rectangle's half diagonal
float nearRadius;          // radius of the near-miss zone's bounding sphere (>= radius)
float facing, r2;          // dot(n, probe - centre); disc radius^2 (leaves)
bool isRect;
uint base;
uint64_t low;
uint atomics = 0u, tests = 0u, occluded = 0u, windowPairs = 0u;

// The texel-centre ray of interior texel t against the footprint; the nearest hit per texel wins. The ray
// direction stays unnormalised (octDecodeL1): only a hit needs the length, for the depth along the unit ray.
void splatTexel(ivec2 t) {
  ++tests;
  vec3 td = octDecodeL1(octTexelCentre(uvec2(t), params.res));
  float denom = -dot(nrm, td);
  if (denom <= 1e-6) return;
  float scaled = facing / denom;  // o + scaled td lies on the footprint's plane
  vec3 h = o + scaled * td - pos;
  vec2 a = isRect ? abs(vec2(dot(h, t1), dot(h, t2))) : vec2(0.0);
  float h2 = isRect ? 0.0 : dot(h, h);
  bool hit = isRect ? all(lessThanEqual(a, ext)) : h2 <= r2;
  uint slot = base + uint(t.y) * params.res + uint(t.x);
  if (hit) {
    float depth = scaled * length(td);
    atomicMin(slots[slot], (uint64_t(floatBitsToUint(depth)) << 32) | low);
    ++atomics;
  } else if (isRect ? all(lessThanEqual(a, nearExt)) : h2 <= nearExt.x * nearExt.x) {
    atomicMin(slots[slot], LFGI_VIR_NEAR_MISS_SLOT);
  }
}

vec2 texelCoord(vec3 q) { return (octEncode(q) * 0.5 + vec2(0.5)) * float(params.res); }

// Widens span (x min, x max) by the edge a-b clipped to the rows y in [y0, y1].
void clipEdge(vec2 a, vec2 b, float y0, float y1, inout vec2 span) {
  if (max(a.y, b.y) < y0 || min(a.y, b.y) > y1) return;
  float dy = b.y - a.y;
  float s0 = dy == 0.0 ? 0.0 : clamp((y0 - a.y) / dy, 0.0, 1.0);
  float s1 = dy == 0.0 ? 1.0 : clamp((y1 - a.y) / dy, 0.0, 1.0);
  float x0 = mix(a.x, b.x, s0), x1 = mix(a.x, b.x, s1);
  span = vec2(min(span.x, min(x0, x1)), max(span.y, max(x0, x1)));
}

// The block's probes (xyz position, w map index), read once per invocation: the node-major loop reads a
// probe per (node, probe) pair, and on llvmpipe a buffer read costs per lane and word while this private
// array, indexed alike by every lane, does not (1.1-1.2x faster at N = 8 and 16).
vec4 blockProbes[LFGI_VIR_LOD_MAX_BLOCK_PROBES];

// One (node, probe) pair: the node's fields are set by main(), the probe's here (k: its index in the block).
void splatPair(uint k) {
  o = blockProbes[k].xyz;
  uint map = uint(blockProbes[k].w);
  base = map * params.res * params.res;
  int n = int(params.res);
  float halfN = float(n) * 0.5;
  vec3 toS = pos - o;
  float d = length(toS);
  if (d > params.maxRange || d < 1e-6) return;
  facing = -dot(nrm, toS);
  if (facing <= 0.0) return;
  vec2 tc = texelCoord(toS);  // continuous texel coordinates of the centre
  ivec2 c = ivec2(floor(tc));
  // The square window: texel centres within the angular radius (x the map's largest stretch) of the
  // centre; none there (most sub-texel nodes): nothing to splat. Its half-size is capped at one map width n
  // (a period of the wrapped map: a huge near node still tests each texel a bounded number of times).
  float rho = asin(min(nearRadius / d, 1.0)) * halfN * LFGI_VIR_OCT_STRETCH;
  ivec2 lo = max(ivec2(ceil(tc - vec2(0.5 + rho))), c - ivec2(n));
  ivec2 hi = min(ivec2(floor(tc + vec2(rho - 0.5))), c + ivec2(n));
  if (any(greaterThan(lo, hi))) return;
#ifdef LFGI_VIR_LOD_SPLAT_FAR
  // Far pass of occlusion culling: the cut kept this node for the block; drop it for this probe when
  // the near pass already covered every texel it could reach with something nearer.
  if (virLodWindowOccluded(map, tc, rho + 1e-3, d - nearRadius)) {
    ++occluded;
    return;
  }
#endif
  // Corners relative to the probe; one octant when no coordinate changes sign across them.
  vec3 q0 = toS - e1 - e2, q1 = toS + e1 - e2, q2 = toS + e1 + e2, q3 = toS - e1 + e2;
  vec3 qmin = min(min(q0, q1), min(q2, q3)), qmax = max(max(q0, q1), max(q2, q3));
  if (all(equal(greaterThanEqual(qmin, vec3(0.0)), greaterThanEqual(qmax, vec3(0.0))))) {
    vec2 p0 = texelCoord(q0), p1 = texelCoord(q1), p2 = texelCoord(q2), p3 = texelCoord(q3);
    float ylo = min(min(p0.y, p1.y), min(p2.y, p3.y)), yhi = max(max(p0.y, p1.y), max(p2.y, p3.y));
    int ty0 = max(int(ceil(ylo - kEdgeEps - 0.5)), 0);
    int ty1 = min(int(floor(yhi + kEdgeEps - 0.5)), n - 1);
    for (int ty = ty0; ty <= ty1; ++ty) {
      float y0 = float(ty) + 0.5 - kEdgeEps, y1 = float(ty) + 0.5 + kEdgeEps;
      vec2 span = vec2(1e30, -1e30);
      clipEdge(p0, p1, y0, y1, span);
      clipEdge(p1, p2, y0, y1, span);
      clipEdge(p2, p3, y0, y1, span);
      clipEdge(p3, p0, y0, y1, span);
      if (span.x > span.y) continue;
      int tx0 = max(int(ceil(span.x - kEdgeEps - 0.5)), 0);
      int tx1 = min(int(floor(span.y + kEdgeEps - 0.5)), n - 1);
      for (int tx = tx0; tx <= tx1; ++tx) splatTexel(ivec2(tx, ty));
    }
  } else {
    ++windowPairs;
    for (int ty = lo.y; ty <= hi.y; ++ty)
      for (int tx = lo.x; tx <= hi.x; ++tx) splatTexel(octWrap(ivec2(tx, ty), n));
  }
}

void main() {
  uint lane = gl_GlobalInvocationID.x;
  uint block = params.blockFirst + gl_GlobalInvocationID.z;
  if (lane >= params.lanes) return;
  uint p0 = block * params.blockProbes;
  uint count = min(cutCount[gl_GlobalInvocationID.z], params.cutCapacity);
  uint cutBase = gl_GlobalInvocationID.z * params.cutCapacity;
  uint inBlock = min(p0 + params.blockProbes, params.probeCount) - p0;  // probes of this block
  for (uint k = 0u; k < inBlock; ++k) blockProbes[k] = probes[p0 + k];
  uint visited = 0u;
  for (uint i = lane; i < count; i += params.lanes) {
    uint s = cut[cutBase + i];
    vec4 pr = nodes[s].positionRadius;
    pos = pr.xyz;
    nrm = nodes[s].normal.xyz;
    radius = pr.w * params.footprintScale;
    r2 = radius * radius;
    vec4 rect = rects[s];
    isRect = rect.z >= 0.0;
    t1 = isRect ? octDecode(rect.xy) : virRectAxis(nrm);
    t2 = cross(nrm, t1);
    ext = isRect ? rect.zw : vec2(radius);
    float ratio = virNearMissRatio(params.fillNearMiss, params.footprintScale);
    nearExt = isRect ? ext + vec2((ratio - 1.0) * min(ext.x, ext.y)) : vec2(radius * ratio);
    nearRadius = isRect ? length(nearExt) : nearExt.x;
    e1 = t1 * nearExt.x;
    e2 = t2 * (isRect ? nearExt.y : nearExt.x);
    low = uint64_t(s);
    visited += inBlock;
    for (uint k = 0u; k < inBlock; ++k) splatPair(k);
  }
  if (visited > 0u) atomicAdd(stats[0], uint64_t(visited));
  if (atomics > 0u) atomicAdd(stats[1], uint64_t(atomics));
  if (tests > 0u) atomicAdd(stats[4], uint64_t(tests));
  if (windowPairs > 0u) atomicAdd(stats[5], uint64_t(windowPairs));
  if (occluded > 0u) atomicAdd(stats[7], uint64_t(occluded));
}
