#version 450
// Generator decode, one stride-2 transposed conv (core/generator.h) in sub-pixel form: output texel
// (2m + py, 2n + px) is a 2 x 2 conv of the input around (m, n), so each of the 4 phases is a GEMM with
// K = 4 Cin. Barrier-free and register-blocked for lavapipe (docs/DESIGN.md §6; same shape as gemm_rowstrip.comp):
// each invocation computes 4 output channels x 4 probes, reading 4 weight vec4 and 4 input vec4 per input
// channel for 16 vec4 FMAs. The zero border of the activations removes all bounds checks from the loop.
layout(local_size_x = 64) in;
#include "gen_tconv_common.glsl"

void main() {
  uint id = gl_GlobalInvocationID.x;
  uint P4 = params.probes4, res = params.res;
  uint p4 = id % P4;
  uint rest = id / P4;
  uint n = rest % res;
  rest /= res;
  uint m = rest % res;
  rest /= res;
  uint phase = rest % 4u, ob = rest / 4u;
  if (ob >= params.cout4) return;
  uint S4 = params.probeStride4;
  uint py = phase >> 1u, px = phase & 1u, rp = res + 2u, plane = rp * rp * S4;
  uint y0 = uint(int(m) + genTapOffset(py, 0u) + 1), y1 = uint(int(m) + genTapOffset(py, 1u) + 1);
  uint x0 = uint(int(n) + genTapOffset(px, 0u) + 1), x1 = uint(int(n) + genTapOffset(px, 1u) + 1);
  uint o0 = (y0 * rp + x0) * S4 + p4, o1 = (y0 * rp + x1) * S4 + p4;
  uint o2 = (y1 * rp + x0) * S4 + p4, o3 = (y1 * rp + x1) * S4 + p4;
  uint wi = (phase * params.cout4 + ob) * params.cin * 4u;
  vec4 acc0 = vec4(0.0), acc1 = vec4(0.0), acc2 = vec4(0.0), acc3 = vec4(0.0);
  for (uint ci = 0u; ci < params.cin; ++ci) {
    uint xb = ci * plane;
    vec4 a0 = x[xb + o0], a1 = x[xb + o1], a2 = x[xb + o2], a3 = x[xb + o3];
    vec4 w0 = w[wi], w1 = w[wi + 1u], w2 = w[wi + 2u], w3 = w[wi + 3u];
    wi += 4u;
    acc0 += w0.x * a0 + w1.x * a1 + w2.x * a2 + w3.x * a3;
    acc1 += w0.y * a0 + w1.y * a1 + w2.y * a2 + w3.y * a3;
    acc2 += w0.z * a0 + w1.z * a1 + w2.z * a2 + w3.z * a3;
    acc3 += w0.w * a0 + w1.w * a1 + w2.w * a2 + w3.w * a3;
  }
  storeBlock(ob, phase, m, n, p4, acc0, acc1, acc2, acc3);
}
