// Probe capture: the ground-truth light field at probe positions, by path tracing an EmbreeScene under
// a SkyModel. Per probe, octahedral maps (core/octahedral.h interior layout, texel (i, j) at j * n + i):
//   radiance        n x n x 3   incoming radiance (sky unit, kcd/m^2), the mean over the texel's solid angle
//   radianceStdError n x n x 3  Monte-Carlo standard error of that mean, per channel
//   distance        n x n x 2   mean r and r^2 of the first hit (misses count as maxDistance), for
//                               Chebyshev visibility (McGuire et al. 2017, "Real-Time Global Illumination
//                               using Precomputed Light Field Probes")
//   normal, albedo  n x n x 3   mean over the texel of the first hit's normal (the side the probe sees
//                               for double-sided materials, the raw front normal otherwise, so a back face
//                               shows as a normal pointing away) and albedo; misses give 0
//   irradiance      m x m x 3   E(normal = texel-centre direction), derived (see below)
//
// Texel estimate. Each texel gets S = samplesPerTexel primary directions, stratified over the texel's
// square in the octahedral (u, v) domain (k x k jittered strata, k = floor(sqrt(S)), the remaining
// S - k^2 samples uniform over the texel) and mapped to the sphere with octDecode. Every sample carries
// the Jacobian weight w = 1 / |p|^3 (p the point on the |x|+|y|+|z| = 1 octahedron, d omega = du dv / |p|^3),
// and each map holds the weighted mean sum(w f) / sum(w): a consistent estimate of the texel's
// solid-angle mean of f, exact for constant f. texelSample() exposes the exact directions and weights
// so tests can reproduce them. Standard error: delta method for a ratio estimator,
// sqrt(sum w^2 (f - mean)^2) / sum w (conservative: it ignores the variance reduction of stratification).
//
// Light transport (per primary sample, a path of diffuse bounces):
// - Surfaces: bake/brdf.h with the material's albedo (times its texture at the hit's uv), roughness and
//   metallic: exactly Lambertian for the default roughness 1 / metallic 0, else Lambertian + single-
//   scatter GGX. A single-sided material seen from the back is a black absorber (the inside of solid
//   geometry); double-sided ones shade either side. No transmission (glass is opaque).
// - Emission (Material::emission, same unit as the sky) is added at every hit of a front side (either
//   side when double-sided).
// - Sun and moon (SkyModel::sun / moon DiscLight) are handled only by next-event estimation: at each
//   surface vertex a shadow ray towards the disc centre (a directional light with the disc's energy,
//   DiscLight::irradiance(n), hard shadows). For the primary segment the disc's energy
//   (irradianceNormal()) goes, if the probe sees the disc centre, into the one texel containing the disc
//   direction as energy / Omega_texel (exact texel solid angle): that is the texel's true mean radiance for
//   a disc inside one texel (the 0.27 deg sun is ~40x smaller than a 16 x 16 texel).
// - Sky: a ray that escapes adds skyRadiance(sky, dir) only, never discRadiance(): every path to a disc
//   is already counted by NEE (or the primary deposit), so nothing is counted twice. No NEE for the sky.
// - Depth: emission is collected at hits 0..maxBounces (hit 0 = the first surface the probe sees) and NEE
//   at hits 0..maxBounces-1, so a furnace (closed, albedo a, emission E) converges to
//   E (1 - a^(maxBounces+1)) / (1 - a). Russian roulette from hit index `rouletteAfter` on, with survival
//   probability min(0.95, max component of the bounce weight f cos / pdf, i.e. the albedo for Lambertian)
//   (unbiased; roulette never makes a path's weight grow).
// Irradiance: the sky/emission/bounce part is bruteForceIrradiance (core/sh.h, exact texel solid angles)
// of the radiance map with the disc deposits removed, plus each disc's analytic irradiance(normal) if the
// probe sees it, so the sun's contribution carries no texel discretisation error.
//
// Determinism: every random number comes from a counter-based hash of (seed, the probe position's bits,
// texel, sample, dimension), so results are bit-identical for any thread count and do not depend on
// which list (cell) the probe was captured in.
//
// Threading: captureProbes runs tbb::parallel_for over probes and texel rows; the caller's
// tbb::global_control / task_arena limits it. It polls InterruptGuard::interrupted() (the caller installs
// the guard) before starting each probe: on Ctrl-C, started probes finish, the rest are skipped and
// returned as not done.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "bake/embree_scene.h"
#include "worlds/sky.h"

namespace lfgi::bake {

struct CaptureOptions {
  int resolution = 16;           // n: radiance, distance, normal, albedo maps, [1, 256]
  int irradianceResolution = 8;  // m: derived irradiance map, [1, 256]
  int samplesPerTexel = 64;      // S, [1, 65536]
  int maxBounces = 12;           // [0, 256]; see the depth rule above
  int rouletteAfter = 3;         // first hit index with Russian roulette, >= 1
  float maxDistance = 1.0e4f;    // m: distance recorded for a miss; also the ray length limit, > 0
  uint64_t seed = 1;
  // The discs the probe sees directly (the primary segment's deposit and analytic irradiance). false:
  // left out of radiance and irradiance, so the maps hold what shading reads from probes (the shading
  // pass adds the discs with shadow rays); the discs' light reflected by surfaces stays either way.
  bool primaryDiscs = true;
};

// Throws lfgi::Error naming the first bad field ("CaptureOptions.resolution = 0 outside [1, 256]").
void validateCaptureOptions(const CaptureOptions& options);

struct ProbeCapture {
  glm::vec3 position{0.0f};
  int resolution = 0;
  int irradianceResolution = 0;
  std::vector<float> radiance;          // n*n*3
  std::vector<float> radianceStdError;  // n*n*3
  std::vector<float> distance;          // n*n*2: mean r, mean r^2
  std::vector<float> normal;            // n*n*3
  std::vector<float> albedo;            // n*n*3
  std::vector<float> irradiance;        // m*m*3
  // Mean over texels with non-zero luminance of (std error of luminance) / luminance; 0 if none.
  double meanRelativeStdError = 0.0;
  uint64_t rays = 0;  // closest-hit + shadow rays traced for this probe

  // 64-bit FNV-1a of the resolutions, position and every map's bytes (not rays or the error summary):
  // equal hashes mean bit-identical maps (docs/DESIGN.md §2: determinism is hashed and tested).
  uint64_t contentHash() const;
};

struct CaptureResult {
  std::vector<ProbeCapture> probes;  // one per input position; only those with done[i] != 0 are filled
  std::vector<uint8_t> done;
  size_t probesDone = 0;
  bool interrupted = false;  // stopped early by InterruptGuard
  uint64_t rays = 0;
  double seconds = 0.0;
  double raysPerSecond() const { return seconds > 0.0 ? double(rays) / seconds : 0.0; }
};

// One probe (texel rows in parallel). Throws lfgi::Error for bad options or a non-finite position.
ProbeCapture captureProbe(const EmbreeScene& scene, const worlds::SkyModel& sky, glm::vec3 position,
                          const CaptureOptions& options);

// All probes, in parallel; prints progress to stderr when showProgress. Validates everything before
// tracing anything.
CaptureResult captureProbes(const EmbreeScene& scene, const worlds::SkyModel& sky,
                            std::span<const glm::vec3> positions, const CaptureOptions& options,
                            bool showProgress = false);

// Roughness-prefiltered radiance for specular lookups (the split-sum approximation, Karis 2013, "Real
// Shading in Unreal Engine 4": N = V = R): an outN x outN octahedral map whose texel with centre
// direction R holds sum_w L(w) K(R, w) Omega_w / sum_w K(R, w) Omega_w over the n x n interior radiance
// map, K = D_GGX(R . h) max(0, R . w), h = normalize(R + w), alpha = max(roughness^2, 1e-3) (brdf.h).
// Normalised, so a constant map stays exactly constant. O(outN^2 n^2). Throws lfgi::Error for
// radiance.size() != n*n*3, n or outN outside [1, 256], or roughness outside [0, 1] (NaN included).
std::vector<float> prefilterRadianceGgx(std::span<const float> radiance, int n, float roughness, int outN);

// The s-th primary sample (0 <= s < samplesPerTexel) of texel (i, j) of an n x n map for a probe at
// `position`: its unit direction and its Jacobian weight 1/|p|^3. This is exactly what the capture uses.
struct TexelSample {
  glm::vec3 direction{0.0f, 1.0f, 0.0f};
  double weight = 1.0;
};
TexelSample texelSample(int i, int j, int n, int s, int samplesPerTexel, uint64_t seed, glm::vec3 position);

}  // namespace lfgi::bake
