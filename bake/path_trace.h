// Internal to bake/: the path tracer shared by probe capture (probe_capture.h) and reference images
// (reference_render.h), so both see exactly the same materials, lights and transport. Not a public API:
// the rules (NEE for the discs, sky only on escape, depth, roulette, ray offsets) are documented at the
// top of probe_capture.h; the direct / indirect split is documented in reference_render.h.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include "bake/embree_scene.h"
#include "core/hash.h"
#include "worlds/sky.h"

namespace lfgi::bake::detail {

// Random numbers of one path: element `counter` of the stream keyed by (key, index, sample), independent
// of thread and order.
class PathRng {
 public:
  PathRng(uint64_t key, int index, int sample)
      : key_(splitmix64Finalize(key ^
                                splitmix64Finalize((uint64_t(uint32_t(index)) << 32) | uint32_t(sample)))) {}
  double nextDouble() { return double(next() >> 11) * 0x1.0p-53; }
  float nextFloat() { return float(next() >> 40) * 0x1.0p-24f; }

 private:
  uint64_t next() { return splitmix64Finalize(key_ + (++counter_) * kGoldenGamma); }
  uint64_t key_;
  uint64_t counter_ = 0;
};

// Surface-hit helpers shared by the path tracer and the shading references (bake/shading_inputs.cpp).
float maxComponent(glm::vec3 c);
// The material's albedo times its texture at the hit's uv.
glm::vec3 hitAlbedo(const worlds::TriangleMesh& mesh, const worlds::Material& m, const RayHit& hit);
// The hit point from the triangle's vertices and barycentrics (more accurate than origin + t dir far
// from the origin).
glm::vec3 hitPoint(const worlds::TriangleMesh& mesh, const RayHit& hit);
// Secondary ray origin pushed off the surface by float ulps (Waechter & Binder 2019, Ray Tracing Gems
// ch. 6); see path_trace.cpp.
glm::vec3 offsetRayOrigin(glm::vec3 p, glm::vec3 n);

struct PathOptions {
  int maxBounces = 12;
  int rouletteAfter = 3;
  float maxDistance = 1.0e4f;
  // A primary ray that escapes also adds discRadiance (the camera sees the sun disc); the capture
  // deposits the discs itself and leaves this off.
  bool discsOnPrimaryMiss = false;
};

// The sun and moon discs with non-zero energy.
struct Discs {
  const worlds::DiscLight* light[2];
  int count = 0;
};
Discs activeDiscs(const worlds::SkyModel& sky);

struct FirstHit {
  float r = 0.0f;
  glm::vec3 normal{0.0f};
  glm::vec3 albedo{0.0f};
};

// The path's radiance split by what reached the first hit (reference_render.h): direct + the two
// indirect parts equal the returned total up to float rounding.
struct PathSplit {
  glm::vec3 direct{0.0f};
  glm::vec3 indirectDiffuse{0.0f};
  glm::vec3 indirectSpecular{0.0f};
};

// One path from origin along unit dir; returns its radiance estimate. first receives the first hit
// (r = maxDistance and zeros on a miss); rays counts closest-hit and shadow rays; split, if not null,
// receives the split (costs a few vector operations per vertex; the total is computed identically).
glm::vec3 tracePath(const EmbreeScene& scene, const worlds::SkyModel& sky, const Discs& discs,
                    const PathOptions& o, glm::vec3 origin, glm::vec3 dir, PathRng& rng, FirstHit& first,
                    uint64_t& rays, PathSplit* split = nullptr);

}  // namespace lfgi::bake::detail
