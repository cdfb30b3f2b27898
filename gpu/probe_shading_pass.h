// Probe shading pass (shaders/probe_shade.comp): shades a G-buffer (gpu/gbuffer_pass.h) from the light
// fields of one or more cells (core/probe_field.h). Per pixel: the 8 probes of its grid cell, weighted by
// trilinear x Chebyshev visibility from the distance moments (McGuire et al. 2017) x backface weight,
// with DDGI's normal/view bias (Majercik et al. 2019); indirect diffuse from the bilinear octahedral
// irradiance maps, indirect specular from GGX-prefiltered radiance at the mirror direction; direct light =
// emission + sun/moon with a shadow ray through the same BVH; escaped rays show sky + discs.
//
// Several cells at once: every ProbeField keeps its own grid; a pixel is shaded by the cell that owns its
// point (half-open boxes, core/probe_grid.h; outside every box, the nearest cell), and a corner of its
// 8-probe cube that falls outside that cell's grid is taken from the cell whose lattice holds the same
// world point (the neighbour's first probe layer), else clamped into the owning grid.
//
// Streaming fallback (streaming/streaming_manager.h): a cell is either full (its field, with a fade in
// [0, 1] while it cross-fades in) or fallback-only (not resident: its box and its SH L1 fallback, no
// probes). Every cell may carry an SH L1 fallback; the fallback at a point is bilinear between the 4 cell
// centres around it in xz (no step at a border). Per pixel, with t_k the trilinear weights of the 8
// corners and f_k the fade of the cell each corner's probe belongs to (0 for a corner in a fallback-only
// cell):
//   E = beta * (probe result over the corners, weights t_k f_k x visibility x backface, normalised)
//     + sum_k t_k (1 - f_k) * fallback(q_k),     beta = sum_k t_k f_k
// where q_k = p, except on an x or z axis where p is in the owning grid's last probe interval: there q_k
// sits on the corner's lattice plane (the last layer or the face), as StreamingManager::sample() places
// its fallback evaluations. A fallback-only cell runs the same sum over its box's lattice, every own corner
// on the fallback (f = 0): a point in it takes the fallback alone, except in its last probe interval before
// a resident neighbour, where it blends into that neighbour's first layer, so the border has no step from
// either side (sample() takes the fallback alone there and steps at the face; the test in
// bake/streaming_shading_test.cpp states the difference). With visibility and backface weights off this is
// sample() everywhere else; no point inside the cells lacks indirect light.
// Specular from a fallback: the SH L1 radiance in the mirror direction r with its linear band scaled by
// 1 - alpha/3 (alpha = roughness^2): L = (E0 + (1.5 - 0.5 alpha) E1 . r) / pi, where E(n) = E0 + E1 . n is
// the fallback irradiance. Mirror: the SH L1 radiance at r; roughness 1: irradiance / pi at r (the cosine
// lobe's band-1 factor 2/3), the standard zonal attenuation of a lobe widening from a delta to a cosine.
// Fallback irradiance and radiance are clamped at 0 (an SH L1 of a peaked sky can go negative).
// Disabled probes (inside solid) are left out of both sums (the t_k renormalised over the others); if all 8
// are, the point takes the fallback.
//
// AO (ShadingOptions::aoRadius): from the G-buffer, not from the probes' distance moments: short cosine rays
// through the same BVH resolve contact occlusion (corners, under objects) far below the probe spacing,
// which the probes' moments, sampled at probe centres, cannot. Applied to indirect diffuse only.
// Limits: every field must have the same radiance/distance resolution n and irradiance resolution m; the
// specular lookup ignores parallax (probe-centred mirror direction); AO also darkens the part of the
// occlusion the probes already hold (it is an option, off by default).
#pragma once

#include <glm/glm.hpp>

#include <span>
#include <vector>

#include "core/probe_field.h"
#include "core/sh.h"
#include "gpu/buffer.h"
#include "gpu/gbuffer_pass.h"
#include "gpu/program.h"
#include "shared/shading.h"

namespace lfgi::gpu {

struct ShadingCellInput {
  const ProbeField* field = nullptr;  // full cells; null for a fallback-only cell
  // Optional GGX-prefiltered radiance (bake::prefilterRadianceGgx): per probe `levels` interior n x n x 3
  // maps, probe-major, level k prefiltered for roughness k / (levels - 1). Empty: the raw radiance serves
  // every level.
  std::span<const float> specular;
  // Streaming state. fade: weight of the probes against the fallback, in [0, 1] (StreamingManager::fade);
  // fallback: the cell's SH L1 radiance (CellSource::fallback; zero: no fallback light).
  float fade = 1.0f;
  ShL1 fallback{};
  // A cell that is not resident: field null, shaded from `fallback` alone; `box` is its owned box (its
  // ProbeGrid: origin, spacing, dims). Ignored for full cells (their field's grid is the box).
  bool fallbackOnly = false;
  ProbeGrid box;
};

// The probes of all cells packed into the GPU layout: bordered octahedral maps, one global probe index.
struct ShadingProbeSet {
  int irradianceResolution = 0;  // m
  int resolution = 0;            // n
  int specularLevels = 1;        // L
  float minSpacing = 1.0f;       // smallest probe spacing of any cell (m): scales the default biases
  std::vector<shared::ShadeCell> cells;
  std::vector<glm::vec4> probes;      // xyz position (with offset), w: 1 active / 0 disabled
  std::vector<glm::vec4> irradiance;  // probes * (m+2)^2
  std::vector<glm::vec2> moments;     // probes * (n+2)^2
  std::vector<glm::vec4> specular;    // probes * L * (n+2)^2
};

// Validates every field (ProbeField::validate) and packs them. Throws lfgi::Error naming the cell index
// for a null field (not fallback-only), a fallback-only cell with a field or a bad box, a fade outside
// [0, 1], a non-finite fallback, different resolutions, or a specular span of the wrong size; levels in
// [1, 16]. Every cell may be fallback-only (then no probe is uploaded).
ShadingProbeSet packShadingProbes(std::span<const ShadingCellInput> cells, int specularLevels);

struct ShadingOptions {
  bool chebyshev = true;     // visibility from distance moments
  bool backface = true;      // DDGI wrap-shading weight towards the probe
  bool sunShadows = true;    // shadow rays for sun and moon
  float normalBias = -1.0f;  // m; < 0: 0.045 x min spacing (DDGI: 0.2 x 0.75 x 0.3)
  float viewBias = -1.0f;    // m; < 0: 0.18 x min spacing (DDGI: 0.8 x 0.75 x 0.3)
  float chebyshevFloor = 0.0f;
  float maxDistance = 1.0e4f;
  bool direct = true, diffuse = true, specular = true;  // layers to compute (others are 0)
  // Ambient occlusion from the G-buffer: LFGI_SHADE_AO_RAYS cosine-distributed rays of length aoRadius
  // from each point through the scene BVH; ao = unoccluded fraction (cosine-weighted), multiplies the
  // indirect diffuse and is written to ShadeOutput::specular.w (1 when off). 0: off.
  float aoRadius = 0.0f;
};

struct ShadeOutput {
  int width = 0, height = 0;
  // vec4 per pixel; diffuse.w = sum of probe weights; specular.w = AO; direct.w = the fallback's share of the
  // indirect light (1 - beta above; 0 on sky and on points not shaded from probes or fallbacks)
  Buffer direct, diffuse, specular, total;
};
ShadeOutput createShadeOutput(Context& ctx, int width, int height);

struct ShadeOutputHost {
  int width = 0, height = 0;
  std::vector<glm::vec4> direct, diffuse, specular, total;
};
ShadeOutputHost readShadeOutput(Context& ctx, const ShadeOutput& out);

class ProbeShadingPass {
 public:
  explicit ProbeShadingPass(Context& ctx);
  // Uploads the probes (replaces earlier ones).
  void setProbes(const ShadingProbeSet& probes);
  // Streaming (the installed runtime): a device pool of `slots` slots of probesPerSlot probes each, maps of
  // the given resolutions and specularLevels levels of raw radiance; a cell's maps are uploaded once into
  // its slot when it becomes resident, and the cell table alone changes with residency, fades and
  // fallbacks. reservePool replaces earlier probes (every slot starts inactive).
  void reservePool(int slots, int64_t probesPerSlot, int irradianceResolution, int resolution,
                   int specularLevels = 1);
  // Uploads field into pool slot `slot`; returns the bytes uploaded. Throws if it does not fit the pool.
  size_t uploadPoolSlot(int slot, const ProbeField& field);
  // The cells to shade: a full cell reads pool slot slots[k] (its maps uploaded there), a fallback-only
  // cell its box (slots[k] ignored). Uploads the cell table only. Throws like packShadingProbes.
  void setPoolCells(std::span<const ShadingCellInput> cells, std::span<const int> slots);
  // Device memory the pass holds for probes, cells and parameters (bytes).
  size_t deviceBytes() const;
  // Uploads the per-view parameters.
  void setView(const shared::SkyParams& sky, const shared::GpuCamera& camera, int width, int height,
               const GpuSceneBuffers& scene, const ShadingOptions& options);
  // setView recorded into cmd (recordBufferUpdate) instead of uploaded: for a command buffer the caller
  // submits (several views in one buffer each see their own parameters).
  void recordView(VkCommandBuffer cmd, const shared::SkyParams& sky, const shared::GpuCamera& camera,
                  int width, int height, const GpuSceneBuffers& scene, const ShadingOptions& options);
  // Records the pass. Throws if setProbes/setView were not called or sizes disagree.
  void record(VkCommandBuffer cmd, const GpuSceneBuffers& scene, const GBuffer& g, ShadeOutput& out) const;

 private:
  Context& ctx_;
  Program program_;
  Buffer params_, cells_, probes_, irradiance_, moments_, specular_;
  float minSpacing_ = 1.0f;
  uint32_t cellCount_ = 0;
  glm::uvec4 maps_{0};
  int width_ = 0, height_ = 0;
  bool haveProbes_ = false;
  struct Pool {
    int slots = 0;
    int64_t probesPerSlot = 0;
  } pool_;
  shared::ShadeParams viewParams(const shared::SkyParams& sky, const shared::GpuCamera& camera, int width,
                                 int height, const GpuSceneBuffers& scene, const ShadingOptions& o);
};

}  // namespace lfgi::gpu
