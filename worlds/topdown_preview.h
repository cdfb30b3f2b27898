// A top-down picture of a region of a world, lit by the sky model: the quick look a person wants after
// generating a world (not ground truth: direct sun with ray-traced hard shadows, an unoccluded sky term
// and emission; no bounces). Orthographic camera looking straight down (-Y); image row 0 is the region's
// min-Z edge, column 0 its min-X edge.
#pragma once

#include "core/image.h"
#include "worlds/mesh.h"
#include "worlds/sky.h"
#include "worlds/triangle_bvh.h"

namespace lfgi::worlds {

struct TopDownOptions {
  int width = 768;  // pixels across X; height follows the region's aspect
  int threads = 0;  // 0: all cores
};

// Per pixel: the first surface below (from above the region's max Y), outgoing radiance (kcd/m^2 RGB)
// L = albedo / pi * (E_sun(n) * visible + E_sky_up * (1 + n.y) / 2) + emission, where E_sky_up is the
// sky's irradiance on an upward plane. Pixels that see nothing get the zenith sky radiance. Channels
// R, G, B. Throws lfgi::Error for an empty region or width outside [1, 8192].
Image renderTopDown(const TriangleMesh& mesh, const TriangleBvh& bvh, const SkyModel& sky, const Aabb& region,
                    const TopDownOptions& options = {});

// Irradiance of the sky (without discs) on an upward-facing plane, klx: integral over the upper
// hemisphere of L cos, by octahedral quadrature at resolution 64.
glm::vec3 skyIrradianceUp(const SkyModel& sky);

}  // namespace lfgi::worlds
