// Push constants of the generator decode kernels (gen_linear, gen_tconv_rowstrip, gen_tconv_tiled; host side
// in gpu/generator_pass.h). Network: core/generator.h.
//
// Device layouts (P4 = probe count rounded up to 4, divided by 4; probes are the vec4 lanes):
//   latents      [P][latentDim] floats, probe-major (as the cell stores them)
//   activations  [Cpad][res + 2][res + 2][S4] vec4: channels padded to 4, a zero border of one texel so the
//                2 x 2 taps of every output texel read without bounds checks. S4 (probeStride4) is the
//                scratch capacity / 4, fixed per scratch buffer, so the border stays zero for every batch
//                size.
//   output       [P][outChannels][R][R] floats, as generatorForward writes it
//   linear weights  [16 C0 / 4][latentDim + condDim][4]: 4 consecutive output rows per vec4
//   conv weights    [4 phases][Cout4][Cin][4 taps] vec4 of 4 output channels. Output texel (2m + py, 2n + px)
//                   is phase py * 2 + px; its tap t = ty * 2 + tx reads input (m + dy(py, ty), n + dx(px,
//                   tx)) with kernel index ky(py, ty), kx(px, tx) (see genTap below).
#ifndef LFGI_SHARED_GENERATOR_H
#define LFGI_SHARED_GENERATOR_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

struct GenLinearParams {
  vec4 cond;  // conditioning vector (zero-padded to 4)
  uint latentDim;
  uint condDim;
  uint rows4;         // 16 C0 / 4
  uint probes;        // P
  uint probes4;       // P4
  uint probeStride4;  // S4
  uint pad1, pad2;
};
LFGI_CHECK_SIZE(GenLinearParams, 48)

struct GenConvParams {
  uint cin;           // input channels (real count; padded channels are zero and skipped)
  uint cout4;         // output channels / 4, rounded up
  uint cout;          // output channels (real count)
  uint res;           // input resolution; output is 2 res
  uint probes;        // P
  uint probes4;       // P4
  uint last;          // 1: write the probe-major float output without ReLU; 0: ReLU into padded activations
  uint probeStride4;  // S4
};
LFGI_CHECK_SIZE(GenConvParams, 32)

// Kernel 4, stride 2, padding 1: output 2m + p (p = 0, 1) gets exactly two taps t = 0, 1 from input m + d
// with kernel index k: p = 0: (k = 1, d = 0), (k = 3, d = -1); p = 1: (k = 0, d = 1), (k = 2, d = 0).
LFGI_INLINE int genTapKernel(uint p, uint t) {
  return p == 0u ? (t == 0u ? 1 : 3) : (t == 0u ? 0 : 2);
}
LFGI_INLINE int genTapOffset(uint p, uint t) {
  return p == 0u ? (t == 0u ? 0 : -1) : (t == 0u ? 1 : 0);
}

LFGI_SHARED_END

#endif  // LFGI_SHARED_GENERATOR_H
