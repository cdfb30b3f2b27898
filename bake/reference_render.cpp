#include "bake/reference_render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>

#include "bake/parallel_work.h"
#include "bake/path_trace.h"
#include "bake/tiled_render.h"
#include "core/error.h"

namespace lfgi::bake {
namespace {

bool finite(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Layer order in the image; keep in sync with the header.
constexpr int kTotal = 0, kDirect = 3, kIndirectDiffuse = 6, kIndirectSpecular = 9, kStdError = 12;

void renderTile(const EmbreeScene& scene, const worlds::SkyModel& sky, const detail::Discs& discs,
                const PinholeCamera& camera, const RenderOptions& o, const detail::PathOptions& po,
                uint64_t key, int x0, int y0, Image& image, uint64_t& rays) {
  const int x1 = std::min(x0 + o.tileSize, o.width);
  const int y1 = std::min(y0 + o.tileSize, o.height);
  const int S = o.samplesPerPixel;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const int pixel = y * o.width + x;
      double sum[3][3] = {}, total[3] = {}, total2[3] = {};
      for (int s = 0; s < S; ++s) {
        detail::PathRng rng(key, pixel, s);
        const float jx = rng.nextFloat();
        const float jy = rng.nextFloat();
        const glm::vec3 dir = cameraRayDirection(camera, o.width, o.height, float(x) + jx, float(y) + jy);
        detail::FirstHit first;
        detail::PathSplit split;
        const glm::vec3 L =
            detail::tracePath(scene, sky, discs, po, camera.position, dir, rng, first, rays, &split);
        for (int ch = 0; ch < 3; ++ch) {
          sum[0][ch] += split.direct[ch];
          sum[1][ch] += split.indirectDiffuse[ch];
          sum[2][ch] += split.indirectSpecular[ch];
          total[ch] += L[ch];
          total2[ch] += double(L[ch]) * double(L[ch]);
        }
      }
      std::span<float> px = image.pixel(x, y);
      for (int ch = 0; ch < 3; ++ch) {
        const float d = float(sum[0][ch] / S);
        const float id = float(sum[1][ch] / S);
        const float is = float(sum[2][ch] / S);
        px[size_t(kDirect + ch)] = d;
        px[size_t(kIndirectDiffuse + ch)] = id;
        px[size_t(kIndirectSpecular + ch)] = is;
        px[size_t(kTotal + ch)] = d + id + is;
        const double mean = total[ch] / S;
        const double var = S > 1 ? std::max(0.0, (total2[ch] - S * mean * mean) / double(S - 1)) : 0.0;
        px[size_t(kStdError + ch)] = float(std::sqrt(var / S));
      }
    }
  }
}

}  // namespace

void validateRenderOptions(const RenderOptions& o) {
  auto range = [](const char* name, int v, int lo, int hi) {
    if (v < lo || v > hi) fail("RenderOptions.{} = {} outside [{}, {}]", name, v, lo, hi);
  };
  range("width", o.width, 1, 16384);
  range("height", o.height, 1, 16384);
  range("samplesPerPixel", o.samplesPerPixel, 1, 65536);
  range("maxBounces", o.maxBounces, 0, 256);
  range("rouletteAfter", o.rouletteAfter, 1, 1 << 20);
  range("tileSize", o.tileSize, 1, 1024);
  if (!(std::isfinite(o.maxDistance) && o.maxDistance > 0.0f))
    fail("RenderOptions.maxDistance = {} must be finite and > 0", o.maxDistance);
}

void validateCamera(const PinholeCamera& c) {
  if (!finite(c.position) || !finite(c.target))
    fail("camera: position ({}, {}, {}) or target ({}, {}, {}) is not finite", c.position.x, c.position.y,
         c.position.z, c.target.x, c.target.y, c.target.z);
  const glm::vec3 d = c.target - c.position;
  const float len = glm::length(d);
  if (!(len > 0.0f))
    fail("camera: target equals position ({}, {}, {})", c.position.x, c.position.y, c.position.z);
  if (std::abs(d.y) / len > 0.99999f)
    fail("camera: view direction ({}, {}, {}) is parallel to up (+Y); tilt the target off the vertical", d.x,
         d.y, d.z);
  if (!(c.verticalFovDeg > 0.0f && c.verticalFovDeg < 180.0f))
    fail("camera: vertical field of view {} deg outside (0, 180)", c.verticalFovDeg);
}

glm::vec3 cameraRayDirection(const PinholeCamera& camera, int width, int height, float px, float py) {
  const glm::vec3 forward = glm::normalize(camera.target - camera.position);
  const glm::vec3 right = glm::normalize(glm::cross(forward, glm::vec3(0.0f, 1.0f, 0.0f)));
  const glm::vec3 up = glm::cross(right, forward);
  const float tanHalf = std::tan(0.5f * camera.verticalFovDeg * std::numbers::pi_v<float> / 180.0f);
  const float sx = (2.0f * px / float(width) - 1.0f) * tanHalf * float(width) / float(height);
  const float sy = (1.0f - 2.0f * py / float(height)) * tanHalf;
  return glm::normalize(forward + sx * right + sy * up);
}

namespace detail {

RenderResult renderTiled(const worlds::SkyModel& sky, const PinholeCamera& camera, const RenderOptions& o,
                         std::vector<std::string> layers, bool showProgress,
                         const std::function<void(const TileJob& job, Image& image, uint64_t& rays)>& tile) {
  validateRenderOptions(o);
  validateCamera(camera);
  const auto start = std::chrono::steady_clock::now();
  RenderResult result;
  result.image = Image(o.width, o.height, std::move(layers));
  const int tilesX = (o.width + o.tileSize - 1) / o.tileSize;
  const int tilesY = (o.height + o.tileSize - 1) / o.tileSize;
  result.tiles = size_t(tilesX) * size_t(tilesY);
  PathOptions po;
  po.maxBounces = o.maxBounces;
  po.rouletteAfter = o.rouletteAfter;
  po.maxDistance = o.maxDistance;
  po.discsOnPrimaryMiss = true;
  const Discs discs = activeDiscs(sky);
  const uint64_t key = splitmix64Finalize(o.seed ^ 0x6c666769'63616d65ULL);

  std::atomic<uint64_t> rays{0};
  const ParallelWorkResult run =
      runParallelInterruptible(result.tiles, "reference", "tiles", showProgress, [&](size_t t) {
        uint64_t localRays = 0;
        const int x0 = int(t % size_t(tilesX)) * o.tileSize, y0 = int(t / size_t(tilesX)) * o.tileSize;
        const TileJob job{
            po, discs, key, x0, y0, std::min(x0 + o.tileSize, o.width), std::min(y0 + o.tileSize, o.height)};
        tile(job, result.image, localRays);
        rays.fetch_add(localRays, std::memory_order_relaxed);
      });
  result.tilesDone = run.done;
  result.interrupted = run.interrupted;
  result.rays = rays.load();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace detail

RenderResult renderReference(const EmbreeScene& scene, const worlds::SkyModel& sky,
                             const PinholeCamera& camera, const RenderOptions& o, bool showProgress) {
  return detail::renderTiled(
      sky, camera, o,
      {"R", "G", "B", "direct.R", "direct.G", "direct.B", "indirect_diffuse.R", "indirect_diffuse.G",
       "indirect_diffuse.B", "indirect_specular.R", "indirect_specular.G", "indirect_specular.B",
       "std_error.R", "std_error.G", "std_error.B"},
      showProgress, [&](const detail::TileJob& job, Image& image, uint64_t& rays) {
        renderTile(scene, sky, job.discs, camera, o, job.path, job.key, job.x0, job.y0, image, rays);
      });
}

}  // namespace lfgi::bake
