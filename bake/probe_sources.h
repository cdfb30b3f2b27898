// Probe sources for shading besides the Embree capture (bake/shading_inputs.h captureGridField): every one
// returns a core ProbeField without the sun/moon discs (the shading pass adds them with shadow rays), so
// ShadingRenderer::setProbes takes any of them and `lfgi render --probes capture|vir|codec` and
// bench/shading compare them on the same view.
//
//   VIR      virProbeField: the surfels relit on the GPU for the current sky (gpu/relight_pass.h
//            relightFrame: key disc through the VIR shadow map, last frame's probe irradiance as
//            the next bounce) over `frames` frames, then splatted into the probes (gpu/vir_pass.h). Texels no
//            surfel covered hold the sky (no discs); irradiance and the 3 x 3 filtered distance moments are
//            the relight pass's own (ProbeLighting), so shading reads exactly what the next relight frame
//            would read. Lambertian surfels (the relight pass's assumption).
//   codec    codecProbeField: a baked cell file (core/cell_file.h) decoded on the CPU (core/generator_cpu.h
//            decodeProbeField) under the frame's conditioning (time of day, overcast); a "no network" cell
//            gives every probe the cell's SH L1 fallback radiance (per probe for a per-probe fallback,
//            `lfgi bake --codec sh-l1`; the keys blended at the sky's time of day and overcast) and
//            open distance moments (missDistance: Chebyshev never occludes); its irradiance is the SH's
//            cosine convolution (as the streaming source decodes), a network cell's that of its maps.
//            The bake trains on maps without the directly seen discs (captureTrainingSet), so the
//            decoded maps are already what shading reads.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "bake/embree_scene.h"
#include "core/cell_file.h"
#include "core/probe_field.h"
#include "core/shared_model.h"
#include "gpu/context.h"
#include "gpu/vir_probe_field.h"
#include "worlds/mesh.h"
#include "worlds/sky.h"
#include "worlds/surfels.h"

namespace lfgi::bake {

// A copy of mesh where every double-sided triangle also appears reversed (single-sided, same material),
// so the surfel sampler puts a disc on each side: VIR culls back-facing discs and each side carries its
// own irradiance.
worlds::TriangleMesh meshWithBackFaces(const worlds::TriangleMesh& mesh);

struct VirProbeOptions {
  int resolution = 16;           // N of the VIR maps, [4, 64]
  int irradianceResolution = 8;  // M, [1, 64]
  int frames = 4;                // relight frames: frame 1 direct light, each further frame one more bounce
  float maxRange = 64.0f;        // m: surfels farther from a probe are not splatted into it
};

struct VirProbeStats {
  double seconds = 0.0;  // wall time of all frames (upload, GPU, readback)
  double gpuMs = 0.0;    // device time summed over frames (relight + VIR + convolution)
  size_t surfels = 0, probes = 0;
};

// Probe field of `grid` (probe i at its lattice point + offsets[i] when offsets is non-empty; probes with
// active[i] == 0 stay inactive and are not splatted when active is non-empty) from VIR relight of
// `surfels`. Throws lfgi::Error on empty surfels, sizes that disagree with the grid, bad options, or an
// interrupt between frames (core/progress.h InterruptGuard).
ProbeField virProbeField(gpu::Context& ctx, std::span<const worlds::Surfel> surfels, const ProbeGrid& grid,
                         std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                         const worlds::SkyModel& sky, const VirProbeOptions& options,
                         VirProbeStats* stats = nullptr);
// The same with the caller's relighter: its pipelines are built once for every field a caller makes
// (a render's 3 x 3 cells), and it holds the last call's GPU buffers until the next.
ProbeField virProbeField(gpu::VirFieldRelighter& relighter, std::span<const worlds::Surfel> surfels,
                         const ProbeGrid& grid, std::span<const glm::vec3> offsets,
                         std::span<const uint8_t> active, const worlds::SkyModel& sky,
                         const VirProbeOptions& options, VirProbeStats* stats = nullptr);

// Visibility from geometry (docs/ARCHITECTURE.md, "Where visibility comes from"): the distance moments of
// field's active probes (probe i at its lattice point + offsets[i] when offsets is non-empty) replaced by
// VIR's of `surfels` at field's N (gpu::VirFieldRelighter::regenerateMoments: one frame, no light);
// radiance, irradiance and inactive probes stay. What the codec's decode and the streaming manager's
// loads (streaming::VirRelightSource) do to a decoded field. stats: that frame's. Throws as
// virProbeField does.
void regenerateVirMoments(gpu::Context& ctx, std::span<const worlds::Surfel> surfels,
                          std::span<const glm::vec3> offsets, ProbeField& field, float maxRange = 64.0f,
                          VirProbeStats* stats = nullptr);
void regenerateVirMoments(gpu::VirFieldRelighter& relighter, std::span<const worlds::Surfel> surfels,
                          std::span<const glm::vec3> offsets, ProbeField& field, float maxRange = 64.0f,
                          VirProbeStats* stats = nullptr);

// Probe field of a decoded cell file (see the top of this file). resolution: map size for a "no network"
// cell (a network cell decodes at its model's size). Throws lfgi::Error naming `what` when the
// file holds no probes or the model cannot emit a ProbeField.
// shared: the world's shared model for a shared-model (version 3) cell (core/shared_model.h
// resolveCellWeights; its errors name the cell and the model file), null for other cells.
ProbeField codecProbeField(const CellFile& cell, const std::string& what, const worlds::SkyModel& sky,
                           int resolution, int irradianceResolution = 8, float missDistance = 1.0e4f,
                           const ResolvedSharedModel* shared = nullptr);

}  // namespace lfgi::bake
