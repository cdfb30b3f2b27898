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
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
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
layout(std430, set = 0, binding = 8) buffer Stats { uint64_t stats[]; };

layout(push_constant) uniform Push { VirLodParams params; };

vec4 blk;
uint buf[32];
uint nbuf = 0u;

int classify(uint s) { return virLodClassify(nodes[s], links[s], blk, params); }

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
  blk = blocks[params.blockFirst + b];
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
  if (decider != 0xFFFFFFFFu) {
    if (decision == LFGI_VIR_LOD_ACCEPT && up[decider].y == fi) {
      emit(b, decider);
      flush(b);
    }
    return;
  }

  uint stack[LFGI_VIR_LOD_STACK];
  int sp = 0;
  stack[sp++] = f;
  uint forced = 0u;
  while (sp > 0) {
    uint s = stack[--sp];
    int c = classify(s);
    if (c == LFGI_VIR_LOD_DROP) continue;
    VirLodLink link = links[s];
    if (c == LFGI_VIR_LOD_REFINE && sp + int(link.childCount) > LFGI_VIR_LOD_STACK) {
      c = LFGI_VIR_LOD_ACCEPT;
      ++forced;
    }
    if (c == LFGI_VIR_LOD_ACCEPT) {
      emit(b, s);
    } else {
      // Pushed in reverse, so the walk pops children in Morton order.
      for (uint k = link.childCount; k > 0u; --k) stack[sp++] = children[link.firstChild + k - 1u];
    }
  }
  flush(b);
  if (forced > 0u) atomicAdd(stats[2], uint64_t(forced));
}
