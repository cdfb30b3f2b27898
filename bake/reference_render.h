// Reference images: a path-traced pinhole view of an EmbreeScene under a SkyModel with exactly the
// capture's transport (bake/path_trace.h: the same materials, brdf.h, sun/moon NEE, sky on escape, depth
// and roulette rules, see probe_capture.h), split into layers so that shading from probes can be compared
// with the true indirect light.
//
// Camera: pinhole at `position` looking at `target`, up = +Y, verticalFovDeg over the image height, square
// pixels; pixel (x, y) (y = 0 the top row) covers [x, x+1) x [y, y+1) on the image plane. Each of the S
// samples per pixel jitters uniformly inside the pixel (box filter).
//
// Layers (Image channels, all radiance in the sky unit kcd/m^2, per-pixel means over the S samples):
//   direct.R/G/B            light with at most one reflection: emission of the first hit (or sky + sun/moon
//                           disc radiance when the primary ray escapes), sun/moon NEE at the first hit, and
//                           what the first bounce ray brings straight from the sky or from an emitter's
//                           surface (emission of the second hit). Furnace (emission E, albedo a): E + a E.
//   indirect_diffuse.R/G/B  everything else arriving at the first hit (NEE and emission at hits >= 2 and sky
//                           after >= 2 reflections; i.e. >= 2 reflections in all), weighted by the first
//                           bounce's diffuse lobe: w0_d = f_d cos / pdf with f_d = diffuseBrdf (brdf.h)
//   indirect_specular.R/G/B the same weighted by the specular lobe, w0_s = w0 - w0_d. Both parts use the
//                           same sampled direction and mixture pdf, so each is an unbiased estimate of its
//                           lobe's share; exactly 0 on Lambertian first hits.
//   R/G/B                   direct + indirect_diffuse + indirect_specular, summed in float from the stored
//                           layer values (so the layers add up to it exactly)
//   std_error.R/G/B         Monte-Carlo standard error of R/G/B (sample std / sqrt(S); 0 when S = 1)
// A pixel of a tile skipped by an interrupt stays 0 in every layer.
//
// Determinism: each sample's random numbers come from a counter-based hash of (seed, pixel, sample), so the
// image is bit-identical for any thread count and tile order. Threading: tbb::parallel_for over tiles
// (tileSize x tileSize pixels); the caller's tbb::global_control / task_arena limits it. Interrupts:
// InterruptGuard::interrupted() is polled before each tile; started tiles finish, the rest are skipped
// and the result says so.
#pragma once

#include <cstdint>

#include <glm/glm.hpp>

#include "bake/embree_scene.h"
#include "core/image.h"
#include "worlds/sky.h"

namespace lfgi::bake {

struct PinholeCamera {
  glm::vec3 position{0.0f, 1.7f, 0.0f};
  glm::vec3 target{0.0f, 1.7f, -1.0f};
  float verticalFovDeg = 60.0f;  // (0, 180)
};

struct RenderOptions {
  int width = 640;             // [1, 16384]
  int height = 360;            // [1, 16384]
  int samplesPerPixel = 64;    // [1, 65536]
  int maxBounces = 12;         // [0, 256], as CaptureOptions
  int rouletteAfter = 3;       // >= 1
  float maxDistance = 1.0e4f;  // m, > 0: ray length limit
  int tileSize = 16;           // [1, 1024]
  uint64_t seed = 1;
};

// Throws lfgi::Error naming the first bad field ("RenderOptions.width = 0 outside [1, 16384]").
void validateRenderOptions(const RenderOptions& options);
// Throws lfgi::Error unless position and target are finite and distinct, the view direction is not
// (anti)parallel to +Y, and the field of view lies in (0, 180) degrees.
void validateCamera(const PinholeCamera& camera);

// Unit direction of the camera ray through image-plane point (px, py) (pixels; (0.5, 0.5) is the centre of
// the top-left pixel) of a width x height image.
glm::vec3 cameraRayDirection(const PinholeCamera& camera, int width, int height, float px, float py);

struct RenderResult {
  Image image;  // the layers above
  size_t tiles = 0;
  size_t tilesDone = 0;
  bool interrupted = false;  // stopped early by InterruptGuard (tilesDone < tiles)
  uint64_t rays = 0;         // closest-hit + shadow rays
  double seconds = 0.0;
  double raysPerSecond() const { return seconds > 0.0 ? double(rays) / seconds : 0.0; }
};

// Renders the view; prints progress (tiles) to stderr when showProgress. Validates everything first.
RenderResult renderReference(const EmbreeScene& scene, const worlds::SkyModel& sky,
                             const PinholeCamera& camera, const RenderOptions& options,
                             bool showProgress = false);

}  // namespace lfgi::bake
