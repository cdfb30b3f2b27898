#include "bake/shading_inputs.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>

#include "bake/brdf.h"
#include "bake/parallel_work.h"
#include "bake/path_trace.h"
#include "bake/tiled_render.h"
#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi::bake {
namespace {

constexpr float kInvPi = float(1.0 / std::numbers::pi);

using detail::hitAlbedo;
using detail::hitPoint;
using detail::maxComponent;
using detail::offsetRayOrigin;

// Emission + disc NEE at the first hit (or sky + discs on a miss): the part of tracePath's total that
// shading computes without probes.
glm::vec3 directAtFirstHit(const EmbreeScene& scene, const worlds::SkyModel& sky, const detail::Discs& discs,
                           const detail::PathOptions& o, glm::vec3 origin, glm::vec3 dir, uint64_t& rays) {
  const worlds::TriangleMesh& mesh = scene.mesh();
  const std::optional<RayHit> hit = scene.intersect(origin, dir, 0.0f, o.maxDistance);
  ++rays;
  if (!hit) return worlds::skyRadiance(sky, dir) + worlds::discRadiance(sky, dir);
  const worlds::Material& m = mesh.materials[mesh.triangleMaterial[hit->triangle]];
  if (hit->backface && !m.doubleSided) return glm::vec3(0.0f);
  glm::vec3 L = m.emission;
  if (o.maxBounces <= 0) return L;
  const glm::vec3 n = hit->backface ? -hit->normal : hit->normal;
  const glm::vec3 albedo = hitAlbedo(mesh, m, *hit);
  const SurfaceBrdf brdf{albedo, m.roughness, m.metallic};
  const glm::vec3 po = offsetRayOrigin(hitPoint(mesh, *hit), n);
  for (int d = 0; d < discs.count; ++d) {
    const worlds::DiscLight& l = *discs.light[d];
    if (glm::dot(n, l.direction) <= 0.0f) continue;
    const glm::vec3 f = brdf.isLambertian() ? albedo * kInvPi : evalBrdf(brdf, n, -dir, l.direction);
    if (!(maxComponent(f) > 0.0f)) continue;
    ++rays;
    if (!scene.occluded(po, l.direction, 0.0f, o.maxDistance)) L += f * l.irradiance(n);
  }
  return L;
}

}  // namespace

ProbeField probeFieldFromCapture(const ProbeGrid& grid, const CaptureResult& r,
                                 std::span<const int64_t> gridIndex) {
  grid.validate();
  if (gridIndex.size() != r.probes.size())
    fail("probe field from capture: {} grid indices for {} captured probes", gridIndex.size(),
         r.probes.size());
  ProbeField f;
  f.grid = grid;
  const int64_t count = grid.probeCount();
  int n = 0, m = 0;
  for (size_t k = 0; k < r.probes.size(); ++k) {
    if (k < r.done.size() && !r.done[k]) continue;
    if (n == 0) {
      n = r.probes[k].resolution;
      m = r.probes[k].irradianceResolution;
    } else if (r.probes[k].resolution != n || r.probes[k].irradianceResolution != m) {
      fail("probe field from capture: probe {} has resolutions {}/{}, others {}/{}", k,
           r.probes[k].resolution, r.probes[k].irradianceResolution, n, m);
    }
  }
  if (n == 0) fail("probe field from capture: no captured probe");
  f.resolution = n;
  f.irradianceResolution = m;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  f.offsets.assign(size_t(count), glm::vec3(0.0f));
  f.active.assign(size_t(count), 0);
  f.radiance.assign(size_t(count) * n2 * 3, 0.0f);
  f.distance.assign(size_t(count) * n2 * 2, 0.0f);
  f.irradiance.assign(size_t(count) * m2 * 3, 0.0f);
  f.normal.assign(size_t(count) * n2 * 3, 0.0f);
  f.albedo.assign(size_t(count) * n2 * 3, 0.0f);
  for (size_t k = 0; k < r.probes.size(); ++k) {
    if (k < r.done.size() && !r.done[k]) continue;
    const int64_t i = gridIndex[k];
    if (i < 0 || i >= count) fail("probe field from capture: grid index {} outside [0, {})", i, count);
    const ProbeCapture& c = r.probes[k];
    f.active[size_t(i)] = 1;
    f.offsets[size_t(i)] = c.position - grid.probePosition(grid.probeCoord(i));
    std::copy(c.radiance.begin(), c.radiance.end(), f.radiance.begin() + std::ptrdiff_t(size_t(i) * n2 * 3));
    std::copy(c.distance.begin(), c.distance.end(), f.distance.begin() + std::ptrdiff_t(size_t(i) * n2 * 2));
    std::copy(c.irradiance.begin(), c.irradiance.end(),
              f.irradiance.begin() + std::ptrdiff_t(size_t(i) * m2 * 3));
    std::copy(c.normal.begin(), c.normal.end(), f.normal.begin() + std::ptrdiff_t(size_t(i) * n2 * 3));
    std::copy(c.albedo.begin(), c.albedo.end(), f.albedo.begin() + std::ptrdiff_t(size_t(i) * n2 * 3));
  }
  f.validate();
  return f;
}

ShL1 fieldFallback(const ProbeField& field) {
  field.validate();
  const int n = field.resolution;
  const size_t n2 = size_t(n) * size_t(n);
  const std::shared_ptr<const std::vector<double>> weights = shTexelWeights(n);
  glm::dvec3 sum[4] = {};
  int64_t count = 0;
  for (int64_t i = 0; i < field.probeCount(); ++i) {
    if (!field.isActive(i)) continue;
    const ShL1 sh =
        shProject<4>(std::span<const float>(field.radiance).subspan(size_t(i) * n2 * 3, n2 * 3), n, *weights);
    for (int k = 0; k < 4; ++k) sum[k] += glm::dvec3(sh.c[size_t(k)]);
    ++count;
  }
  if (count == 0) fail("fieldFallback: the field has no active probe");
  ShL1 out;
  for (int k = 0; k < 4; ++k) out.c[size_t(k)] = glm::vec3(sum[k] / double(count));
  return out;
}

std::vector<uint8_t> fallbackProbeMask(const ProbeGrid& grid, std::span<const uint8_t> disabled,
                                       int columns) {
  grid.validate();
  if (columns < 1) fail("fallbackProbeMask: {} columns, expected >= 1", columns);
  if (!disabled.empty() && disabled.size() != size_t(grid.probeCount()))
    fail("fallbackProbeMask: {} flags for {} probes", disabled.size(), grid.probeCount());
  auto pick = [&](int dims) {
    std::vector<int> at;
    const int k = std::min(columns, dims);
    for (int c = 0; c < k; ++c) at.push_back(int((float(c) + 0.5f) * float(dims) / float(k)));
    return at;
  };
  std::vector<uint8_t> mask(size_t(grid.probeCount()), 0);
  for (int z : pick(grid.dims.z))
    for (int x : pick(grid.dims.x))
      for (int y = 0; y < grid.dims.y; ++y) {
        const size_t i = size_t(grid.linearIndex({x, y, z}));
        mask[i] = disabled.empty() || disabled[i] == 0;
      }
  return mask;
}

std::vector<float> prefilterSpecularLevels(const ProbeField& field, int levels) {
  if (levels < 1 || levels > 16) fail("prefilterSpecularLevels: {} levels outside [1, 16]", levels);
  const int n = field.resolution;
  const size_t n2 = size_t(n) * size_t(n);
  const int64_t count = field.probeCount();
  std::vector<float> out(size_t(count) * size_t(levels) * n2 * 3, 0.0f);
  detail::runParallelInterruptible(size_t(count), "prefilter", "probes", false, [&](size_t i) {
    if (!field.isActive(int64_t(i))) return;
    std::span<const float> rad(field.radiance.data() + i * n2 * 3, n2 * 3);
    for (int l = 0; l < levels; ++l) {
      const float roughness = levels == 1 ? 0.0f : float(l) / float(levels - 1);
      const std::vector<float> p = prefilterRadianceGgx(rad, n, roughness, n);
      std::copy(p.begin(), p.end(), out.begin() + std::ptrdiff_t((i * size_t(levels) + size_t(l)) * n2 * 3));
    }
  });
  return out;
}

RenderResult renderShadingReference(const EmbreeScene& scene, const worlds::SkyModel& sky,
                                    const PinholeCamera& camera, const RenderOptions& o, bool showProgress) {
  // detail::renderTiled uses renderReference's random key, so the totals agree sample for sample.
  return detail::renderTiled(
      sky, camera, o,
      {"R", "G", "B", "direct.R", "direct.G", "direct.B", "indirect.R", "indirect.G", "indirect.B"},
      showProgress, [&](const detail::TileJob& job, Image& image, uint64_t& localRays) {
        for (int y = job.y0; y < job.y1; ++y) {
          for (int x = job.x0; x < job.x1; ++x) {
            const int pixel = y * o.width + x;
            glm::dvec3 total(0.0), direct(0.0);
            for (int s = 0; s < o.samplesPerPixel; ++s) {
              detail::PathRng rng(job.key, pixel, s);
              const float jx = rng.nextFloat();
              const float jy = rng.nextFloat();
              const glm::vec3 dir =
                  cameraRayDirection(camera, o.width, o.height, float(x) + jx, float(y) + jy);
              detail::FirstHit first;
              total += glm::dvec3(detail::tracePath(scene, sky, job.discs, job.path, camera.position, dir,
                                                    rng, first, localRays));
              direct += glm::dvec3(
                  directAtFirstHit(scene, sky, job.discs, job.path, camera.position, dir, localRays));
            }
            std::span<float> px = image.pixel(x, y);
            for (int ch = 0; ch < 3; ++ch) {
              const float tot = float(total[ch] / o.samplesPerPixel);
              const float dir = float(direct[ch] / o.samplesPerPixel);
              px[size_t(ch)] = tot;
              px[size_t(3 + ch)] = dir;
              px[size_t(6 + ch)] = tot - dir;
            }
          }
        }
      });
}

}  // namespace lfgi::bake

namespace lfgi::bake {

ProbeField captureGridField(const EmbreeScene& scene, const worlds::SkyModel& sky, const ProbeGrid& grid,
                            std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                            const CaptureOptions& options, bool showProgress) {
  grid.validate();
  const int64_t count = grid.probeCount();
  if ((!offsets.empty() && offsets.size() != size_t(count)) ||
      (!active.empty() && active.size() != size_t(count)))
    fail("captureGridField: {} offsets / {} active flags for {} probes", offsets.size(), active.size(),
         count);
  std::vector<glm::vec3> positions;
  std::vector<int64_t> index;
  for (int64_t i = 0; i < count; ++i) {
    if (!active.empty() && !active[size_t(i)]) continue;
    positions.push_back(grid.probePosition(grid.probeCoord(i)) +
                        (offsets.empty() ? glm::vec3(0.0f) : offsets[size_t(i)]));
    index.push_back(i);
  }
  const CaptureResult r = captureProbes(scene, sky, positions, options, showProgress);
  if (r.interrupted) fail("capture interrupted");
  ProbeField f = probeFieldFromCapture(grid, r, index);
  subtractDiscLight(f, scene, sky, options.maxDistance);
  return f;
}

void subtractDiscLight(ProbeField& f, const EmbreeScene& scene, const worlds::SkyModel& sky,
                       float maxDistance) {
  const detail::Discs discs = detail::activeDiscs(sky);
  if (discs.count == 0) return;
  const int n = f.resolution, m = f.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  const std::vector<double> omega = octTexelSolidAngles(n);
  for (int64_t i = 0; i < f.probeCount(); ++i) {
    if (!f.isActive(i)) continue;
    for (int d = 0; d < discs.count; ++d) {
      const worlds::DiscLight& l = *discs.light[d];
      if (scene.occluded(f.probePosition(i), l.direction, 0.0f, maxDistance)) continue;
      const glm::ivec2 tx = octDirectionTexel(l.direction, n);
      const size_t t = size_t(tx.y) * size_t(n) + size_t(tx.x);
      const glm::vec3 add = l.irradianceNormal() / float(omega[t]);
      float* rad = f.radiance.data() + (size_t(i) * n2 + t) * 3;
      for (int ch = 0; ch < 3; ++ch) rad[ch] = std::max(0.0f, rad[ch] - add[ch]);
      for (int j = 0; j < m; ++j)
        for (int k = 0; k < m; ++k) {
          const glm::vec3 e = l.irradiance(octTexelDirection(k, j, m));
          float* irr = f.irradiance.data() + (size_t(i) * m2 + size_t(j) * size_t(m) + size_t(k)) * 3;
          for (int ch = 0; ch < 3; ++ch) irr[ch] = std::max(0.0f, irr[ch] - e[ch]);
        }
    }
  }
}

}  // namespace lfgi::bake
