#version 450
// VIR LOD cut: per probe block (consecutive probes; bounding sphere and per-axis extents in `blocks`), the
// cut through the surfel LOD tree (gpu/vir_lod.h): walking down from the root, stop at the first node that
// shared/vir.h virLodClassify accepts (a leaf, or a coherent node at most lodTexels texels wide, or up to
// lodElongation x that when seen obliquely from the whole block, and thin enough seen from the block's
// nearest point) or drops (beyond maxRange, or facing away from every probe of the block: the splat would
// cull all of it); incoherent nodes (normal cone too wide) are always refined. vir_lod_splat.comp splats
// the cut into each probe of the block.
//
// The walk runs in two stages (VirLodParams::cutStage). Top: one invocation per block walks the nodes
// above the frontier (VirLodTree::frontier cuts the tree into subtrees of <= 2048 nodes; up[i].y != ~0u
// marks a node above it), emits what it accepts there and lists the frontier subtrees its walk reaches
// (`todo`, with the far bit). Subtrees: one invocation per (listed subtree, block) walks its subtree depth
// first. This keeps every invocation's loop short (llvmpipe stops a shader invocation's loops after
// 65535 iterations in total, which silently truncated one long walk per block) and gives a GPU
// blocks x subtrees parallel work. Each node above the frontier is classified once per block (before
// 2026-12-03 every frontier subtree's invocation replayed the walk along its ancestors). No shared memory,
// no barriers; entries are appended through a 32-entry private buffer and one atomicAdd per flush (the
// cut's order does not matter: the splat's atomicMin is order independent).
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
// (parent, designated frontier node: ~0u for frontier nodes and below)
layout(std430, set = 0, binding = 3) readonly buffer Up { uvec2 up[]; };
layout(std430, set = 0, binding = 4) buffer Todo { uint todo[]; };  // blockCount x nodeCount: node | kFarBit
layout(std430, set = 0, binding = 5) readonly buffer Blocks { VirLodBlock blocks[]; };  // gpu::virLodBlock
layout(std430, set = 0, binding = 6) writeonly buffer Cut { uint cut[]; };      // blockCount x cutCapacity
// [b]: cut entries of block b; [blockCount + b]: its todo entries (zeroed before each batch)
layout(std430, set = 0, binding = 7) buffer CutCount { uint cutCount[]; };
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
VirLodBlock blk;
uint globalBlock;
uint buf[32];
uint nbuf = 0u;

int classify(uint s) { return virLodClassify(nodes[s], links[s], blk, cp); }

bool beyondNear(uint s) { return virLodBeyond(nodes[s], blk.sphere, params.nearRange, params.footprintScale); }

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
  uint k = gl_GlobalInvocationID.y;
  if (b >= params.blockCount) return;
  bool top = params.cutStage == LFGI_VIR_LOD_STAGE_TOP;
  if (top ? k != 0u : k >= min(cutCount[params.blockCount + b], params.nodeCount)) return;
  globalBlock = params.blockFirst + b;
  blk = blocks[globalBlock];
  cp = params;
  if (params.cutPass == LFGI_VIR_LOD_PASS_NEAR) cp.maxRange = min(params.maxRange, params.nearRange);
  bool farPass = params.cutPass == LFGI_VIR_LOD_PASS_FAR;
  uint todoBase = b * params.nodeCount;

  uint stack[LFGI_VIR_LOD_STACK];
  int sp = 0;
  uint forced = 0u, dropped = 0u, listed = 0u;
  if (!top) stack[sp++] = todo[todoBase + k];
  else if (up[params.rootNode].y != 0xFFFFFFFFu) stack[sp++] = params.rootNode;
  else todo[todoBase + listed++] = params.rootNode;  // the root is a frontier node: a one-subtree tree
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
      // Pushed in reverse, so the walk pops children in Morton order. The top stage lists the frontier
      // subtrees it reaches instead of walking them.
      uint bit = isFar ? kFarBit : 0u;
      for (uint i = link.childCount; i > 0u; --i) {
        uint ch = children[link.firstChild + i - 1u];
        if (top && up[ch].y == 0xFFFFFFFFu) todo[todoBase + listed++] = ch | bit;
        else stack[sp++] = ch | bit;
      }
    }
  }
  flush(b);
  if (top) cutCount[params.blockCount + b] = listed;
  if (forced > 0u) atomicAdd(stats[2], uint64_t(forced));
  if (dropped > 0u) atomicAdd(stats[6], uint64_t(dropped));
}
