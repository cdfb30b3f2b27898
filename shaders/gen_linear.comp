#version 450
// Generator decode, linear layer (core/generator.h): h0 = ReLU(W0 [z | c] + b0) for a batch of probes, written
// into the zero-bordered activation layout of shared/generator.h. Barrier-free and register-blocked like
// gemm_rowstrip.comp: each invocation computes 4 output rows x 4 probes (one vec4 per row).
#include "shared/generator.h"

layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) readonly buffer Latents { float z[]; };
layout(std430, set = 0, binding = 1) readonly buffer Weights { vec4 w[]; };   // [rows4][in][4 rows]
layout(std430, set = 0, binding = 2) readonly buffer Bias { vec4 bias[]; };   // [rows4]
layout(std430, set = 0, binding = 3) writeonly buffer Act { vec4 act[]; };    // [C0pad][6][6][S4]
layout(push_constant) uniform Push { GenLinearParams params; };

void main() {
  uint id = gl_GlobalInvocationID.x;
  uint p4 = id % params.probes4, rb = id / params.probes4;
  if (rb >= params.rows4) return;
  uint L = params.latentDim, inDim = params.latentDim + params.condDim;
  // Padded probes (the last vec4's tail) read the last real probe; their results are never stored as output.
  uint last = params.probes - 1u;
  uint z0 = min(p4 * 4u + 0u, last) * L, z1 = min(p4 * 4u + 1u, last) * L;
  uint z2 = min(p4 * 4u + 2u, last) * L, z3 = min(p4 * 4u + 3u, last) * L;
  vec4 b = bias[rb];
  vec4 acc0 = vec4(b.x), acc1 = vec4(b.y), acc2 = vec4(b.z), acc3 = vec4(b.w);
  uint wb = rb * inDim;
  for (uint k = 0u; k < L; ++k) {
    vec4 x = vec4(z[z0 + k], z[z1 + k], z[z2 + k], z[z3 + k]);
    vec4 wk = w[wb + k];
    acc0 += wk.x * x;
    acc1 += wk.y * x;
    acc2 += wk.z * x;
    acc3 += wk.w * x;
  }
  for (uint c = 0u; c < params.condDim; ++c) {
    vec4 wk = w[wb + L + c] * params.cond[c];
    acc0 += wk.x;
    acc1 += wk.y;
    acc2 += wk.z;
    acc3 += wk.w;
  }
  // rows rb*4 .. rb*4+3 are channel rb / 4, texel row iy = rb % 4, texels ix = 0..3
  uint ch = rb / 4u, iy = rb % 4u;
  uint s4 = params.probeStride4;
  uint base = ((ch * 6u + iy + 1u) * 6u + 1u) * s4 + p4;
  act[base] = max(acc0, vec4(0.0));
  act[base + s4] = max(acc1, vec4(0.0));
  act[base + 2u * s4] = max(acc2, vec4(0.0));
  act[base + 3u * s4] = max(acc3, vec4(0.0));
}
