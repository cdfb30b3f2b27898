#include "gpu/irradiance_pass.h"

#include "core/error.h"
#include "core/octahedral.h"
#include "gpu/timing.h"

namespace lfgi::gpu {

IrradianceConvolution::IrradianceConvolution(Context& ctx)
    : ctx_(ctx), program_(ctx, "irradiance_convolve") {}

void IrradianceConvolution::record(VkCommandBuffer cmd, const Buffer& radiance, const Buffer& solidAngles,
                                   const Buffer& irradiance, const shared::IrradianceParams& p) const {
  const VkDeviceSize n2 = VkDeviceSize{p.radianceRes} * p.radianceRes;
  const VkDeviceSize m2 = VkDeviceSize{p.irradianceRes} * p.irradianceRes;
  if (radiance.size() < p.probeCount * n2 * sizeof(glm::vec4) || solidAngles.size() < n2 * sizeof(float) ||
      irradiance.size() < p.probeCount * m2 * sizeof(glm::vec4))
    fail("irradiance convolution: buffers too small for {} probes, N={}, M={}", p.probeCount, p.radianceRes,
         p.irradianceRes);
  dispatch(ctx_, cmd, program_, {&radiance, &solidAngles, &irradiance}, p,
           {p.irradianceRes, p.irradianceRes, p.probeCount});
}

std::vector<glm::vec3> IrradianceConvolution::run(std::span<const glm::vec3> radiance, int radianceRes,
                                                  int irradianceRes, int probeCount, double* gpuMs) {
  if (radianceRes < 1 || irradianceRes < 1 || probeCount < 1)
    fail("irradiance convolution: bad sizes N={}, M={}, probes={}", radianceRes, irradianceRes, probeCount);
  const size_t n2 = size_t(radianceRes) * size_t(radianceRes),
               m2 = size_t(irradianceRes) * size_t(irradianceRes);
  if (radiance.size() != n2 * size_t(probeCount))
    fail("irradiance convolution: {} radiance texels given, expected {}", radiance.size(),
         n2 * size_t(probeCount));

  std::vector<glm::vec4> rad4(radiance.size());
  for (size_t i = 0; i < radiance.size(); ++i) rad4[i] = glm::vec4(radiance[i], 0.0f);
  std::vector<double> omega = octTexelSolidAngles(radianceRes);
  std::vector<float> omegaF(omega.begin(), omega.end());

  Buffer radBuf = createStorageBuffer(ctx_, rad4.size() * sizeof(glm::vec4));
  Buffer omegaBuf = createStorageBuffer(ctx_, omegaF.size() * sizeof(float));
  Buffer irrBuf = createStorageBuffer(ctx_, m2 * size_t(probeCount) * sizeof(glm::vec4));
  upload<glm::vec4>(ctx_, radBuf, rad4);
  upload<float>(ctx_, omegaBuf, omegaF);
  shared::IrradianceParams params{uint32_t(radianceRes), uint32_t(irradianceRes), uint32_t(probeCount), 0};
  GpuTimer timer(ctx_, 2);
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    record(cmd, radBuf, omegaBuf, irrBuf, params);
    timer.stamp(cmd, 1);
    memoryBarrier(cmd);
  });
  if (gpuMs) *gpuMs = timer.elapsedMs(0, 1);
  std::vector<glm::vec4> out4(m2 * size_t(probeCount));
  readback<glm::vec4>(ctx_, irrBuf, out4);
  std::vector<glm::vec3> out(out4.size());
  for (size_t i = 0; i < out4.size(); ++i) out[i] = glm::vec3(out4[i]);
  return out;
}

}  // namespace lfgi::gpu
