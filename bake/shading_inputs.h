// Glue between the ground truth (bake/) and the probe shading pass (gpu/probe_shading_pass.h), with no
// Vulkan here: materials in the GPU layout, capture results as core ProbeFields, GGX-prefiltered radiance
// levels, and a path-traced reference split the way the shading pass splits its image.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "bake/probe_capture.h"
#include "bake/reference_render.h"
#include "core/image.h"
#include "core/probe_field.h"
#include "core/sh.h"
#include "shared/shading.h"
#include "worlds/mesh.h"

namespace lfgi::bake {

// A cell's ProbeField from a capture: probe k of `result` is grid probe gridIndex[k] (its offset from the
// lattice point is kept); grid probes without a captured probe (or not done) are inactive with zero maps.
// Throws lfgi::Error if sizes disagree, an index is out of range, or the captures' resolutions differ.
ProbeField probeFieldFromCapture(const ProbeGrid& grid, const CaptureResult& result,
                                 std::span<const int64_t> gridIndex);

// SH L1 fallback of a cell from its field, as the bake's cell-file fallback is made (the mean of the active
// probes' L1 projections of radiance) but from the field given, so from a field without the discs it holds
// no sun (the shading pass adds the sun itself). Throws lfgi::Error if the field has no active probe.
ShL1 fieldFallback(const ProbeField& field);

// A sparse subset of a cell's probes for its fallback (fieldFallback of a capture of just these): every
// layer of about columns x columns evenly spaced xz columns, leaving out probes inside solid (disabled[i]
// != 0). Returns an active mask over grid.probeCount().
std::vector<uint8_t> fallbackProbeMask(const ProbeGrid& grid, std::span<const uint8_t> disabled,
                                       int columns = 3);

// GGX-prefiltered radiance for the shading pass's specular lookups: per probe `levels` n x n x 3 maps,
// level k = prefilterRadianceGgx(radiance, n, k / (levels - 1), n) (one level: roughness 0). Inactive
// probes get zeros. Cost O(levels n^4) per probe.
std::vector<float> prefilterSpecularLevels(const ProbeField& field, int levels);

// Reference for shading from probes: per pixel and sample the capture's path tracer (tracePath), split as
//   direct.R/G/B    what the shading pass computes without probes: the primary ray's sky + disc radiance
//                   on a miss, else emission of the first hit + sun/moon next-event estimation at it
//   indirect.R/G/B  total - direct: everything the probes must supply (light reflected at the first hit
//                   after arriving from other surfaces, emitters' surfaces or the sky)
//   R/G/B           total
// Same camera, jitter, seeds and transport as renderReference, so R/G/B equals its R/G/B for the same
// options up to float summation order. Threads, interrupts and progress as renderReference.
RenderResult renderShadingReference(const EmbreeScene& scene, const worlds::SkyModel& sky,
                                    const PinholeCamera& camera, const RenderOptions& options,
                                    bool showProgress = false);

}  // namespace lfgi::bake

namespace lfgi::bake {

// Removes the sun and moon from a captured field, exactly undoing what the capture added for each disc
// the probe sees (scene.occluded from the probe position, as the capture tests it): energy / Omega_texel
// in the radiance texel holding the disc direction, and DiscLight::irradiance(n) in every irradiance
// texel (clamped at 0 against float rounding). The shading pass adds the discs itself with shadow rays,
// so fields given to it must not hold them (else the sun counts twice).
void subtractDiscLight(ProbeField& field, const EmbreeScene& scene, const worlds::SkyModel& sky,
                       float maxDistance = 1.0e4f);

// Captures every probe of `grid` (position = lattice point + offsets[i] when offsets is non-empty; probes
// with active[i] == 0 skipped when active is non-empty) and returns the field for shading: without the
// discs (subtractDiscLight). Progress and interrupts as captureProbes; an interrupted capture throws
// lfgi::Error("capture interrupted").
ProbeField captureGridField(const EmbreeScene& scene, const worlds::SkyModel& sky, const ProbeGrid& grid,
                            std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                            const CaptureOptions& options, bool showProgress = false);

}  // namespace lfgi::bake
