#include "core/probe_grid.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace lfgi {

void ProbeGrid::validate() const {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1) fail("ProbeGrid: dims ({}, {}, {}) must be >= 1 on every axis", dims.x, dims.y, dims.z);
    if (!(spacing[a] > 0.0f) || !std::isfinite(spacing[a]))
      fail("ProbeGrid: spacing ({}, {}, {}) must be finite and > 0", spacing.x, spacing.y, spacing.z);
    if (!std::isfinite(origin[a]))
      fail("ProbeGrid: origin ({}, {}, {}) is not finite", origin.x, origin.y, origin.z);
  }
  // Three int32 factors cannot overflow int64; the limit keeps float coordinates of probes exact.
  if (probeCount() > (std::int64_t(1) << 40))
    fail("ProbeGrid: {} probes is more than supported", probeCount());
}

glm::ivec3 ProbeGrid::probeCoord(std::int64_t index) const {
  const std::int64_t plane = std::int64_t(dims.x) * dims.y;
  const std::int64_t z = index / plane;
  const std::int64_t rest = index - z * plane;
  return {static_cast<int>(rest % dims.x), static_cast<int>(rest / dims.x), static_cast<int>(z)};
}

bool ProbeGrid::owns(glm::vec3 p) const {
  const glm::vec3 hi = boxMax();
  return p.x >= origin.x && p.y >= origin.y && p.z >= origin.z && p.x < hi.x && p.y < hi.y && p.z < hi.z;
}

TrilinearProbes ProbeGrid::trilinear(glm::vec3 p) const {
  TrilinearProbes out;
  glm::vec3 frac(0.0f);
  for (int a = 0; a < 3; ++a) {
    const int last = dims[a] - 1;
    const float local = std::clamp((p[a] - origin[a]) / spacing[a], 0.0f, float(last));
    // The base stops one short of the last probe so the far corner exists; the last probe itself is
    // then reached with frac = 1.
    const int b = std::min(static_cast<int>(std::floor(local)), std::max(last - 1, 0));
    out.base[a] = b;
    frac[a] = last == 0 ? 0.0f : std::clamp(local - float(b), 0.0f, 1.0f);
  }
  for (int k = 0; k < 8; ++k) {
    const glm::ivec3 step((k & 1), (k >> 1) & 1, (k >> 2) & 1);
    out.corners[k] = glm::min(out.base + step, dims - 1);
    out.indices[k] = linearIndex(out.corners[k]);
    const glm::vec3 w = glm::mix(glm::vec3(1.0f) - frac, frac, glm::vec3(step));
    out.weights[k] = w.x * w.y * w.z;
  }
  return out;
}

}  // namespace lfgi
