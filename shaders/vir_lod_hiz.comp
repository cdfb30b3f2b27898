#version 450
// VIR LOD occlusion culling (VirOptions::lodOcclusionRange): one level of each probe map's max-depth
// pyramid after the near pass. Level 0 is the splat's depth buffer (the depth word of each 64-bit slot,
// ~0u for a hole); level l >= 1 is ceil(N / 2^l) texels square, each the max of the <= 2 x 2 texels of
// level l - 1 it covers. Read by shaders/vir_lod_occlusion.glsl.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "shared/octahedral.h"
#include "shared/surfel.h"
#include "shared/vir.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Slots { uint64_t slots[]; };
layout(std430, set = 0, binding = 1) buffer Hiz { uint hiz[]; };

layout(push_constant) uniform Push { VirLodParams params; };

#include "vir_lod_occlusion.glsl"

void main() {
  uint level = params.hizLevel;
  uint dim = virHizLevelDim(level), below = virHizLevelDim(level - 1u);
  uvec2 t = gl_GlobalInvocationID.xy;
  uint map = gl_GlobalInvocationID.z;
  if (t.x >= dim || t.y >= dim || map >= params.probeCount) return;
  uint m = 0u;
  for (uint dy = 0u; dy < 2u; ++dy)
    for (uint dx = 0u; dx < 2u; ++dx)
      m = max(m, virHizRead(map, level - 1u, min(2u * t + uvec2(dx, dy), uvec2(below - 1u))));
  hiz[virHizIndex(map, level, t)] = m;
}
