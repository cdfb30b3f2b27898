// ShadingRenderer: one view shaded from probes, end to end (G-buffer ray cast + probe shading on the
// device), for `lfgi render`, bench/shading and the accuracy tests. Lives in its own library,
// lfgi_bake_shading (bake/ + gpu/), so lfgi_bake itself stays free of Vulkan.
//
// Image channels of render(): R/G/B (total), direct.R/G/B, indirect_diffuse.R/G/B,
// indirect_specular.R/G/B, indirect.R/G/B (diffuse + specular: compare with renderShadingReference's
// indirect layer), weight (sum of probe weights; 0 where no probe contributed), ao (ambient occlusion
// applied to indirect diffuse, gpu::ShadingOptions::aoRadius; 1 when off), fallback (share of the indirect
// light from the cells' SH L1 fallbacks, gpu/probe_shading_pass.h: 0 where probes give it all, 1 in a
// fallback-only cell; 0 on sky). A pixel is shaded from probes or fallbacks where weight > 0 or fallback > 0.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "bake/probe_capture.h"
#include "bake/reference_render.h"
#include "core/image.h"
#include "core/probe_field.h"
#include "gpu/gbuffer_pass.h"
#include "gpu/probe_shading_pass.h"
#include "worlds/mesh.h"
#include "worlds/sky.h"
#include "worlds/synthetic_world.h"

namespace lfgi::bake {

struct ShadedView {
  Image image;
  double gbufferMs = 0.0;  // device time of the G-buffer ray cast (GPU timestamps)
  double shadeMs = 0.0;    // device time of the probe shading pass
};

class ShadingRenderer {
 public:
  // Builds the GPU BVH of mesh and uploads it.
  ShadingRenderer(gpu::Context& ctx, const worlds::TriangleMesh& mesh);
  // Prefilters (bake::prefilterSpecularLevels, `levels` roughness levels), packs and uploads the fields.
  void setProbes(std::span<const ProbeField* const> fields, int specularLevels = 4);
  // Cells in any streaming state (full with a fade, or fallback-only: gpu::ShadingCellInput); full cells
  // without a specular span get prefilterSpecularLevels of their field.
  void setCells(std::span<const gpu::ShadingCellInput> cells, int specularLevels = 4);
  ShadedView render(const worlds::SkyModel& sky, const PinholeCamera& camera, int width, int height,
                    const gpu::ShadingOptions& options = {});
  // Shades given G-buffer points (no ray cast), viewed from eye (tests, leak probes).
  gpu::ShadeOutputHost shadePoints(const worlds::SkyModel& sky, const gpu::GBufferHost& points, glm::vec3 eye,
                                   const gpu::ShadingOptions& options = {});
  const gpu::GpuScene& scene() const { return scene_; }

 private:
  gpu::Context& ctx_;
  gpu::GpuScene scene_;
  gpu::GpuSceneBuffers buffers_;
  gpu::GBufferPass gbuffer_;
  gpu::ProbeShadingPass shading_;
};

// Mask (width*height) of the pixels shaded from probes or fallbacks (weight > 0 or fallback > 0), leaving out
// those where either image sees an emitter (direct.G >= emitterLevel): at an emitter's edge the reference's
// jittered samples mix in its radiance, which a total would then compare against a pixel-centre G-buffer.
// ref is a renderShadingReference image of the same size.
std::vector<uint8_t> shadedSurfaceMask(const Image& shaded, const Image& ref, float emitterLevel);

// Relative RMS (core/metrics.h) between the 3 channels layer+"R/G/B" of a and of reference, over pixels
// where mask (if given, width*height) is non-zero. Throws lfgi::Error naming a missing channel.
double layerRelativeRms(const Image& a, const std::string& layerA, const Image& reference,
                        const std::string& layerRef, const std::vector<uint8_t>* mask = nullptr);

// Per-pixel error heat map of luminance |a - ref| / (mean luminance of ref), 0 (black) .. 0.5 (white)
// through blue-green-yellow-red; channels R/G/B in [0, 1] (write with writePng exposure 0, Reinhard off).
Image errorHeatMap(const Image& a, const std::string& layerA, const Image& reference,
                   const std::string& layerRef);

// Mean indirect-diffuse luminance (Rec. 709 weights) over a points x points lattice of floor points of a
// room's air box (0.3 m in from its walls, just above its floor, normal up, albedo 0.5), shaded from
// r's probes (direct and specular off) with Chebyshev visibility on or off: what the leak tests compare.
double roomFloorIndirect(ShadingRenderer& r, const worlds::SkyModel& sky, const worlds::Aabb& air,
                         bool chebyshev, int points = 6);

// Leak test (docs/DESIGN.md §5, NVIDIA LFP/DDGI style) on the first LeakTestSite of a world cell: captures
// the cell's own placed probes around the house (within one spacing of its bounds), shades 5 x 5 floor points
// of the lit room and of the sealed room and reports mean indirect-diffuse luminance, with Chebyshev
// visibility on and off. ratio = sealed / lit. Throws lfgi::Error if the cell has no leak test.
struct LeakTestResult {
  size_t probes = 0;
  double litOn = 0.0, sealedOn = 0.0, litOff = 0.0, sealedOff = 0.0;
  double ratioOn() const { return litOn > 0.0 ? sealedOn / litOn : 0.0; }
  double ratioOff() const { return litOff > 0.0 ? sealedOff / litOff : 0.0; }
};
LeakTestResult measureLeakTest(gpu::Context& ctx, const worlds::SyntheticWorld& world, worlds::CellCoord cell,
                               const worlds::SkyModel& sky, const CaptureOptions& capture);

}  // namespace lfgi::bake
