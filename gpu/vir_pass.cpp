#include "gpu/vir_pass.h"

#include <cmath>

#include "core/error.h"
#include "gpu/timing.h"

namespace lfgi::gpu {

namespace {

Program requireInt64Atomics(Context& ctx, const char* name) {
  if (!ctx.features.shaderBufferInt64Atomics)
    fail("VIR: device '{}' lacks shaderBufferInt64Atomics (64-bit buffer atomics)", ctx.info.name);
  return Program(ctx, name);
}

}  // namespace

VirPass::VirPass(Context& ctx)
    : ctx_(ctx),
      splat_(requireInt64Atomics(ctx, "vir_splat")),
      resolve_(ctx, "vir_resolve"),
      holefill_(ctx, "vir_holefill") {}

ProbeAtlas VirPass::run(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> probes,
                        const VirOptions& o, std::span<const glm::vec4> surfelIrradiance) {
  if (surfels.empty() || probes.empty())
    fail("VIR: {} surfels, {} probes: need at least one of each", surfels.size(), probes.size());
  if (o.resolution < 1 || o.resolution > 1024) fail("VIR: resolution {} outside [1, 1024]", o.resolution);
  if (!(std::isfinite(o.maxRange) && o.maxRange > 0.0f))
    fail("VIR: maxRange {} must be finite and > 0", o.maxRange);
  if (!(std::isfinite(o.footprintScale) && o.footprintScale > 0.0f))
    fail("VIR: footprintScale {} must be finite and > 0", o.footprintScale);
  if (o.maxFootprintRadius < 0 || o.maxFootprintRadius > 8)
    fail("VIR: maxFootprintRadius {} outside [0, 8]", o.maxFootprintRadius);
  if (o.fillPasses < 0 || o.fillPasses > VirOptions::kMaxFillPasses)
    fail("VIR: fillPasses {} outside [0, {}]", o.fillPasses, VirOptions::kMaxFillPasses);
  if (!surfelIrradiance.empty() && surfelIrradiance.size() != surfels.size())
    fail("VIR: {} surfel irradiance values for {} surfels", surfelIrradiance.size(), surfels.size());
  const uint32_t* maxGroups = ctx_.properties.limits.maxComputeWorkGroupCount;
  const uint64_t splatGroupsX = (surfels.size() + 63) / 64;
  const uint64_t mapGroups = (uint64_t(o.resolution) + 7) / 8;
  if (splatGroupsX > maxGroups[0] || probes.size() > maxGroups[1] || probes.size() > maxGroups[2] ||
      surfels.size() > 0xFFFFFFFFull || mapGroups > maxGroups[0])
    fail("VIR: {} surfels x {} probes exceeds the device's dispatch limits ({}, {}, {} workgroups)",
         surfels.size(), probes.size(), maxGroups[0], maxGroups[1], maxGroups[2]);

  const size_t n2 = size_t(o.resolution) * size_t(o.resolution);
  const size_t texels = n2 * probes.size();
  std::vector<glm::vec4> probe4(probes.size());
  for (size_t i = 0; i < probes.size(); ++i) probe4[i] = glm::vec4(probes[i], 1.0f);
  std::vector<glm::vec4> irradiance(surfels.size(), glm::vec4(0.0f));
  if (!surfelIrradiance.empty()) irradiance.assign(surfelIrradiance.begin(), surfelIrradiance.end());

  Buffer surfelBuf = createStorageBuffer(ctx_, surfels.size_bytes());
  Buffer probeBuf = createStorageBuffer(ctx_, probe4.size() * sizeof(glm::vec4));
  Buffer irrBuf = createStorageBuffer(ctx_, irradiance.size() * sizeof(glm::vec4));
  Buffer slots = createStorageBuffer(ctx_, texels * sizeof(uint64_t));
  Buffer distBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec2));
  Buffer normalBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec4));
  Buffer albedoBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec4));
  Buffer radianceBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec4));
  Buffer counters = createStorageBuffer(ctx_, (1 + VirOptions::kMaxFillPasses) * sizeof(uint32_t));
  upload<shared::Surfel>(ctx_, surfelBuf, surfels);
  upload<glm::vec4>(ctx_, probeBuf, probe4);
  upload<glm::vec4>(ctx_, irrBuf, irradiance);

  shared::VirParams params{};
  params.probeCount = uint32_t(probes.size());
  params.res = uint32_t(o.resolution);
  params.surfelCount = uint32_t(surfels.size());
  params.maxFootprintRadius = uint32_t(o.maxFootprintRadius);
  params.maxRange = o.maxRange;
  params.footprintScale = o.footprintScale;
  const uint32_t res = params.res, probeCount = params.probeCount;

  GpuTimer timer(ctx_, 5);
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    vkCmdFillBuffer(cmd, slots.handle(), 0, VK_WHOLE_SIZE, 0xFFFFFFFFu);
    vkCmdFillBuffer(cmd, counters.handle(), 0, VK_WHOLE_SIZE, 0u);
    memoryBarrier(cmd);
    timer.stamp(cmd, 1);
    dispatch(ctx_, cmd, splat_, {&surfelBuf, &probeBuf, &slots}, params, {params.surfelCount, probeCount, 1});
    memoryBarrier(cmd);
    timer.stamp(cmd, 2);
    dispatch(ctx_, cmd, resolve_,
             {&slots, &surfelBuf, &irrBuf, &distBuf, &normalBuf, &albedoBuf, &radianceBuf, &counters}, params,
             {res, res, probeCount});
    memoryBarrier(cmd);
    timer.stamp(cmd, 3);
    for (int pass = 0; pass < o.fillPasses; ++pass) {
      params.fillPass = uint32_t(pass);
      dispatch(ctx_, cmd, holefill_, {&distBuf, &normalBuf, &albedoBuf, &radianceBuf, &counters}, params,
               {res, res, probeCount});
      memoryBarrier(cmd);
    }
    timer.stamp(cmd, 4);
  });

  ProbeAtlas atlas;
  atlas.resolution = o.resolution;
  atlas.probeCount = int(probes.size());
  atlas.splatMs = timer.elapsedMs(1, 2);
  atlas.resolveMs = timer.elapsedMs(2, 3);
  atlas.fillMs = timer.elapsedMs(3, 4);
  atlas.gpuMs = timer.elapsedMs(0, 4);
  atlas.distance.resize(texels);
  atlas.normal.resize(texels);
  atlas.albedo.resize(texels);
  atlas.radiance.resize(texels);
  readback<glm::vec2>(ctx_, distBuf, atlas.distance);
  readback<glm::vec4>(ctx_, normalBuf, atlas.normal);
  readback<glm::vec4>(ctx_, albedoBuf, atlas.albedo);
  readback<glm::vec4>(ctx_, radianceBuf, atlas.radiance);
  std::vector<uint32_t> count(1 + VirOptions::kMaxFillPasses);
  readback<uint32_t>(ctx_, counters, count);
  atlas.holeFractionBeforeFill = double(count[0]) / double(texels);
  atlas.holeFractionAfterFill = double(count[size_t(o.fillPasses)]) / double(texels);
  return atlas;
}

}  // namespace lfgi::gpu
