#version 450
// GEMM without shared memory or barriers (docs/DESIGN.md §6: on lavapipe a workgroup's invocations run as
// coroutines, so barriers are very expensive). Each invocation computes a 4 x 4 block of C: four rows of
// A (scalars) times one vec4 column strip of B, accumulating in registers.
#include "shared/ceilings.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) readonly buffer A { vec4 a[]; };   // M x K, row-major, as vec4
layout(std430, set = 0, binding = 1) readonly buffer B { vec4 b[]; };   // K x N, row-major, as vec4
layout(std430, set = 0, binding = 2) writeonly buffer C { vec4 c[]; };  // M x N, row-major, as vec4
layout(push_constant) uniform Push { GemmParams params; };

void main() {
  uint n4 = params.n / 4, k4 = params.k / 4;
  uint id = gl_GlobalInvocationID.x;
  uint col4 = id % n4, row = (id / n4) * 4;
  if (row >= params.m) return;
  vec4 acc0 = vec4(0.0), acc1 = vec4(0.0), acc2 = vec4(0.0), acc3 = vec4(0.0);
  for (uint kk = 0; kk < k4; ++kk) {
    vec4 a0 = a[(row + 0) * k4 + kk], a1 = a[(row + 1) * k4 + kk];
    vec4 a2 = a[(row + 2) * k4 + kk], a3 = a[(row + 3) * k4 + kk];
    uint kb = kk * 4;
    vec4 b0 = b[(kb + 0) * n4 + col4], b1 = b[(kb + 1) * n4 + col4];
    vec4 b2 = b[(kb + 2) * n4 + col4], b3 = b[(kb + 3) * n4 + col4];
    acc0 += a0.x * b0 + a0.y * b1 + a0.z * b2 + a0.w * b3;
    acc1 += a1.x * b0 + a1.y * b1 + a1.z * b2 + a1.w * b3;
    acc2 += a2.x * b0 + a2.y * b1 + a2.z * b2 + a2.w * b3;
    acc3 += a3.x * b0 + a3.y * b1 + a3.z * b2 + a3.w * b3;
  }
  c[(row + 0) * n4 + col4] = acc0;
  c[(row + 1) * n4 + col4] = acc1;
  c[(row + 2) * n4 + col4] = acc2;
  c[(row + 3) * n4 + col4] = acc3;
}
