#version 450
// Probe irradiance for the next relight frame: E(n) = sum_texels L(w) max(0, n.w) dOmega(w) (exact
// cosine convolution, as irradiance_convolve.comp) over each probe's N x N VIR radiance map, where a
// texel that no surfel covered (coverage 0 after hole fill) sees the sky: skyRadiance without the discs
// (LFGI_RELIGHT_SKY; the discs reach surfels through the shadow map, never through the probes). With
// LFGI_RELIGHT_FILLED_SKY (RelightOptions::filledTexelsSeeSky, off by default), texels that only the hole
// fill covered count as uncovered too. Off is right for a fill that closes only enclosed gaps
// (vir_holefill.comp), which are geometry; a fill that grew silhouettes into the sky would need it on.
// The probe-independent parts come from the CPU (RelightPass::convolve): output texels are taken in
// groups of 16 (texel o = 16 g + 4 k + c, k = 0..3, c = 0..3, row-major over the M x M map; past M^2: none),
// weights[(g N^2 + t) 4 + k][c] = max(0, n_o . w_t) dOmega_t, and sky[t] is the sky radiance of input
// texel t. One invocation per (probe, group): every input texel is loaded once for 16 outputs (register
// blocking, as gemm_rowstrip.comp); lanes are neighbouring probes of one group, so the weight loads are
// the same for every lane; no barriers. (One invocation per output texel, with the directions, the
// cosine and the sky evaluated per pair, took ~8 s per call on a 15 k-probe city cell on lavapipe.)
#include "shared/relight.h"

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Radiance { vec4 radiance[]; };
layout(std430, set = 0, binding = 1) readonly buffer Normal { vec4 normals[]; };
layout(std430, set = 0, binding = 2) readonly buffer Weights { vec4 weights[]; };
layout(std430, set = 0, binding = 3) readonly buffer Sky { vec4 sky[]; };
layout(std430, set = 0, binding = 4) writeonly buffer Irradiance { vec4 irradiance[]; };

layout(push_constant) uniform Push { RelightParams params; };

void main() {
  uint probe = gl_GlobalInvocationID.x, g = gl_GlobalInvocationID.y;
  uint m2 = params.irradianceRes * params.irradianceRes;
  uint n2 = params.distanceRes * params.distanceRes;
  if (probe >= params.probeCount || g * 16u >= m2) return;
  bool useSky = (params.flags & LFGI_RELIGHT_SKY) != 0u;
  uint base = probe * n2;
  vec3 e[16] = vec3[16](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0),
                        vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
  for (uint t = 0u; t < n2; ++t) {
    uint wi = (g * n2 + t) * 4u;
    vec4 w0 = weights[wi], w1 = weights[wi + 1u], w2 = weights[wi + 2u], w3 = weights[wi + 3u];
    if (w0 + w1 + w2 + w3 == vec4(0.0)) continue;  // behind all 16 normals (keeps Inf x 0 out of the sums)
    vec3 l = radiance[base + t].rgb;
    float coverage = normals[base + t].w;
    if (relightTexelSeesSky(coverage, params.flags)) l = useSky ? sky[t].rgb : vec3(0.0);
    e[0] += l * w0.x; e[1] += l * w0.y; e[2] += l * w0.z; e[3] += l * w0.w;
    e[4] += l * w1.x; e[5] += l * w1.y; e[6] += l * w1.z; e[7] += l * w1.w;
    e[8] += l * w2.x; e[9] += l * w2.y; e[10] += l * w2.z; e[11] += l * w2.w;
    e[12] += l * w3.x; e[13] += l * w3.y; e[14] += l * w3.z; e[15] += l * w3.w;
  }
  // Constant indices only: a dynamically indexed e[] would live in memory on llvmpipe.
  uint first = g * 16u, out0 = probe * m2 + first;
#define LFGI_STORE(k) if (first + k < m2) irradiance[out0 + k] = vec4(e[k], 0.0);
  LFGI_STORE(0) LFGI_STORE(1) LFGI_STORE(2) LFGI_STORE(3) LFGI_STORE(4) LFGI_STORE(5) LFGI_STORE(6) LFGI_STORE(7)
  LFGI_STORE(8) LFGI_STORE(9) LFGI_STORE(10) LFGI_STORE(11) LFGI_STORE(12) LFGI_STORE(13) LFGI_STORE(14) LFGI_STORE(15)
#undef LFGI_STORE
}
