#version 450
// 64-bit atomicMin throughput on scattered slots: the primitive of VIR's depth-tested splat
// (depth bits << 32 | surfel index).
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "shared/ceilings.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) buffer Slots { uint64_t slots[]; };
layout(push_constant) uniform Push { AtomicParams params; };

uint hash(uint x) {  // lowbias32 (Wellons 2020)
  x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
  return x;
}

void main() {
  uint id = gl_GlobalInvocationID.x;
  if (id >= params.threads) return;
  uint h = hash(id ^ params.seed);
  for (uint i = 0; i < params.updates; ++i) {
    h = hash(h + i);
    uint slot = h & (params.slots - 1u);
    atomicMin(slots[slot], (uint64_t(h) << 32) | uint64_t(id));
  }
}
