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
// above the frontier (VirLodTree::frontier cuts the tree into subtrees of <= 2048 nodes;
// LFGI_VIR_LOD_ABOVE_FRONTIER marks a node above it), emits what it accepts there and lists the frontier
// subtrees its walk reaches (`todo`, with the far bit). Subtrees: one invocation per (listed subtree,
// block) walks its subtree depth first. This keeps every invocation's loop short (llvmpipe stops a shader
// invocation's loops after 65535 iterations in total, which silently truncated one long walk per block)
// and gives a GPU blocks x subtrees parallel work. Each node above the frontier is classified once per
// block, not once per frontier subtree along its ancestors. The walks are stackless (VirLodCutNode
// firstChild / skip links) and each entry is appended with one atomicAdd: no private arrays, which
// llvmpipe spills and indexes lane by lane (a 128-entry stack and a 32-entry emit buffer make the cut
// ~1.2-1.6x slower at N <= 32). No shared memory, no barriers; the cut's order does not matter (the splat's atomicMin is order independent).
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

// VirLodTree::cutNodes
layout(std430, set = 0, binding = 0) readonly buffer Nodes { VirLodCutNode nodes[]; };
layout(std430, set = 0, binding = 1) buffer Todo { uint todo[]; };  // blockCount x nodeCount: node | kFarBit
layout(std430, set = 0, binding = 2) readonly buffer Blocks { VirLodBlock blocks[]; };  // gpu::virLodBlock
layout(std430, set = 0, binding = 3) writeonly buffer Cut { uint cut[]; };      // blockCount x cutCapacity
// [b]: cut entries of block b; [blockCount + b]: its todo entries (zeroed before each batch)
layout(std430, set = 0, binding = 4) buffer CutCount { uint cutCount[]; };
// [0] cut entries x probes (vir_lod_splat), [1] splat atomics, [2] unused,
// [3] entries a block needed beyond cutCapacity (0: none), [4] texel ray tests and [5] pairs through the
// wrapped square window (vir_lod_splat)
// [6] far-pass nodes dropped as occluded (subtrees count once), [7] far-pass pairs the splat dropped
layout(std430, set = 0, binding = 5) buffer Stats { uint64_t stats[]; };
layout(std430, set = 0, binding = 6) readonly buffer Probes { vec4 probes[]; };  // block order; w: map index
layout(std430, set = 0, binding = 7) readonly buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 8) readonly buffer Hiz { uint hiz[]; };
layout(std430, set = 0, binding = 9) readonly buffer Bounds { float bounds[]; };  // VirLodTree::bounds

layout(push_constant) uniform Push { VirLodParams params; };

#include "vir_lod_occlusion.glsl"

const uint kFarBit = 0x80000000u;  // todo entries: node | kFarBit when an ancestor is far

VirLodParams cp;  // params, with the near pass's range
VirLodBlock blk;
uint globalBlock;

int classify(uint s) { return virLodClassify(nodes[s], blk, cp); }

bool beyondNear(uint s) {
  return virLodBeyond(nodes[s].sphere, blk.sphere, params.nearRange, params.footprintScale);
}

// The sphere (node centre, radius) is occluded in every probe of the block.
bool blockOccluded(uint s, float radius) {
  vec3 c = nodes[s].sphere.xyz;
  for (uint i = 0u; i < params.blockProbes; ++i) {
    uint p = globalBlock * params.blockProbes + i;
    if (p >= params.probeCount) break;
    if (!virLodOccluded(probes[p].xyz, uint(probes[p].w), c, radius)) return false;
  }
  return true;
}

// Far pass: a far node whose footprint (accepted) or subtree (refined) is hidden from the whole block.
bool culled(uint s, int c) {
  return blockOccluded(s, c == LFGI_VIR_LOD_ACCEPT ? nodes[s].sphere.w * params.footprintScale : bounds[s]);
}

// Appends s to block b's cut (an overflow is counted: VirPass grows the buffer and runs again).
void emit(uint b, uint s) {
  uint at = atomicAdd(cutCount[b], 1u);
  if (at < params.cutCapacity) cut[b * params.cutCapacity + at] = s;
  else atomicMax(stats[3], uint64_t(at + 1u));
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

  // Stackless depth-first walk (VirLodCutNode::firstChild / skip) from node i until `end`, the node after
  // the walked subtree. farEnd: the skip of the far node whose subtree the walk is in (every node below a
  // far node is far), LFGI_VIR_LOD_NONE outside one.
  uint dropped = 0u, listed = 0u;
  uint i = params.rootNode, end = LFGI_VIR_LOD_NONE, farEnd = LFGI_VIR_LOD_NONE;
  if (!top) {
    uint e = todo[todoBase + k];
    i = e & ~kFarBit;
    end = nodes[i].skip;
    if ((e & kFarBit) != 0u) farEnd = end;
  }
  while (i != end) {
    if (i == farEnd) farEnd = LFGI_VIR_LOD_NONE;  // left the far subtree
    uint skip = nodes[i].skip;
    if (top && (nodes[i].flags & LFGI_VIR_LOD_ABOVE_FRONTIER) == 0u) {
      // A frontier subtree (the root itself, for a one-subtree tree): listed for the subtree stage.
      todo[todoBase + listed++] = i | (farEnd != LFGI_VIR_LOD_NONE ? kFarBit : 0u);
      i = skip;
      continue;
    }
    int c = classify(i);
    bool isFar = false;
    if (c != LFGI_VIR_LOD_DROP && farPass) {
      isFar = farEnd != LFGI_VIR_LOD_NONE || beyondNear(i);
      if (isFar && culled(i, c)) {
        ++dropped;
        c = LFGI_VIR_LOD_DROP;
      }
    }
    if (c == LFGI_VIR_LOD_REFINE) {
      if (isFar && farEnd == LFGI_VIR_LOD_NONE) farEnd = skip;
      i = nodes[i].firstChild;  // children in Morton order
    } else {
      if (c == LFGI_VIR_LOD_ACCEPT && (!farPass || isFar)) emit(b, i);
      i = skip;
    }
  }
  if (top) cutCount[params.blockCount + b] = listed;
  if (dropped > 0u) atomicAdd(stats[6], uint64_t(dropped));
}
