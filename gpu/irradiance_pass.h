// GPU pass: brute-force irradiance convolution of octahedral radiance maps
// (shaders/irradiance_convolve.comp). The exact (reference) derivation of irradiance maps from radiance maps;
// O(M^2 N^2) per probe.
#pragma once

#include <glm/glm.hpp>

#include <span>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/program.h"
#include "shared/irradiance.h"

namespace lfgi::gpu {

class IrradianceConvolution {
 public:
  explicit IrradianceConvolution(Context& ctx);

  // Records the pass. radiance: probeCount * N*N vec4 (rgb used); solidAngles: N*N floats (exact
  // octahedral texel solid angles, see core/octahedral.h); irradiance: probeCount * M*M vec4.
  // Throws lfgi::Error if a buffer is smaller than params require.
  void record(VkCommandBuffer cmd, const Buffer& radiance, const Buffer& solidAngles,
              const Buffer& irradiance, const shared::IrradianceParams& params) const;

  // Convenience: uploads, runs, waits and returns probeCount * M*M irradiance values (rgb). If gpuMs is
  // given, it receives the pass's device time from GPU timestamps (excluding uploads and readback).
  std::vector<glm::vec3> run(std::span<const glm::vec3> radiance, int radianceRes, int irradianceRes,
                             int probeCount, double* gpuMs = nullptr);

 private:
  Context& ctx_;
  Program program_;
};

}  // namespace lfgi::gpu
