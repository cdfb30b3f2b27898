#version 450
// Register-only FMA loop: 8 independent vec4 accumulators per invocation hide FMA latency; no memory
// traffic inside the loop. Measures the device's arithmetic ceiling (docs/DESIGN.md §6).
#include "shared/ceilings.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) writeonly buffer Out { vec4 outValues[]; };
layout(push_constant) uniform Push { FmaParams params; };

void main() {
  uint id = gl_GlobalInvocationID.x;
  if (id >= params.threads) return;
  vec4 a = vec4(float(id) * 1e-7f), m = vec4(0.9999f), c = vec4(1e-4f);
  vec4 x0 = a, x1 = a + 1.0f, x2 = a + 2.0f, x3 = a + 3.0f, x4 = a + 4.0f, x5 = a + 5.0f, x6 = a + 6.0f, x7 = a + 7.0f;
  for (uint i = 0; i < params.iterations; ++i) {
    x0 = fma(x0, m, c); x1 = fma(x1, m, c); x2 = fma(x2, m, c); x3 = fma(x3, m, c);
    x4 = fma(x4, m, c); x5 = fma(x5, m, c); x6 = fma(x6, m, c); x7 = fma(x7, m, c);
  }
  outValues[id] = x0 + x1 + x2 + x3 + x4 + x5 + x6 + x7;
}
