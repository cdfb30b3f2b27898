#include "core/probe_field.h"

#include <cmath>

#include "core/error.h"

namespace lfgi {

void ProbeField::validate() const {
  grid.validate();
  if (resolution < 1 || resolution > 256) fail("ProbeField.resolution = {} outside [1, 256]", resolution);
  if (irradianceResolution < 1 || irradianceResolution > 256)
    fail("ProbeField.irradianceResolution = {} outside [1, 256]", irradianceResolution);
  const size_t P = size_t(probeCount()), n2 = size_t(resolution) * size_t(resolution),
               m2 = size_t(irradianceResolution) * size_t(irradianceResolution);
  auto check = [](const std::vector<float>& v, size_t want, const char* name, bool optional) {
    if (optional && v.empty()) return;
    if (v.size() != want)
      fail("ProbeField.{} holds {} floats, the grid and resolution need {}", name, v.size(), want);
    for (size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i])) fail("ProbeField.{}[{}] = {} is not finite", name, i, v[i]);
  };
  check(radiance, P * n2 * 3, "radiance", false);
  check(distance, P * n2 * 2, "distance", false);
  check(irradiance, P * m2 * 3, "irradiance", false);
  check(normal, P * n2 * 3, "normal", true);
  check(albedo, P * n2 * 3, "albedo", true);
  if (!offsets.empty() && offsets.size() != P)
    fail("ProbeField.offsets holds {} entries for {} probes", offsets.size(), P);
  if (!active.empty() && active.size() != P)
    fail("ProbeField.active holds {} entries for {} probes", active.size(), P);
}

size_t ProbeField::bytes() const {
  return sizeof(float) *
             (radiance.size() + distance.size() + irradiance.size() + normal.size() + albedo.size()) +
         sizeof(glm::vec3) * offsets.size() + active.size();
}

}  // namespace lfgi
