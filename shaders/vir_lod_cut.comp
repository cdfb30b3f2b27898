#version 450
// VIR LOD cut: per probe block (consecutive probes, bounding sphere in `blocks`), the cut through the
// surfel LOD tree (gpu/vir_lod.h): walking down from the root, stop at the first node that
// shared/vir.h virLodClassify accepts (a leaf, or a coherent node at most lodTexels texels wide and thin
// enough seen from the block's nearest point) or drops (beyond maxRange, or facing away from every probe
// of the block: the splat would cull all of it); incoherent nodes (normal cone too wide) are always
// refined. vir_lod_splat.comp splats the cut into each probe of the block.
//
// The walk is split into one invocation per (frontier subtree, block): the frontier (VirLodTree::frontier)
// cuts the tree into subtrees of <= 2048 nodes. An invocation first replays the walk along its subtree
// root's ancestors: if the walk would stop above it (accept or drop), only the ancestor's designated
// frontier invocation emits that node; otherwise it walks its subtree depth first. This keeps every
// invocation's loop short (llvmpipe stops a shader invocation's loops after 65535 iterations in total,
// which silently truncated one long walk per block) and gives a GPU blocks x frontier parallel work.
// No shared memory, no barriers; entries are appended through a 32-entry private buffer and one
// atomicAdd per flush (the cut's order does not matter: the splat's atomicMin is order independent).
//
// Occlusion culling (cutPass, shared/vir.h): the near pass classifies with maxRange = min(maxRange,
// nearRange); the far pass walks with the full range, carries a "far" bit down the walk (this node or an
// ancestor lies beyond nearRange of the block: the near pass dropped it), emits only far nodes, and drops
// a far node whose bounding sphere (its own footprint when accepted, the subtree's `bounds` when refined)
// is occluded in every probe of the block (vir_lod_occlusion.glsl against the near pass's HiZ).
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "shared/octahedral.h"
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Nodes { Surfel nodes[]; };
layout(std430, set = 0, binding = 1) readonly buffer Links { VirLodLink links[]; };
layout(std430, set = 0, binding = 2) readonly buffer Children { uint children[]; };
layout(std430, set = 0, binding = 3) readonly buffer Up { uvec2 up[]; };  // (parent, designated frontier)
layout(std430, set = 0, binding = 4) readonly buffer Frontier { uint frontier[]; };
layout(std430, set = 0, binding = 5) readonly buffer Blocks { vec4 blocks[]; };  // xyz centre, w radius
layout(std430, set = 0, binding = 6) writeonly buffer Cut { uint cut[]; };      // blockCount x cutCapacity
layout(std430, set = 0, binding = 7) buffer CutCount { uint cutCount[]; };      // zeroed before each batch
// [0] cut entries x probes (vir_lod_splat), [1] splat atomics, [2] nodes accepted for lack of stack,
// [3] entries a block needed beyond cutCapacity (0: none), [4] texel ray tests and [5] pairs through the
// wrapped square window (vir_lod_splat)
// [6] far-pass nodes dropped as occluded (subtrees count once), [7] far-pass pairs the splat dropped
layout(std430, set = 0, binding = 8) buffer Stats { uint64_t stats[]; };
layout(std430, set = 0, binding = 9) readonly buffer Probes { vec4 probes[]; };  // block order; w: map index
layout(std430, set = 0, binding = 10) readonly buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 11) readonly buffer Hiz { uint hiz[]; };
layout(std430, set = 0, binding = 12) readonly buffer Bounds { float bounds[]; };  // VirLodTree::bounds

layout(push_constant) uniform Push { VirLodParams params; };

#include "vir_lod_occlusion.glsl"

const uint kFarBit = 0x80000000u;  // stack entries: node | kFarBit when the node or an ancestor is far

VirLodParams cp;  // params, with the near pass's range
vec4 blk;
uint globalBlock;
uint buf[32];
uint nbuf = 0u;

int classify(uint s) { return virLodClassify(nodes[s], links[s], blk, cp); }

bool beyondNear(uint s) { return virLodBeyond(nodes[s], blk, params.nearRange, params.footprintScale); }

// The sphere (node centre, radius) is occluded in every probe of the block.
bool blockOccluded(uint s, float radius) {
  vec3 c = nodes[s].positionRadius.xyz;
  for (uint i = 0u; i < params.blockProbes; ++i) {
    uint p = globalBlock * params.blockProbes + i;
    if (p >= params.probeCount) break;
    if (!virLodOccluded(probes[p].xyz, uint(probes[p].w), c, radius)) return false;
  }
  return true;
}

// Far pass: a far node whose footprint (accepted) or subtree (refined) is hidden from the whole block.
bool culled(uint s, int c) {
  return blockOccluded(s, c == LFGI_VIR_LOD_ACCEPT ? nodes[s].positionRadius.w * params.footprintScale : bounds[s]);
}

void flush(uint b) {
  if (nbuf == 0u) return;
  uint at = atomicAdd(cutCount[b], nbuf);
  uint base = b * params.cutCapacity;
  for (uint k = 0u; k < nbuf; ++k)
    if (at + k < params.cutCapacity) cut[base + at + k] = buf[k];
  if (at + nbuf > params.cutCapacity) atomicMax(stats[3], uint64_t(at + nbuf));
  nbuf = 0u;
}

void emit(uint b, uint s) {
  buf[nbuf++] = s;
  if (nbuf == 32u) flush(b);
}

void main() {
  uint b = gl_GlobalInvocationID.x;
  uint fi = gl_GlobalInvocationID.y;
  if (fi >= params.nodeCount || b >= params.blockCount) return;
  globalBlock = params.blockFirst + b;
  blk = blocks[globalBlock];
  cp = params;
  if (params.cutPass == LFGI_VIR_LOD_PASS_NEAR) cp.maxRange = min(params.maxRange, params.nearRange);
  bool farPass = params.cutPass == LFGI_VIR_LOD_PASS_FAR;
  uint f = frontier[fi];

  // The top-down walk stops at the topmost ancestor that is accepted or dropped.
  uint decider = 0xFFFFFFFFu;
  int decision = LFGI_VIR_LOD_REFINE;
  for (uint a = up[f].x; a != 0xFFFFFFFFu; a = up[a].x) {
    int c = classify(a);
    if (c != LFGI_VIR_LOD_REFINE) {
      decider = a;
      decision = c;
    }
  }
  // Far pass: the walk down to the decider (or to f's parent) passed a node beyond nearRange.
  bool far = false;
  if (farPass)
    for (uint a = decider != 0xFFFFFFFFu ? decider : up[f].x; a != 0xFFFFFFFFu && !far; a = up[a].x) far = beyondNear(a);
  if (decider != 0xFFFFFFFFu) {
    if (decision == LFGI_VIR_LOD_ACCEPT && up[decider].y == fi) {
      if (!farPass) {
        emit(b, decider);
      } else if (far) {
        if (culled(decider, decision)) atomicAdd(stats[6], uint64_t(1));
        else emit(b, decider);
      }
      flush(b);
    }
    return;
  }

  uint stack[LFGI_VIR_LOD_STACK];
  int sp = 0;
  stack[sp++] = f | (far ? kFarBit : 0u);
  uint forced = 0u, dropped = 0u;
  while (sp > 0) {
    uint e = stack[--sp];
    uint s = e & ~kFarBit;
    int c = classify(s);
    if (c == LFGI_VIR_LOD_DROP) continue;
    bool isFar = false;
    if (farPass) {
      isFar = (e & kFarBit) != 0u || beyondNear(s);
      if (isFar && culled(s, c)) {
        ++dropped;
        continue;
      }
    }
    VirLodLink link = links[s];
    if (c == LFGI_VIR_LOD_REFINE && sp + int(link.childCount) > LFGI_VIR_LOD_STACK) {
      c = LFGI_VIR_LOD_ACCEPT;
      ++forced;
    }
    if (c == LFGI_VIR_LOD_ACCEPT) {
      if (!farPass || isFar) emit(b, s);
    } else {
      // Pushed in reverse, so the walk pops children in Morton order.
      uint bit = isFar ? kFarBit : 0u;
      for (uint k = link.childCount; k > 0u; --k) stack[sp++] = children[link.firstChild + k - 1u] | bit;
    }
  }
  flush(b);
  if (forced > 0u) atomicAdd(stats[2], uint64_t(forced));
  if (dropped > 0u) atomicAdd(stats[6], uint64_t(dropped));
}
