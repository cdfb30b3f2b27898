// GPU pass: View-Independent Rasterization (Marrs, Watson & Healey, EG 2017) of a surfel cloud into the
// octahedral maps of many probes at once — splat (shaders/vir_splat.comp), resolve (vir_resolve.comp)
// and hole fill (vir_holefill.comp). The depth test is a 64-bit atomicMin on (depth bits << 32 | surfel
// index), so the device needs shaderBufferInt64Atomics.
//
// Channels per probe, N x N texels each (octahedral, no border, shared/octahedral.h texel convention):
//   distance: (r, r^2), r = distance along the texel-centre ray to the nearest surfel disc it hits
//   normal:   xyz the surfel normal, w the coverage (0 hole, 1 covered, p + 2 filled by dilation pass p)
//   albedo, radiance: rgb (radiance = emission + albedo * E / pi, E the per-surfel irradiance input)
#pragma once

#include <glm/glm.hpp>

#include <span>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/program.h"
#include "shared/surfel.h"
#include "shared/vir.h"

namespace lfgi::gpu {

struct VirOptions {
  int resolution = 16;          // N
  float maxRange = 64.0f;       // m; surfels farther from a probe are not splatted into it
  float footprintScale = 1.5f;  // disc radius multiplier of the footprint test (see vir_splat.comp)
  int maxFootprintRadius = 6;   // splat window half-size in texels (up to 13 x 13, near surfels only)
  int fillPasses = 2;           // dilation passes, 0..kMaxFillPasses
  static constexpr int kMaxFillPasses = 8;
};

struct ProbeAtlas {
  int resolution = 0;
  int probeCount = 0;
  std::vector<glm::vec2> distance;  // probeCount * N^2: (r, r^2)
  std::vector<glm::vec4> normal;    // w: coverage
  std::vector<glm::vec4> albedo;
  std::vector<glm::vec4> radiance;
  double holeFractionBeforeFill = 0.0;  // texels no surfel reached / all texels
  double holeFractionAfterFill = 0.0;   // texels still holes after the fill passes / all texels
  double gpuMs = 0.0;                   // device time of clear + splat + resolve + fill
  double splatMs = 0.0, resolveMs = 0.0, fillMs = 0.0;
};

class VirPass {
 public:
  // Throws lfgi::Error if the device lacks 64-bit buffer atomics.
  explicit VirPass(Context& ctx);

  // Uploads, splats, resolves, fills, waits and reads back. surfelIrradiance: one irradiance E (rgb) per
  // surfel, or empty for zero (radiance = emission). Throws lfgi::Error on empty input, bad options,
  // a mismatched irradiance count, or a grid beyond the device's dispatch limits.
  ProbeAtlas run(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> probes,
                 const VirOptions& options, std::span<const glm::vec4> surfelIrradiance = {});

 private:
  Context& ctx_;
  Program splat_;
  Program resolve_;
  Program holefill_;
};

}  // namespace lfgi::gpu
