// Push constants of the View-Independent Rasterization passes (vir_splat/vir_resolve/vir_holefill.comp),
// shared by GLSL and C++. See gpu/vir_pass.h for the algorithm.
#ifndef LFGI_SHARED_VIR_H
#define LFGI_SHARED_VIR_H

#include "lfgi_shared.h"
#include "surfel.h"

LFGI_SHARED_BEGIN

#ifdef __cplusplus
using glm::sqrt;
#endif

struct VirParams {
  uint probeCount;          // probes, one N x N octahedral map each, stored one after another
  uint res;                 // N: texels per map side (no border)
  uint surfelCount;         // surfels in the surfel buffer
  uint maxFootprintRadius;  // splat window half-size in texels: at most (2k+1)^2 candidate texels per pair
  float maxRange;           // surfels farther than this from a probe (m) are not splatted into it
  float footprintScale;     // disc radius multiplier for the footprint test (>= 1 closes gaps between discs)
  uint fillPass;            // hole fill: index of this fill pass (0, 1, ...)
  uint emissionOnly;        // LOD resolve: 1 when no irradiance was given (radiance = the node's emission)
  float fillNearMiss;       // near-miss radius in disc radii (VirOptions::fillNearMiss; 0: off)
  uint pad0, pad1, pad2;
};
LFGI_CHECK_SIZE(VirParams, 48)
LFGI_CHECK_OFFSET(VirParams, maxRange, 16)

// Surfel LOD tree topology (gpu/vir_lod.h), one per node, beside the node's disc (a Surfel).
struct VirLodLink {
  uint firstChild;  // first entry of this node's children in the child-index buffer
  uint childCount;  // 0: leaf
  uint flags;       // LFGI_VIR_LOD_COHERENT: the leaves below lie in the node's plane (may be splatted)
  uint surfel;      // leaf: index of its surfel in the caller's array (irradiance lookup); inner: ~0u
};
LFGI_CHECK_SIZE(VirLodLink, 16)

#define LFGI_VIR_LOD_COHERENT 1u
// Largest per-axis stretch of the octahedral map, texel coordinates per radian in units of N / 2 (measured
// numerically: sqrt(2) where the fold's diagonals meet the equator), with a margin: bounds splat windows.
#define LFGI_VIR_OCT_STRETCH 1.5f
// First axis of a LOD node's rectangle frame (gpu/vir_lod.h), and of the bounding square of a leaf disc in
// vir_lod_splat.comp: a world axis projected into the plane of normal n (walls: up; floors and roofs: +x),
// so the axis-aligned walls and roofs of the synthetic city get tight rectangles. n: unit length.
LFGI_INLINE vec3 virRectAxis(vec3 n) {
  vec3 axis = abs(n.y) >= 0.5f ? vec3(1.0f, 0.0f, 0.0f) : vec3(0.0f, 1.0f, 0.0f);
  return normalize(axis - dot(axis, n) * n);
}

#define LFGI_VIR_LOD_MAX_BLOCK_PROBES \
  32  // VirOptions::lodBlockProbes limit (vir_lod_splat.comp's probe array)

// Push constants of the LOD passes (vir_lod_radiance/vir_lod_cut/vir_lod_splat/vir_lod_resolve.comp).
struct VirLodParams {
  uint probeCount;       // probes in the whole run
  uint res;              // N
  uint blockProbes;      // probes per block: block b holds probes [b * blockProbes, ...)
  uint blockFirst;       // first block of this batch
  uint blockCount;       // blocks in this batch
  uint cutCapacity;      // cut entries per block
  uint rootNode;         // LOD tree root
  uint cutPass;          // LFGI_VIR_LOD_PASS_*: one pass, or the near / far pass of the occlusion-culled cut
  uint nodeFirst;        // radiance pass: nodes [nodeFirst, nodeFirst + nodeCount) of one level
  uint nodeCount;        // cut pass: the number of frontier subtrees (todo entries per block)
  uint leafPass;         // radiance pass: 1 for the leaf level (emission + albedo E / pi)
  uint lanes;            // splat pass: invocations sharing one probe block's cut
  float maxRange;        // m
  float footprintScale;  // disc radius multiplier (as VirParams)
  float lodTexels;       // a node may be splatted when its footprint diameter <= lodTexels texels
  float depthTolerance;  // cut: a merged node's thickness must be <= depthTolerance x its distance
  float nearRange;       // occlusion culling: the near pass splats nodes within this range (m) of a block
  uint hizProbeTexels;   // occlusion culling: uints per probe in the HiZ buffer (levels 1, 2, ...)
  uint hizLevel;         // HiZ pass: the level written (>= 1); level 0 is the slots' depth words
  uint cutStage;         // cut pass: LFGI_VIR_LOD_STAGE_TOP or _SUBTREES (vir_lod_cut.comp)
  float lodElongation;   // cut: a foreshortened node may be up to this x lodTexels long (1: isotropic)
  float fillNearMiss;    // splat: near-miss radius in disc radii (as VirParams)
};
LFGI_CHECK_SIZE(VirLodParams, 88)
LFGI_CHECK_OFFSET(VirLodParams, maxRange, 48)

// VirLodParams::cutPass. Occlusion culling (VirOptions::lodOcclusionRange > 0) runs the cut and splat
// twice: the near pass keeps the nodes within nearRange of the block (virLodBeyond false for the node and
// all its ancestors), then per probe a max-depth pyramid (HiZ) of what they covered is built, then the far
// pass walks the whole tree again, emits only what the near pass did not, and drops a node when every
// texel its bounding sphere can reach already holds a nearer surface in every probe of the block.
#define LFGI_VIR_LOD_PASS_ALL 0u
#define LFGI_VIR_LOD_PASS_NEAR 1u
#define LFGI_VIR_LOD_PASS_FAR 2u

// VirLodParams::cutStage: the walk above the tree's frontier (one invocation per block, listing the
// frontier subtrees to walk), then the walks of the listed subtrees.
#define LFGI_VIR_LOD_STAGE_TOP 0u
#define LFGI_VIR_LOD_STAGE_SUBTREES 1u

// A probe block as the cut sees it (gpu::virLodBlock): a sphere about the probes' centroid holding them
// all, and the largest |offset| of a probe from that centroid per axis (bounds a probe's height over a
// node's plane far more tightly than the radius where the normal is axis-aligned: the city's walls).
struct VirLodBlock {
  vec4 sphere;  // xyz centre, w radius
  vec4 extent;  // xyz: per-axis extent about the centre (<= radius); w unused
};
LFGI_CHECK_SIZE(VirLodBlock, 32)

// One LOD tree node as the cut reads it (VirLodTree::cutNodes; vir_lod_cut.comp, gpu::virLodCut): the
// fields of its Surfel that virLodClassify needs and its links for a stackless depth-first walk, in 12
// words. The walk goes to firstChild when it refines a node and to skip otherwise, so it needs no stack: on
// llvmpipe a private array indexed by a data-dependent stack pointer is spilled and accessed lane by lane.
struct VirLodCutNode {
  vec4 sphere;      // xyz: node centre, w: node radius (before footprintScale), as Surfel::positionRadius
  vec4 normalCone;  // xyz: unit normal; w: cosine of the normal cone's half-angle (the node's albedo.w)
  uint firstChild;  // node index of the first child (the others follow through skip); leaves:
                    // LFGI_VIR_LOD_NONE
  uint skip;        // the node visited after this node's subtree: the next sibling, else the parent's skip
                    // (the root: LFGI_VIR_LOD_NONE)
  uint flags;       // LFGI_VIR_LOD_COHERENT | LFGI_VIR_LOD_ABOVE_FRONTIER
  float thickness;  // largest distance of a leaf centre below from the node plane (the node's emission.w)
};
LFGI_CHECK_SIZE(VirLodCutNode, 48)

#define LFGI_VIR_LOD_NONE 0xFFFFFFFFu
#define LFGI_VIR_LOD_ABOVE_FRONTIER 2u  // VirLodCutNode::flags: above VirLodTree::frontier (up[i].y != ~0u)

// True when the node's footprint (sphere: centre, radius before footprintScale) lies entirely beyond
// `range` of the whole block (the cut's range drop).
LFGI_INLINE bool virLodBeyond(vec4 sphere, vec4 block, float range, float footprintScale) {
  float dmin = length(vec3(block) - vec3(sphere)) - block.w;
  return dmin - sphere.w * footprintScale > range;
}

#define LFGI_VIR_LOD_REFINE 0
#define LFGI_VIR_LOD_ACCEPT 1
#define LFGI_VIR_LOD_DROP 2

// The cut's decision for one node of the LOD tree (gpu/vir_lod.h) seen from a probe block (sphere: xyz
// centre, w radius), shared by vir_lod_cut.comp and the CPU replay gpu::virLodCut:
//   drop   when the node's footprint lies beyond maxRange of the whole block, or when every node below it
//          faces away from every probe of the block (the splat would cull them all): normals within the
//          cone node.normalCone.w = cos(half-angle) of the node normal, centres within
//          r (1 + 1 / cos) + 2 thickness of the node centre (its rectangle bounds the projections of the
//          rectangles below, which tilt by at most the cone), tested only for cones below 60 degrees;
//   accept a leaf, or a coherent node whose footprint (radius r) is at most lodTexels texels wide seen from
//          the block's nearest point (w = r N / d <= lodTexels, i.e. 2 r / d <= lodTexels x 2 / N, the angle
//          of a texel where the map is least stretched) and whose thickness is <= depthTolerance x that
//          distance; a foreshortened node may be up to lodElongation x wider (w <= lodElongation x
//          lodTexels) while w^2 c <= lodTexels^2, c a bound on |cos| between its normal and any direction
//          from a probe of the block to its footprint (its projected area stays a lodTexels-wide node's):
//          walls seen obliquely from a street, whose cut nodes cover few texel centres each;
//   refine otherwise (children next).
LFGI_INLINE int virLodClassify(VirLodCutNode node, VirLodBlock blk, VirLodParams params) {
  vec4 block = blk.sphere;
  if (virLodBeyond(node.sphere, block, params.maxRange, params.footprintScale)) return LFGI_VIR_LOD_DROP;
  float r = node.sphere.w * params.footprintScale;
  vec3 v = vec3(block) - vec3(node.sphere);
  float lv = length(v);
  // nearest probe distance >= the distance to the block's sphere and to its box (per-axis extents)
  float dmin = max(lv - block.w, length(max(abs(v) - vec3(blk.extent), vec3(0.0f))));
  // largest offset of a probe from the block centre along the node normal (<= the radius)
  float spreadN = min(block.w, dot(abs(vec3(node.normalCone)), vec3(blk.extent)));
  float cosA = node.normalCone.w;
  if (cosA > 0.5f && lv > 0.0f) {
    float cosT = dot(vec3(node.normalCone), v) / lv;  // angle between the normal and the block centre
    float sinT = sqrt(max(1.0f - cosT * cosT, 0.0f)), sinA = sqrt(max(1.0f - cosA * cosA, 0.0f));
    float spread =
        node.firstChild == LFGI_VIR_LOD_NONE ? 0.0f : r * (1.0f + 1.0f / cosA) + 2.0f * node.thickness;
    // max over the cone's normals m of dot(m, v) = |v| cos(angle - cone half-angle); a probe's offset o
    // from the centre adds dot(m, o) <= |dot(n, o)| + |m - n| |o| <= spreadN + 2 sin(A / 2) radius
    float offsetN = min(block.w, spreadN + 2.0f * sqrt(max(0.5f - 0.5f * cosA, 0.0f)) * block.w);
    if (lv * (cosT * cosA + sinT * sinA) + offsetN + spread < 0.0f) return LFGI_VIR_LOD_DROP;
  }
  if (node.firstChild == LFGI_VIR_LOD_NONE) return LFGI_VIR_LOD_ACCEPT;
  if ((node.flags & LFGI_VIR_LOD_COHERENT) != 0u && dmin > 0.0f &&
      node.thickness <= params.depthTolerance * dmin) {
    float w = r * float(params.res) / dmin;  // the footprint's width in the classify's texel units
    // foreshortening bound: |cos| between the normal and the direction from any probe of the block to any
    // point of the footprint (in the node's plane) = the probe's height over the plane / its distance to
    // the point <= (centre height + largest probe offset along the normal) / (dmin - r)
    float closest = dmin - r;
    float c = closest > 0.0f ? min((abs(dot(vec3(node.normalCone), v)) + spreadN) / closest, 1.0f) : 1.0f;
    if (w <= params.lodTexels * params.lodElongation && w * w * c <= params.lodTexels * params.lodTexels)
      return LFGI_VIR_LOD_ACCEPT;
  }
  return LFGI_VIR_LOD_REFINE;
}

// Coverage generation stored in the w of the normal channel of a resolved map texel.
#define LFGI_VIR_HOLE 0.0f     // no surfel and no filled value
#define LFGI_VIR_COVERED 1.0f  // nearest surfel; a texel filled by fill pass p holds p + 2

// Near misses (VirOptions::fillNearMiss): a splat whose texel-centre ray misses a footprint but passes
// within max(footprintScale, fillNearMiss) disc radii of its centre (a LOD rectangle: within its smaller
// half extent x the same ratio over footprintScale beyond its edges) marks a slot still empty with this
// value, larger than every (depth bits << 32 | index) of a hit, so any hit wins over it. The resolve
// treats it as a hole; the hole fill closes only holes so marked: cracks between the discs of a surface
// are near misses, a window or skylight wider than about a disc radius is not.
#define LFGI_VIR_NEAR_MISS_SLOT 0xFFFFFFFEFFFFFFFFUL

// Near-miss radius over footprint radius (>= 1; 1: no near-miss zone).
LFGI_INLINE float virNearMissRatio(float fillNearMiss, float footprintScale) {
  return fillNearMiss > footprintScale ? fillNearMiss / footprintScale : 1.0f;
}

LFGI_SHARED_END

#endif  // LFGI_SHARED_VIR_H
