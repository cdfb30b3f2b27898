// Shared by gen_tconv_rowstrip.comp and gen_tconv_tiled.comp: bindings and the store of one invocation's
// 4 output channels x 4 probes (layouts in shared/generator.h).
#include "shared/generator.h"

layout(std430, set = 0, binding = 0) readonly buffer Act { vec4 x[]; };       // [Cin pad][res+2][res+2][S4]
layout(std430, set = 0, binding = 1) readonly buffer Weights { vec4 w[]; };   // [4][cout4][cin][4 taps]
layout(std430, set = 0, binding = 2) readonly buffer Bias { vec4 bias[]; };   // [cout4]
layout(std430, set = 0, binding = 3) writeonly buffer Next { vec4 y[]; };     // [cout4*4][2res+2][2res+2][S4]
layout(std430, set = 0, binding = 4) writeonly buffer Out { float outp[]; };  // [P][cout][2res][2res]
layout(push_constant) uniform Push { GenConvParams params; };

void storeBlock(uint ob, uint phase, uint m, uint n, uint p4, vec4 acc0, vec4 acc1, vec4 acc2, vec4 acc3) {
  vec4 b = bias[ob];
  acc0 += b.x;
  acc1 += b.y;
  acc2 += b.z;
  acc3 += b.w;
  uint ro = params.res * 2u;
  uint oy = 2u * m + (phase >> 1u), ox = 2u * n + (phase & 1u);
  if (params.last == 0u) {
    uint rp = ro + 2u, plane = rp * rp * params.probeStride4;
    uint base = (((ob * 4u) * rp + oy + 1u) * rp + ox + 1u) * params.probeStride4 + p4;
    y[base] = max(acc0, vec4(0.0));
    y[base + plane] = max(acc1, vec4(0.0));
    y[base + 2u * plane] = max(acc2, vec4(0.0));
    y[base + 3u * plane] = max(acc3, vec4(0.0));
  } else {
    uint texel = oy * ro + ox, chStride = ro * ro, probeStride = params.cout * chStride;
    for (uint l = 0u; l < 4u; ++l) {
      uint p = p4 * 4u + l;
      if (p >= params.probes) break;
      uint o = ob * 4u, base = p * probeStride + o * chStride + texel;
      if (o + 0u < params.cout) outp[base] = acc0[l];
      if (o + 1u < params.cout) outp[base + chStride] = acc1[l];
      if (o + 2u < params.cout) outp[base + 2u * chStride] = acc2[l];
      if (o + 3u < params.cout) outp[base + 3u * chStride] = acc3[l];
    }
  }
}
