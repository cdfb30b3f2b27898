#include "worlds/topdown_preview.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <thread>

#include "core/error.h"
#include "core/octahedral.h"
#include "core/sh.h"

namespace lfgi::worlds {

glm::vec3 skyIrradianceUp(const SkyModel& sky) {
  const int n = 64;
  std::vector<float> map = skyOctahedralMap(sky, n, false);
  return bruteForceIrradiance(map, n, glm::vec3(0.0f, 1.0f, 0.0f));
}

Image renderTopDown(const TriangleMesh& mesh, const TriangleBvh& bvh, const SkyModel& sky, const Aabb& region,
                    const TopDownOptions& opt) {
  const glm::vec3 size = region.size();
  if (region.empty() || !(size.x > 0.0f) || !(size.z > 0.0f)) fail("top-down preview: empty region");
  if (opt.width < 1 || opt.width > 8192) fail("top-down preview: width {} outside [1, 8192]", opt.width);
  const int w = opt.width, h = std::max(1, int(std::lround(double(w) * size.z / size.x)));
  Image img(w, h, {"R", "G", "B"});
  const glm::vec3 skyUp = skyIrradianceUp(sky);
  const glm::vec3 zenith = skyRadiance(sky, glm::vec3(0.0f, 1.0f, 0.0f));
  const DiscLight& sun = sky.sun.elevationDeg > 0.0f ? sky.sun : sky.moon;
  const float top = region.max.y + 10.0f;
  auto shadeRows = [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        glm::vec3 o(region.min.x + (float(x) + 0.5f) * size.x / float(w), top,
                    region.min.z + (float(y) + 0.5f) * size.z / float(h));
        auto hit = bvh.intersect(o, glm::vec3(0.0f, -1.0f, 0.0f));
        glm::vec3 L = zenith;
        if (hit) {
          const Material& m = mesh.materials[mesh.triangleMaterial[hit->triangle]];
          glm::vec3 n = mesh.faceNormal(hit->triangle);
          if (glm::dot(n, glm::vec3(0.0f, 1.0f, 0.0f)) < 0.0f) n = -n;  // seen from above: face up
          glm::vec3 p = o + glm::vec3(0.0f, -hit->t, 0.0f) + n * 1e-3f;
          glm::vec3 direct = sun.irradiance(n);
          if (direct != glm::vec3(0.0f) && bvh.intersect(p, sun.direction)) direct = glm::vec3(0.0f);
          L = m.albedo / std::numbers::pi_v<float> * (direct + skyUp * (0.5f * (1.0f + n.y))) + m.emission;
        }
        for (int c = 0; c < 3; ++c) img.at(x, y, c) = L[c];
      }
  };
  const int threads = std::max(1, opt.threads > 0 ? opt.threads : int(std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(shadeRows, h * t / threads, h * (t + 1) / threads);
  for (auto& th : pool) th.join();
  return img;
}

}  // namespace lfgi::worlds
