// A whole ProbeField from VIR relighting of a surfel cloud (the GPU-only sequence shared by the bake's
// probe source, bake/probe_sources.h virProbeField, and the streaming manager's VIR relight,
// streaming/vir_relight_source.h): over `frames` frames, gpu::relightFrame lights the surfels for the sky
// (key disc through the VIR shadow map, last frame's probe irradiance as the next bounce) and splats them
// into the probes (gpu/vir_pass.h); the last frame's maps become the field:
//   radiance    covered texels: the relit surfel radiance; texels no surfel covered (or only the hole
//               fill did, as the relight convolution treats them) hold the sky (shared::skyRadiance,
//               no discs);
//   distance    the relight pass's 3 x 3 filtered moments (r, r^2), sky texels at missDistance;
//   irradiance  the relight pass's own probe irradiance (ProbeLighting: what the next relight frame
//               would read), without the discs.
// The sun and moon a probe sees directly are never in the maps, as in the codec's fields: the shading pass
// adds them with shadow rays.
// Only the box of lattice indices holding active probes is relit and splatted, and only surfels within
// maxRange of that box (VIR's cost is per (surfel, probe) pair).
//
// Seed: a field of the same grid and resolutions whose irradiance (without discs) and distance moments
// stand in for frame 0's "last frame" probe lighting, so frame 1 already carries its bounce light (the
// streaming relight passes the cell's previous VIR lighting). Without a seed frame 1 is direct light only
// and each further frame adds one bounce.
//
// Threading: a VirFieldRelighter owns a RelightPass and a VirPass on one Context: one thread at a time
// (see gpu/relight_pass.h); callers serialise.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/probe_field.h"
#include "gpu/relight_pass.h"
#include "gpu/vir_pass.h"
#include "shared/sky.h"
#include "shared/surfel.h"

namespace lfgi::gpu {

struct VirFieldOptions {
  int resolution = 16;           // N of the VIR maps, [4, 64]
  int irradianceResolution = 8;  // M, [1, 64]
  int frames = 4;                // relight frames, [1, 64]
  float maxRange = 64.0f;        // m: surfels farther from a probe are not splatted into it
  bool storeOffsets = true;      // out.offsets = offsets (false: out.offsets left empty; the probes still
                                 // sit at lattice + offsets for the relight)
  bool noSurfelsIsSky = false;   // no surfel within maxRange: every active probe sees only the sky
                                 // (else lfgi::Error)
  bool checkInterrupt = true;    // core/progress.h InterruptGuard between frames (lfgi::Error)
  // The passes' own options; resolution, irradianceResolution and maxRange above override theirs.
  VirOptions vir{};
  RelightOptions relight{};
};

struct VirFieldStats {
  double seconds = 0.0;  // wall time (upload, GPU, readback, CPU packing)
  double gpuMs = 0.0;    // device time summed over frames (relight + VIR + convolution)
  size_t surfels = 0, probes = 0;
  bool seeded = false;
};

class VirFieldRelighter {
 public:
  // Throws lfgi::Error if the device lacks 64-bit buffer atomics.
  explicit VirFieldRelighter(Context& ctx);

  // Writes the field of `grid` into `out` (reusing its capacity): probe i at its lattice point +
  // offsets[i] (offsets empty: none), active[i] == 0 probes stay inactive and zero (active empty: all
  // active). out.normal / out.albedo are cleared. Throws lfgi::Error on sizes that disagree with the grid,
  // bad options, a seed of another grid / resolution, no surfel near the probes (unless
  // noSurfelsIsSky), or an interrupt between frames.
  void run(std::span<const shared::Surfel> surfels, const ProbeGrid& grid, std::span<const glm::vec3> offsets,
           std::span<const uint8_t> active, const shared::SkyParams& sky, const VirFieldOptions& options,
           ProbeField& out, const ProbeField* seed = nullptr, VirFieldStats* stats = nullptr);

  // Visibility from geometry (docs/ARCHITECTURE.md, "Where visibility comes from"): replaces the distance
  // moments of field's active probes (probe i at its lattice point + offsets[i]) with VIR's of `surfels`
  // at field's N, as run() makes them (3 x 3 filtered, sky texels at missDistance); radiance, irradiance
  // and inactive probes stay (field.offsets too: a caller that shades the field sets them to offsets,
  // where the moments were seen). One frame without sun or bounce (moments do not depend on the light);
  // scratch holds that frame's field (reused). Throws as run() does.
  void regenerateMoments(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> offsets,
                         const VirFieldOptions& options, ProbeField& field, ProbeField& scratch,
                         VirFieldStats* stats = nullptr);

 private:
  RelightPass relight_;
  VirPass vir_;
  std::vector<shared::Surfel> near_;  // scratch, reused
};

}  // namespace lfgi::gpu
