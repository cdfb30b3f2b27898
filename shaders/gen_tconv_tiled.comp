#version 450
// Generator decode, one stride-2 transposed conv, shared-memory tiled for real GPUs (the same sub-pixel GEMM as
// gen_tconv_rowstrip.comp). A workgroup of 64 computes 16 output channels x 16 column groups (texel, 4 probes):
// each step stages 16 input channels x 4 taps x 16 column groups of activations and the matching weights in
// shared memory, so every activation is read from memory once per 16 output channels instead of once per 4.
// On lavapipe the barriers make this several times slower than the rowstrip kernel (docs/DESIGN.md §6).
layout(local_size_x = 64) in;
#include "gen_tconv_common.glsl"

const uint kCi = 16u;    // input channels per step
const uint kCols = 16u;  // column groups per workgroup
shared vec4 sx[kCi * 4u * kCols];  // [ci][tap][col]
shared vec4 sw[kCi * 4u * 4u];     // [ci][tap][ob]

void main() {
  uint lid = gl_LocalInvocationID.x;
  uint sub = lid / kCols, col = lid % kCols;
  uint P4 = params.probes4, S4 = params.probeStride4, res = params.res, rp = res + 2u, plane = rp * rp * S4;
  uint columns = res * res * P4;
  uint phase = gl_WorkGroupID.y % 4u, obBase = (gl_WorkGroupID.y / 4u) * 4u;
  uint py = phase >> 1u, px = phase & 1u;
  vec4 acc0 = vec4(0.0), acc1 = vec4(0.0), acc2 = vec4(0.0), acc3 = vec4(0.0);
  for (uint ci0 = 0u; ci0 < params.cin; ci0 += kCi) {
    for (uint i = 0u; i < 16u; ++i) {
      uint e = lid + 64u * i;
      uint c = e / (4u * kCols), t = (e / kCols) % 4u, cl = e % kCols;
      uint g = gl_WorkGroupID.x * kCols + cl, ci = ci0 + c;
      vec4 v = vec4(0.0);
      if (ci < params.cin && g < columns) {
        uint gp4 = g % P4, gn = (g / P4) % res, gm = g / (P4 * res);
        uint yy = uint(int(gm) + genTapOffset(py, t >> 1u) + 1), xx = uint(int(gn) + genTapOffset(px, t & 1u) + 1);
        v = x[ci * plane + (yy * rp + xx) * S4 + gp4];
      }
      sx[e] = v;
    }
    for (uint i = 0u; i < 4u; ++i) {
      uint e = lid + 64u * i;
      uint c = e / 16u, t = (e / 4u) % 4u, ob = obBase + e % 4u, ci = ci0 + c;
      sw[e] = (ci < params.cin && ob < params.cout4) ? w[((phase * params.cout4 + ob) * params.cin + ci) * 4u + t]
                                                     : vec4(0.0);
    }
    barrier();
    for (uint c = 0u; c < kCi; ++c) {
      vec4 a0 = sx[(c * 4u + 0u) * kCols + col], a1 = sx[(c * 4u + 1u) * kCols + col];
      vec4 a2 = sx[(c * 4u + 2u) * kCols + col], a3 = sx[(c * 4u + 3u) * kCols + col];
      vec4 w0 = sw[(c * 4u + 0u) * 4u + sub], w1 = sw[(c * 4u + 1u) * 4u + sub];
      vec4 w2 = sw[(c * 4u + 2u) * 4u + sub], w3 = sw[(c * 4u + 3u) * 4u + sub];
      acc0 += w0.x * a0 + w1.x * a1 + w2.x * a2 + w3.x * a3;
      acc1 += w0.y * a0 + w1.y * a1 + w2.y * a2 + w3.y * a3;
      acc2 += w0.z * a0 + w1.z * a1 + w2.z * a2 + w3.z * a3;
      acc3 += w0.w * a0 + w1.w * a1 + w2.w * a2 + w3.w * a3;
    }
    barrier();
  }
  uint g = gl_WorkGroupID.x * kCols + col, ob = obBase + sub;
  if (g >= columns || ob >= params.cout4) return;
  storeBlock(ob, phase, (g / P4) / res, (g / P4) % res, g % P4, acc0, acc1, acc2, acc3);
}
