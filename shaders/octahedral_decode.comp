#version 450
// Decodes the centre direction of every texel of an N x N octahedral map (test + reference pass).
#include "shared/octahedral.h"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) writeonly buffer Directions { vec4 directions[]; };

layout(push_constant) uniform Params { uint resolution; } params;

void main() {
  uvec2 texel = gl_GlobalInvocationID.xy;
  uint n = params.resolution;
  if (texel.x >= n || texel.y >= n) return;
  directions[texel.y * n + texel.x] = vec4(octTexelDirection(texel, n), 0.0);
}
