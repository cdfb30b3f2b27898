#include "gpu/vir_pass.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "gpu/timing.h"

namespace lfgi::gpu {

namespace {

Program requireInt64Atomics(Context& ctx, const char* name) {
  if (!ctx.features.shaderBufferInt64Atomics)
    fail("VIR: device '{}' lacks shaderBufferInt64Atomics (64-bit buffer atomics)", ctx.info.name);
  return Program(ctx, name);
}

constexpr size_t kMaxCutEntries = size_t(1) << 24;  // per batch of blocks (64 MiB of node indices)
constexpr size_t kLodStats =
    8;  // counters of vir_lod_cut.comp / vir_lod_splat.comp (see their Stats buffers)

}  // namespace

VirPass::VirPass(Context& ctx)
    : ctx_(ctx),
      splat_(requireInt64Atomics(ctx, "vir_splat")),
      resolve_(ctx, "vir_resolve"),
      holefill_(ctx, "vir_holefill"),
      lodRadiance_(ctx, "vir_lod_radiance"),
      lodCut_(ctx, "vir_lod_cut"),
      lodSplat_(ctx, "vir_lod_splat"),
      lodSplatFar_(ctx, "vir_lod_splat_far"),
      lodResolve_(ctx, "vir_lod_resolve"),
      lodHiz_(ctx, "vir_lod_hiz") {}

void VirPass::grow(Buffer& buffer, size_t bytes) {
  bytes = std::max<size_t>(bytes, 16);
  if (buffer.handle() == VK_NULL_HANDLE || buffer.size() < bytes) buffer = createStorageBuffer(ctx_, bytes);
}

shared::VirLodParams virLodClassifyParams(const VirOptions& o) {
  shared::VirLodParams lp{};
  lp.res = uint32_t(o.resolution);
  lp.maxRange = o.maxRange;
  lp.footprintScale = o.footprintScale;
  lp.lodTexels = o.lodTexels;
  lp.lodElongation = o.lodElongation;
  lp.depthTolerance = o.lodDepthTolerance;
  return lp;
}

bool VirPass::sameSplat(const VirOptions& a, const VirOptions& b) {
  return a.resolution == b.resolution && a.maxRange == b.maxRange && a.footprintScale == b.footprintScale &&
         a.maxFootprintRadius == b.maxFootprintRadius && a.lod == b.lod && a.lodTexels == b.lodTexels &&
         a.lodElongation == b.lodElongation && a.lodBlockProbes == b.lodBlockProbes &&
         a.lodDepthTolerance == b.lodDepthTolerance && a.lodOcclusionRange == b.lodOcclusionRange &&
         a.fillNearMiss == b.fillNearMiss;
}

double VirPass::prepareSurfels(std::span<const shared::Surfel> surfels, const VirOptions& o) {
  const bool same = cachedSurfels_.size() == surfels.size() &&
                    std::memcmp(cachedSurfels_.data(), surfels.data(), surfels.size_bytes()) == 0;
  if (!same) {
    cachedSurfels_.assign(surfels.begin(), surfels.end());
    cachedUploaded_ = false;
    cachedLodScale_ = -1.0f;
    splatValid_ = false;
  }
  if (!o.lod) {
    if (!cachedUploaded_) {
      grow(surfelBuf_, surfels.size_bytes());
      upload<shared::Surfel>(ctx_, surfelBuf_, surfels);
      cachedUploaded_ = true;
    }
    return 0.0;
  }
  if (cachedLodScale_ == o.footprintScale) return 0.0;
  const auto t0 = std::chrono::steady_clock::now();
  VirLodBuildOptions bo;
  bo.footprintScale = o.footprintScale;
  tree_ = buildVirLodTree(surfels, bo);
  grow(nodeBuf_, tree_.nodes.size() * sizeof(shared::Surfel));
  grow(linkBuf_, tree_.links.size() * sizeof(shared::VirLodLink));
  grow(childBuf_, tree_.children.size() * sizeof(uint32_t));
  grow(nodeRadianceBuf_, tree_.nodes.size() * sizeof(glm::vec4));
  grow(rectBuf_, tree_.rects.size() * sizeof(glm::vec4));
  upload<glm::vec4>(ctx_, rectBuf_, tree_.rects);
  grow(boundsBuf_, tree_.bounds.size() * sizeof(float));
  upload<float>(ctx_, boundsBuf_, tree_.bounds);
  upload<shared::Surfel>(ctx_, nodeBuf_, tree_.nodes);
  upload<shared::VirLodLink>(ctx_, linkBuf_, tree_.links);
  grow(cutNodeBuf_, tree_.cutNodes.size() * sizeof(shared::VirLodCutNode));
  upload<shared::VirLodCutNode>(ctx_, cutNodeBuf_, tree_.cutNodes);
  if (!tree_.children.empty()) upload<uint32_t>(ctx_, childBuf_, tree_.children);
  cachedLodScale_ = o.footprintScale;
  splatValid_ = false;
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void VirOptions::validate() const {
  if (resolution < 1 || resolution > 1024) fail("VIR: resolution {} outside [1, 1024]", resolution);
  if (!(std::isfinite(maxRange) && maxRange > 0.0f))
    fail("VIR: maxRange {} must be finite and > 0", maxRange);
  if (!(std::isfinite(footprintScale) && footprintScale > 0.0f))
    fail("VIR: footprintScale {} must be finite and > 0", footprintScale);
  if (maxFootprintRadius < 0 || maxFootprintRadius > 8)
    fail("VIR: maxFootprintRadius {} outside [0, 8]", maxFootprintRadius);
  if (fillPasses < 0 || fillPasses > kMaxFillPasses)
    fail("VIR: fillPasses {} outside [0, {}]", fillPasses, kMaxFillPasses);
  if (!(std::isfinite(fillNearMiss) && fillNearMiss >= 0.0f))
    fail("VIR: fillNearMiss {} must be finite and >= 0", fillNearMiss);
  if (!(std::isfinite(lodTexels) && lodTexels > 0.0f && lodTexels <= 16.0f))
    fail("VIR: lodTexels {} outside (0, 16]", lodTexels);
  if (!(std::isfinite(lodElongation) && lodElongation >= 1.0f && lodElongation <= 8.0f))
    fail("VIR: lodElongation {} outside [1, 8]", lodElongation);
  if (!(std::isfinite(lodDepthTolerance) && lodDepthTolerance >= 0.0f && lodDepthTolerance <= 1.0f))
    fail("VIR: lodDepthTolerance {} outside [0, 1]", lodDepthTolerance);
  if (lodBlockProbes < 1 || lodBlockProbes > LFGI_VIR_LOD_MAX_BLOCK_PROBES)
    fail("VIR: lodBlockProbes {} outside [1, {}]", lodBlockProbes, LFGI_VIR_LOD_MAX_BLOCK_PROBES);
  if (!(std::isfinite(lodOcclusionRange) && lodOcclusionRange >= 0.0f))
    fail("VIR: lodOcclusionRange {} must be finite and >= 0", lodOcclusionRange);
}

// What the stages of one run share: the options, the probes as uploaded, the push constants and the LOD
// batching.
struct VirPass::RunState {
  const VirOptions& o;
  std::span<const shared::Surfel> surfels;
  std::span<const glm::vec3> probes;
  size_t n2 = 0, texels = 0;
  bool lit = false;               // per-surfel irradiance given
  std::vector<glm::vec4> probe4;  // w: the probe's index in the caller's list
  shared::VirParams params{};
  uint32_t res = 0, probeCount = 0;
  shared::VirLodParams lp{};
  size_t blockCount = 0, batchBlocks = 0;
  bool occlusion = false;
  uint32_t hizLevels = 0;
  bool reuse = false;  // slots_ holds this run's splat already
};

void VirPass::checkInputs(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> probes,
                          const VirOptions& o, std::span<const glm::vec4> surfelIrradiance) const {
  if (surfels.empty() || probes.empty())
    fail("VIR: {} surfels, {} probes: need at least one of each", surfels.size(), probes.size());
  o.validate();
  if (!surfelIrradiance.empty() && surfelIrradiance.size() != surfels.size())
    fail("VIR: {} surfel irradiance values for {} surfels", surfelIrradiance.size(), surfels.size());
  const uint32_t* maxGroups = ctx_.properties.limits.maxComputeWorkGroupCount;
  const uint64_t splatGroupsX = (surfels.size() + 63) / 64;
  const uint64_t mapGroups = (uint64_t(o.resolution) + 7) / 8;
  if ((!o.lod && (splatGroupsX > maxGroups[0] || probes.size() > maxGroups[1])) ||
      probes.size() > maxGroups[2] || surfels.size() > 0x7FFFFFFFull || mapGroups > maxGroups[0])
    fail("VIR: {} surfels x {} probes exceeds the device's dispatch limits ({}, {}, {} workgroups)",
         surfels.size(), probes.size(), maxGroups[0], maxGroups[1], maxGroups[2]);
}

void VirPass::uploadProbes(RunState& s, std::span<const glm::vec4> surfelIrradiance) {
  const VirOptions& o = s.o;
  const std::span<const shared::Surfel> surfels = s.surfels;
  const std::span<const glm::vec3> probes = s.probes;
  const size_t texels = s.texels;
  // LOD: probes in block order (a Morton curve, so each block of consecutive entries is compact), w = the
  // probe's index in the caller's list (its map); the full splat keeps the caller's order.
  if (o.lod && probes.size() > (size_t(1) << 24)) fail("VIR LOD: {} probes exceed 2^24", probes.size());
  const std::vector<uint32_t> order = o.lod ? virProbeBlockOrder(probes) : std::vector<uint32_t>{};
  std::vector<glm::vec4>& probe4 = s.probe4;
  probe4.resize(probes.size());
  for (size_t i = 0; i < probes.size(); ++i) {
    const uint32_t k = o.lod ? order[i] : uint32_t(i);
    probe4[i] = glm::vec4(probes[k], float(k));
  }
  grow(probeBuf_, probe4.size() * sizeof(glm::vec4));
  grow(irrBuf_, surfels.size() * sizeof(glm::vec4));
  grow(slots_, texels * sizeof(uint64_t));
  grow(distBuf_, texels * sizeof(glm::vec2));
  grow(normalBuf_, texels * sizeof(glm::vec4));
  grow(albedoBuf_, texels * sizeof(glm::vec4));
  grow(radianceBuf_, texels * sizeof(glm::vec4));
  upload<glm::vec4>(ctx_, probeBuf_, probe4);
  // Without irradiance every radiance is the emission: the LOD path then reads the nodes' area-weighted
  // emission (built with the tree, the radiance pass's answer for E = 0) and runs no radiance pass. With
  // it, the LOD leaf pass reads E in leaf order (uploaded so: a streaming read, not a gather per leaf).
  s.lit = !surfelIrradiance.empty();
  const bool lit = s.lit;
  if (lit && o.lod) {
    std::vector<glm::vec4> leafIrradiance(tree_.leafCount);
    for (uint32_t i = 0; i < tree_.leafCount; ++i)
      leafIrradiance[i] = surfelIrradiance[tree_.links[i].surfel];
    upload<glm::vec4>(ctx_, irrBuf_, leafIrradiance);
  } else if (lit) {
    upload<glm::vec4>(ctx_, irrBuf_, surfelIrradiance);
  }
}

void VirPass::prepareLodBlocks(RunState& s, ProbeAtlas& atlas) {
  const VirOptions& o = s.o;
  const std::span<const glm::vec3> probes = s.probes;
  shared::VirLodParams& lp = s.lp;
  // LOD: probe blocks (consecutive probes in block order, virLodBlock bounds) and the cut buffer.
  lp = virLodClassifyParams(o);
  lp.fillNearMiss = s.params.fillNearMiss;
  if (o.lod) {
    const size_t bp = size_t(o.lodBlockProbes);
    s.blockCount = (probes.size() + bp - 1) / bp;
    const size_t blockCount = s.blockCount;
    std::vector<shared::VirLodBlock> blocks(blockCount);
    std::vector<glm::vec3> inBlock;
    for (size_t b = 0; b < blockCount; ++b) {
      inBlock.clear();
      for (size_t i = b * bp; i < std::min(probes.size(), (b + 1) * bp); ++i)
        inBlock.push_back(glm::vec3(s.probe4[i]));
      blocks[b] = virLodBlock(inBlock);
    }
    grow(blockBuf_, blocks.size() * sizeof(shared::VirLodBlock));
    upload<shared::VirLodBlock>(ctx_, blockBuf_, blocks);
    // First guess 128 N^2 entries per block: a block of a city cell at N = 16 cuts ~30 k nodes, and an
    // overflow redoes the whole run (16 N^2 cost one extra run per new VirPass on a 15 k-probe cell).
    if (cutCapacity_ == 0) cutCapacity_ = uint32_t(std::clamp<size_t>(128 * s.n2, 4096, kMaxCutEntries));
    grow(cutCountBuf_, 2 * blockCount * sizeof(uint32_t));  // cut and todo entries per block of a batch
    grow(statsBuf_, kLodStats * sizeof(uint64_t));
    lp.probeCount = s.probeCount;
    lp.blockProbes = uint32_t(bp);
    lp.rootNode = tree_.root();
    lp.nearRange = o.lodOcclusionRange;
    atlas.lodNodes = tree_.nodes.size();
  }
  // Occlusion culling: HiZ levels 1..top (top: 1 x 1), hizProbeTexels uints per probe map.
  s.occlusion = o.lod && o.lodOcclusionRange > 0.0f && o.lodOcclusionRange < o.maxRange;
  if (s.occlusion) {
    if (tree_.nodes.size() >= (size_t(1) << 31)) fail("VIR LOD: {} nodes exceed 2^31", tree_.nodes.size());
    for (uint32_t dim = s.res; dim > 1; ++s.hizLevels) {
      dim = (dim + 1) / 2;
      lp.hizProbeTexels += dim * dim;
    }
  }
  if (o.lod)
    grow(hizBuf_, size_t(lp.hizProbeTexels) * s.probeCount * sizeof(uint32_t));  // bound even when unused
}

ProbeAtlas VirPass::run(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> probes,
                        const VirOptions& o, std::span<const glm::vec4> surfelIrradiance) {
  checkInputs(surfels, probes, o, surfelIrradiance);

  ProbeAtlas atlas;
  atlas.lodBuildMs = prepareSurfels(surfels, o);
  RunState s{o, surfels, probes};
  s.n2 = size_t(o.resolution) * size_t(o.resolution);
  s.texels = s.n2 * probes.size();
  uploadProbes(s, surfelIrradiance);

  shared::VirParams& params = s.params;
  params.probeCount = uint32_t(probes.size());
  params.res = uint32_t(o.resolution);
  params.surfelCount = uint32_t(surfels.size());
  params.maxFootprintRadius = uint32_t(o.maxFootprintRadius);
  params.maxRange = o.maxRange;
  params.footprintScale = o.footprintScale;
  params.emissionOnly = s.lit ? 0u : 1u;
  params.fillNearMiss = o.fillNearMiss;
  s.res = params.res;
  s.probeCount = params.probeCount;

  prepareLodBlocks(s, atlas);

  s.reuse = o.reuseSplat && splatValid_ && sameSplat(o, splatOptions_) && splatProbes_ == s.probe4;
  splatValid_ = splatValid_ && s.reuse;  // this run overwrites slots_ unless it reuses them
  GpuTimer timer(ctx_, 5);
  splatUntilTheCutFits(s, timer);
  finishAtlas(s, timer, atlas);
  return atlas;
}

void VirPass::splatUntilTheCutFits(RunState& s, GpuTimer& timer) {
  const VirOptions& o = s.o;
  shared::VirLodParams& lp = s.lp;
  const uint32_t* maxGroups = ctx_.properties.limits.maxComputeWorkGroupCount;
  for (;;) {
    if (o.lod) {
      s.batchBlocks = std::clamp<size_t>(kMaxCutEntries / cutCapacity_, 1, s.blockCount);
      s.batchBlocks = std::min<size_t>(s.batchBlocks, std::min(maxGroups[1], maxGroups[2]));
      grow(cutBuf_, s.batchBlocks * cutCapacity_ * sizeof(uint32_t));
      grow(todoBuf_, s.batchBlocks * tree_.frontier.size() * sizeof(uint32_t));
      lp.cutCapacity = cutCapacity_;
      // Splat invocations per block: about <= 512 (cut entry, probe) pairs each (llvmpipe's loop limit,
      // see the shader).
      const uint32_t entriesPerLane = std::max(1u, 512u / lp.blockProbes);
      lp.lanes = std::clamp((cutCapacity_ / entriesPerLane + 63) / 64 * 64, 64u, 8192u);
    }
    submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
      timer.reset(cmd);
      timer.stamp(cmd, 0);
      recordClearsAndRadiance(s, cmd);
      timer.stamp(cmd, 1);
      recordSplat(s, cmd);
      timer.stamp(cmd, 2);
      recordResolve(s, cmd);
      timer.stamp(cmd, 3);
      recordFill(s, cmd);
      timer.stamp(cmd, 4);
    });
    if (!o.lod || s.reuse) break;
    std::array<uint64_t, kLodStats> stats{};
    readback<uint64_t>(ctx_, statsBuf_, stats);
    if (stats[3] == 0) {
      splatStats_.assign(stats.begin(), stats.end());
      break;
    }
    if (cutCapacity_ >= kMaxCutEntries)
      fail(
          "VIR LOD: a probe block's cut has {} nodes, more than {}: use fewer lodBlockProbes or more "
          "lodTexels",
          stats[3], kMaxCutEntries);
    spdlog::debug("VIR LOD: a probe block's cut has {} nodes, more than its {} entries: splatting again",
                  stats[3], cutCapacity_);
    cutCapacity_ = uint32_t(std::min<uint64_t>(kMaxCutEntries, stats[3] + stats[3] / 4));  // and run again
  }
}

void VirPass::recordClearsAndRadiance(RunState& s, VkCommandBuffer cmd) {
  const VirOptions& o = s.o;
  const size_t texels = s.texels;
  const bool lit = s.lit;
  shared::VirLodParams& lp = s.lp;
  if (!s.reuse) vkCmdFillBuffer(cmd, slots_.handle(), 0, texels * sizeof(uint64_t), 0xFFFFFFFFu);
  // Holes stay all 0 (LFGI_VIR_HOLE): the resolve writes only covered texels.
  vkCmdFillBuffer(cmd, distBuf_.handle(), 0, texels * sizeof(glm::vec2), 0u);
  for (Buffer* b : {&normalBuf_, &albedoBuf_, &radianceBuf_})
    vkCmdFillBuffer(cmd, b->handle(), 0, texels * sizeof(glm::vec4), 0u);
  if (!lit && !o.lod) vkCmdFillBuffer(cmd, irrBuf_.handle(), 0, VK_WHOLE_SIZE, 0u);
  if (o.lod) vkCmdFillBuffer(cmd, statsBuf_.handle(), 0, VK_WHOLE_SIZE, 0u);
  memoryBarrier(cmd);
  if (o.lod && lit) {
    // Node radiance, level by level from the leaves (children always sit in lower levels).
    for (size_t l = 0; l + 1 < tree_.levelStart.size(); ++l) {
      lp.nodeFirst = tree_.levelStart[l];
      lp.nodeCount = tree_.levelStart[l + 1] - tree_.levelStart[l];
      if (lp.nodeCount == 0) continue;
      lp.leafPass = l == 0 ? 1u : 0u;
      dispatch(ctx_, cmd, lodRadiance_, {&nodeBuf_, &linkBuf_, &childBuf_, &irrBuf_, &nodeRadianceBuf_}, lp,
               {lp.nodeCount, 1, 1});
      memoryBarrier(cmd);
    }
  }
}

void VirPass::recordSplat(RunState& s, VkCommandBuffer cmd) {
  const VirOptions& o = s.o;
  const uint32_t res = s.res, probeCount = s.probeCount;
  shared::VirLodParams& lp = s.lp;
  if (s.reuse) {
    // slots_ holds this splat's winners already.
  } else if (o.lod) {
    if (s.occlusion) {
      recordLodCutAndSplat(s, cmd, LFGI_VIR_LOD_PASS_NEAR);
      for (uint32_t l = 1, dim = res; l <= s.hizLevels; ++l) {
        dim = (dim + 1) / 2;
        lp.hizLevel = l;
        dispatch(ctx_, cmd, lodHiz_, {&slots_, &hizBuf_}, lp, {dim, dim, probeCount});
        memoryBarrier(cmd);
      }
      recordLodCutAndSplat(s, cmd, LFGI_VIR_LOD_PASS_FAR);
    } else {
      recordLodCutAndSplat(s, cmd, LFGI_VIR_LOD_PASS_ALL);
    }
  } else {
    dispatch(ctx_, cmd, splat_, {&surfelBuf_, &probeBuf_, &slots_}, s.params,
             {s.params.surfelCount, probeCount, 1});
    memoryBarrier(cmd);
  }
}

// Cut + splat of every batch of blocks for one pass (LFGI_VIR_LOD_PASS_*).
void VirPass::recordLodCutAndSplat(RunState& s, VkCommandBuffer cmd, uint32_t pass) {
  shared::VirLodParams& lp = s.lp;
  const size_t blockCount = s.blockCount, batchBlocks = s.batchBlocks;
  lp.cutPass = pass;
  for (size_t b0 = 0; b0 < blockCount; b0 += batchBlocks) {
    lp.blockFirst = uint32_t(b0);
    lp.blockCount = uint32_t(std::min(batchBlocks, blockCount - b0));
    vkCmdFillBuffer(cmd, cutCountBuf_.handle(), 0, VK_WHOLE_SIZE, 0u);
    memoryBarrier(cmd);
    lp.nodeCount = uint32_t(tree_.frontier.size());
    for (const uint32_t stage : {LFGI_VIR_LOD_STAGE_TOP, LFGI_VIR_LOD_STAGE_SUBTREES}) {
      lp.cutStage = stage;
      dispatch(ctx_, cmd, lodCut_,
               {&cutNodeBuf_, &todoBuf_, &blockBuf_, &cutBuf_, &cutCountBuf_, &statsBuf_, &probeBuf_, &slots_,
                &hizBuf_, &boundsBuf_},
               lp, {lp.blockCount, stage == LFGI_VIR_LOD_STAGE_TOP ? 1u : lp.nodeCount, 1});
      memoryBarrier(cmd);
    }
    if (pass == LFGI_VIR_LOD_PASS_FAR)
      dispatch(ctx_, cmd, lodSplatFar_,
               {&nodeBuf_, &probeBuf_, &cutBuf_, &cutCountBuf_, &slots_, &statsBuf_, &rectBuf_, &hizBuf_}, lp,
               {lp.lanes, 1, lp.blockCount});
    else
      dispatch(ctx_, cmd, lodSplat_,
               {&nodeBuf_, &probeBuf_, &cutBuf_, &cutCountBuf_, &slots_, &statsBuf_, &rectBuf_}, lp,
               {lp.lanes, 1, lp.blockCount});
    memoryBarrier(cmd);
  }
}

void VirPass::recordResolve(RunState& s, VkCommandBuffer cmd) {
  const VirOptions& o = s.o;
  const uint32_t res = s.res, probeCount = s.probeCount;
  const shared::VirParams& params = s.params;
  if (o.lod)
    dispatch(ctx_, cmd, lodResolve_,
             {&slots_, &nodeBuf_, &nodeRadianceBuf_, &distBuf_, &normalBuf_, &albedoBuf_, &radianceBuf_},
             params, {res, res, probeCount});
  else
    dispatch(ctx_, cmd, resolve_,
             {&slots_, &surfelBuf_, &irrBuf_, &distBuf_, &normalBuf_, &albedoBuf_, &radianceBuf_}, params,
             {res, res, probeCount});
  memoryBarrier(cmd);
}

void VirPass::recordFill(RunState& s, VkCommandBuffer cmd) {
  const VirOptions& o = s.o;
  const uint32_t res = s.res, probeCount = s.probeCount;
  shared::VirParams& params = s.params;
  for (int pass = 0; pass < o.fillPasses; ++pass) {
    params.fillPass = uint32_t(pass);
    dispatch(ctx_, cmd, holefill_, {&distBuf_, &normalBuf_, &albedoBuf_, &radianceBuf_, &slots_}, params,
             {res, res, probeCount});
    memoryBarrier(cmd);
  }
}

void VirPass::finishAtlas(const RunState& s, const GpuTimer& timer, ProbeAtlas& atlas) {
  const VirOptions& o = s.o;
  const size_t texels = s.texels;
  const bool reuse = s.reuse;
  if (o.lod) {  // this run's counters, or the reused splat's
    atlas.splatPairs = splatStats_[0];
    atlas.splatAtomics = splatStats_[1];
    atlas.splatTexelTests = splatStats_[4];
    atlas.splatWindowPairs = splatStats_[5];
    atlas.occludedNodes = splatStats_[6];
    atlas.occludedPairs = splatStats_[7];
  } else {
    atlas.splatPairs = uint64_t(s.surfels.size()) * s.probes.size();
  }
  atlas.splatReused = reuse;
  if (!reuse) {
    splatValid_ = true;
    splatOptions_ = o;
    splatProbes_ = s.probe4;
  }

  atlas.resolution = o.resolution;
  atlas.probeCount = int(s.probes.size());
  atlas.lodRadianceMs = o.lod && s.lit ? timer.elapsedMs(0, 1) : 0.0;
  atlas.splatMs = timer.elapsedMs(1, 2);
  atlas.resolveMs = timer.elapsedMs(2, 3);
  atlas.fillMs = timer.elapsedMs(3, 4);
  atlas.gpuMs = timer.elapsedMs(0, 4);
  atlas.distance.resize(texels);
  atlas.normal.resize(texels);
  atlas.albedo.resize(texels);
  atlas.radiance.resize(texels);
  readback<glm::vec2>(ctx_, distBuf_, atlas.distance);
  readback<glm::vec4>(ctx_, normalBuf_, atlas.normal);
  readback<glm::vec4>(ctx_, albedoBuf_, atlas.albedo);
  readback<glm::vec4>(ctx_, radianceBuf_, atlas.radiance);
  // Coverage w: 0 a hole after the fill, 1 covered by the splat, >= 2 filled (a hole before the fill).
  size_t holesAfter = 0, filled = 0;
  for (const glm::vec4& nw : atlas.normal) {
    holesAfter += nw.w == LFGI_VIR_HOLE ? 1 : 0;
    filled += nw.w > LFGI_VIR_COVERED ? 1 : 0;
  }
  atlas.holeFractionBeforeFill = double(holesAfter + filled) / double(texels);
  atlas.holeFractionAfterFill = double(holesAfter) / double(texels);
}

}  // namespace lfgi::gpu
