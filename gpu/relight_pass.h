// GPU pass: relight a cell's surfels for the current sun/sky/weather and emissives, DDGI-style (Majercik
// et al. 2019): each frame lights every surfel from
//   - the key disc (the sun; the moon when it is brighter, i.e. at night), shadowed by a shadow map that
//     is built by the same VIR splat as the probes, from the light's direction (orthographic depth map
//     over the cell's surfels, 64-bit atomicMin, shaders/relight_shadow_splat.comp; single-tap depth
//     compare with bias = biasConstant + biasSlope x texel x tan(theta), relight_surfels.comp),
//   - last frame's probe irradiance (trilinear over the probe grid, DDGI backface and Chebyshev weights
//     from the VIR distance moments): the sky as the probes see it (occluded), plus every bounce so far.
//     There is no separate unoccluded sky term: a probe texel no surfel covered sees the sky, so sky
//     light reaches surfels one frame late and occluded by what the probes see.
//   - emitter next-event estimation (options.emitterNee, when some surfel emits): direct light from the
//     emissive surfels (the Cornell lamp, lit windows). Emitters are grouped into at most
//     maxEmitterClusters clusters (a uniform grid over their bounds x the 6 dominant normal directions,
//     coarsened until few enough; never fewer than the normal directions present); each
//     cluster gets one octahedral depth map VIR-splatted from its centre (VirPass::run with the cluster
//     centre as the only probe: an omnidirectional shadow map, hard shadows from the centre point), and
//     at most maxEmitterSamples emitter surfels in all (every k-th of a cluster, its area scaled up) are
//     summed per receiving surfel (relight_surfels.comp). The probes' own view of the emitters stays
//     VIR's (texels that see an emitter surfel), but the gather then reads maps without emission
//     (CellLighting::reflected) so the emitters' direct light reaches surfels once.
// then VirPass::run re-splats with that irradiance (radiance = emission + albedo E / pi; from the second
// frame on with unchanged surfels and probes it keeps the last splat's winners and only resolves again,
// VirOptions::reuseSplat) and convolve()
// turns the new radiance maps into the probe irradiance + distance moments of the next frame. Multi-
// bounce therefore converges over frames: after k frames a closed furnace holds
// pi Le (1 - a^k) / (1 - a) (gpu/relight_pass_test.cpp).
// The other disc (moon by day, sun by night) is left out: it is < 1e-5 of the key disc whenever it is
// above the horizon. Geometry outside the surfel list (neighbour cells) casts no shadow.
//
// Threading: a RelightPass uses its Context from the calling thread only; one thread at a time (the
// streaming manager's render/GPU thread) calls relight()/convolve()/relightFrame(), once per frame per
// resident cell. CellLighting is the per-cell state the caller keeps between frames; passes hold none.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

#include "core/probe_grid.h"
#include "gpu/buffer.h"
#include "gpu/program.h"
#include "gpu/vir_pass.h"
#include "shared/relight.h"
#include "shared/sky.h"
#include "shared/surfel.h"

namespace lfgi::gpu {

// The cell's probes as the relight pass reads them: a regular grid (core/probe_grid.h index order) whose
// probe i actually sits at positions[i] (after relocation) and is used only where active[i] != 0.
struct RelightProbes {
  ProbeGrid grid;
  std::vector<glm::vec3> positions;  // grid.probeCount() entries
  std::vector<uint8_t> active;       // empty: every probe active
};

struct RelightOptions {
  int shadowResolution = 0;           // shadow map texels per side, [16, 4096]; 0: texel = 0.75 x mean surfel
                                      // radius, clamped to [64, 2048] texels
  float shadowFootprintScale = 1.3f;  // disc radius multiplier of the shadow splat (as VirOptions)
  int shadowMaxFootprintRadius = 16;  // shadow splat window half-size (texels), [0, 64]
  float shadowBiasConstant = 0.02f;   // m
  // texels x tan(theta): a plane's depth changes by at most sqrt(2) / 2 texel x tan(theta) between the texel
  // centre and a point of the texel, so 0.75 covers the receiver's own surface; more lets a surface within
  // that depth below an occluder through (the leak scene's wall tops under a 0.25 m roof at 0.43 m texels:
  // sealed-room leak 1.5 % at 1.5, 0.07 % at 0.75; bake/probe_leak_test.cpp)
  float shadowBiasSlope = 0.75f;
  int irradianceResolution = 8;  // M of the probe irradiance maps, [1, 64]
  float normalBias = -1.0f;      // m, Chebyshev test point offset along the normal; < 0: 0.2 x min spacing
  float missDistance = 1.0e4f;   // m, distance moment of a probe texel that sees the sky
  bool sun = true;               // key disc with the shadow map
  bool bounce = true;            // last frame's probe irradiance
  bool chebyshev = true;         // Chebyshev visibility weights
  bool skyInProbes = true;       // probe texels no surfel covered see the sky
  // ... and so do texels only the VIR hole fill covered (relight_probe_irradiance.comp). false (default):
  // the fill closes only enclosed gaps (vir_holefill.comp), so a filled gap is geometry. true: filled
  // texels see the sky.
  bool filledTexelsSeeSky = false;
  bool emitterNee = true;            // emitter next-event estimation (see the top of this file)
  int maxEmitterClusters = 16;       // [1, 256] (exceeded only by the count of distinct normal directions)
  int maxEmitterSamples = 256;       // [1, 65536] over all clusters
  int emitterShadowResolution = 32;  // octahedral depth map per cluster, [4, 256]
  float emitterBiasSlope = 1.5f;     // depth bias in texel angles x distance (>= 0)
};

// How the probe convolution treats uncovered texels (LFGI_RELIGHT_SKY, LFGI_RELIGHT_FILLED_SKY of
// RelightOptions::skyInProbes / filledTexelsSeeSky): the flags for shared::relightTexelSeesSky.
uint32_t probeSkyFlags(const RelightOptions& options);

// Per-probe maps derived from one VIR atlas: the next frame's relight input.
struct ProbeLighting {
  int irradianceResolution = 0;  // M
  int distanceResolution = 0;    // N (the VIR resolution)
  int probeCount = 0;
  std::vector<glm::vec4> irradiance;  // probeCount * M^2: rgb E(normal = texel centre), without the discs
  std::vector<glm::vec2> moments;     // probeCount * N^2: 3 x 3 filtered (r, r^2), sky = missDistance
  double gpuMs = 0.0;
};

struct RelightResult {
  std::vector<glm::vec4> irradiance;  // per surfel: rgb E (kilolux), w: key-light visibility (0 or 1)
  int shadowResolution = 0;
  float shadowTexelM = 0.0f;
  glm::vec3 keyDirection{0.0f};                 // towards the shadowed disc; 0 when neither disc is up
  int emitterClusters = 0, emitterSamples = 0;  // emitter NEE (0: none)
  double shadowMs = 0.0, lightMs = 0.0;
  double emitterShadowMs = 0.0;  // VIR splat of the clusters' depth maps
};

// With emitter NEE: a probe texel whose nearest surface in the emitters-only splat is an emitter (texel
// index into the atlas, that distance, the emitted radiance).
struct EmitterTexel {
  uint32_t texel = 0;
  float distance = 0.0f;
  glm::vec3 radiance{0.0f};
};

// Everything a cell keeps between frames.
struct CellLighting {
  ProbeAtlas atlas;         // last VIR atlas (radiance holds the last relit radiance)
  ProbeLighting probes;     // derived from atlas
  ProbeLighting reflected;  // with emitter NEE: the same maps without emission (the gather's
                            // input); empty when no surfel emits or NEE is off
  std::vector<glm::vec4> surfelIrradiance;
  int frames = 0;
  // The emitters-only splat's texels (see relightFrame), kept while the emitter surfels, probe positions
  // and splat options stay the same (and VirOptions::reuseSplat is on): the emitters-only VIR run and its
  // readback then happen once per cell, not once per frame.
  std::vector<EmitterTexel> emitterTexels;
  std::vector<shared::Surfel> emitterSurfels;
  std::vector<glm::vec3> emitterProbes;
  VirOptions emitterOptions;
  bool emitterTexelsValid = false;
};

class RelightPass {
 public:
  // Throws lfgi::Error if the device lacks 64-bit buffer atomics.
  explicit RelightPass(Context& ctx);

  // Lights every surfel (see the top of this file). previous: last frame's probe lighting, or null /
  // empty for none (frame 0: key disc and nothing else). Throws lfgi::Error on empty surfels, a probe
  // list that does not match probes.grid, bad options, or previous maps of the wrong size.
  RelightResult relight(std::span<const shared::Surfel> surfels, const RelightProbes& probes,
                        const shared::SkyParams& sky, const ProbeLighting* previous,
                        const RelightOptions& options);

  // Probe irradiance (exact cosine convolution of the atlas' radiance, sky in uncovered texels) and
  // filtered distance moments, on the GPU. The moments depend only on the atlas' distance and coverage:
  // given sameGeometry (the convolution of an atlas with the same distance and normal maps, e.g. the
  // emission-free atlas of the same splat), its moments are copied instead of computed. Throws
  // lfgi::Error on an empty or inconsistent atlas, or a sameGeometry of another size.
  ProbeLighting convolve(const ProbeAtlas& atlas, const shared::SkyParams& sky, const RelightOptions& options,
                         const ProbeLighting* sameGeometry = nullptr);

  // GGX-prefiltered radiance (split sum, N = V = R) of probeCount N x N radiance maps (rgb used) into
  // outN x outN maps: the GPU version of bake::prefilterRadianceGgx (same normalised kernel, exact texel
  // solid angles; shaders/relight_prefilter_ggx.comp). Throws lfgi::Error for sizes outside [1, 256],
  // roughness outside [0, 1] or a radiance count != probeCount N^2. gpuMs, if given, gets the device time.
  std::vector<glm::vec4> prefilterGgx(std::span<const glm::vec4> radiance, int n, int probeCount,
                                      float roughness, int outN, double* gpuMs = nullptr);

  // The VirPass relightFrame splats the emitters alone with (NEE): its own, so that the caller's VirPass
  // and this one each keep their winners from frame to frame (VirOptions::reuseSplat).
  VirPass& emitterProbeVir() { return emitterProbes_; }

 private:
  Context& ctx_;
  Program shadowSplat_;
  Program surfels_;
  Program probeIrradiance_;
  Program probeMoments_;
  Program prefilter_;
  VirPass emitterShadow_;
  VirPass emitterProbes_;
};

// One frame for one cell: relight (with state.probes from the last frame) -> VirPass::run with the new
// surfel irradiance -> convolve; updates state and returns the relight result. probes.positions are the
// VIR probe positions (disabled probes are splatted too and simply never read).
// With emitter NEE and emissive surfels: relight gathers from state.reflected; VIR runs on the surfels
// with their emission zeroed (-> state.reflected) and once more on the emitters alone, whose radiance is
// added to the texels where an emitter is the nearest surface (same distance): state.atlas / state.probes
// hold emission + reflection as without NEE. The emitters-only texels are cached in state (see
// CellLighting::emitterTexels); state.probes is state.reflected plus those texels' cosine sums (the
// convolution is linear in radiance), same moments.
RelightResult relightFrame(RelightPass& relight, VirPass& vir, std::span<const shared::Surfel> surfels,
                           const RelightProbes& probes, const shared::SkyParams& sky,
                           const VirOptions& virOptions, const RelightOptions& options, CellLighting& state);

}  // namespace lfgi::gpu
