// Surfel: one disc of the scene's point cloud, as stored on the GPU (std430) and on the CPU.
#ifndef LFGI_SHARED_SURFEL_H
#define LFGI_SHARED_SURFEL_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

struct Surfel {
  vec4 positionRadius;  // xyz: world position (m); w: disc radius (m)
  vec4 normal;          // xyz: unit front-facing normal; w: unused (0)
  vec4 albedo;          // rgb: linear diffuse albedo in [0, 1]; a: unused (1)
  vec4 emission;        // rgb: emitted radiance, scene units; a: unused (0)
};
LFGI_CHECK_SIZE(Surfel, 64)
LFGI_CHECK_OFFSET(Surfel, emission, 48)

LFGI_SHARED_END

#endif  // LFGI_SHARED_SURFEL_H
