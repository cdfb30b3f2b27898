// Push constants of irradiance_convolve.comp, shared by GLSL and C++.
#ifndef LFGI_SHARED_IRRADIANCE_H
#define LFGI_SHARED_IRRADIANCE_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

struct IrradianceParams {
  uint radianceRes;    // N: radiance maps are N x N texels (no border), vec4 per texel (rgb, unused)
  uint irradianceRes;  // M: irradiance maps are M x M texels (no border)
  uint probeCount;     // maps are stored one after another
  uint pad;
};
LFGI_CHECK_SIZE(IrradianceParams, 16)
LFGI_CHECK_OFFSET(IrradianceParams, probeCount, 8)

LFGI_SHARED_END

#endif  // LFGI_SHARED_IRRADIANCE_H
