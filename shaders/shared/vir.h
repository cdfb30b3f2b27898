// Push constants of the View-Independent Rasterization passes (vir_splat/vir_resolve/vir_holefill.comp),
// shared by GLSL and C++. See gpu/vir_pass.h for the algorithm.
#ifndef LFGI_SHARED_VIR_H
#define LFGI_SHARED_VIR_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

struct VirParams {
  uint probeCount;          // probes, one N x N octahedral map each, stored one after another
  uint res;                 // N: texels per map side (no border)
  uint surfelCount;         // surfels in the surfel buffer
  uint maxFootprintRadius;  // splat window half-size in texels: at most (2k+1)^2 candidate texels per pair
  float maxRange;           // surfels farther than this from a probe (m) are not splatted into it
  float footprintScale;     // disc radius multiplier for the footprint test (>= 1 closes gaps between discs)
  uint fillPass;            // hole fill: index of this dilation pass (0, 1, ...)
  uint pad;
};
LFGI_CHECK_SIZE(VirParams, 32)
LFGI_CHECK_OFFSET(VirParams, maxRange, 16)

// Coverage generation stored in the w of the normal channel of a resolved map texel.
#define LFGI_VIR_HOLE 0.0f     // no surfel and no filled value
#define LFGI_VIR_COVERED 1.0f  // nearest surfel; a texel filled by dilation pass p holds p + 2

LFGI_SHARED_END

#endif  // LFGI_SHARED_VIR_H
