// GPU pass: View-Independent Rasterization (Marrs, Watson & Healey, EG 2017) of a surfel cloud into the
// octahedral maps of many probes at once — splat (shaders/vir_splat.comp), resolve (vir_resolve.comp)
// and hole fill (vir_holefill.comp). The depth test is a 64-bit atomicMin on (depth bits << 32 | surfel
// index), so the device needs shaderBufferInt64Atomics.
//
// Two splat paths (VirOptions::lod):
//   off: every surfel into every probe (vir_splat.comp; one invocation per (surfel, probe) pair).
//   on (default): a surfel LOD tree (gpu/vir_lod.h, built once per surfel set and kept resident) is cut
//     per block of nearby probes at the coarsest nodes whose disc stays below lodTexels texels, or whose
//     projected area stays that small when the whole block sees them obliquely (lodElongation), in
//     vir_lod_cut.comp, and only the cut is splatted (vir_lod_splat.comp, node-major within a block).
//     Far surfels cover a tiny fraction of a texel, so most (surfel, probe) pairs of the full splat only
//     lose the depth test; the cut keeps ~ texels x depth complexity discs per probe. Merged discs carry
//     the area-weighted mean radiance of their surfels (vir_lod_radiance.comp, per call, so relighting
//     stays exact in the mean; without irradiance it is the tree's area-weighted emission, no pass).
//     Blocks are runs of lodBlockProbes probes along a Morton curve of their positions
//     (virProbeBlockOrder: 2 x 2 x 2 probes of a grid, not a row of 8), whatever the order given.
//
// Buffers are resident in the VirPass and grow only (no per-call allocation once the largest run has
// been seen); the LOD tree and the surfel upload are reused while the surfel array's bytes and the
// footprintScale stay the same (a memcmp per call).
//
// Channels per probe, N x N texels each (octahedral, no border, shared/octahedral.h texel convention):
//   distance: (r, r^2), r = distance along the texel-centre ray to the nearest surfel disc it hits
//   normal:   xyz the surfel normal, w the coverage (0 hole, 1 covered, p + 2 filled by fill pass p)
//   albedo, radiance: rgb (radiance = emission + albedo * E / pi, E the per-surfel irradiance input)
#pragma once

#include <glm/glm.hpp>

#include <span>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/program.h"
#include "gpu/vir_lod.h"
#include "shared/surfel.h"
#include "shared/vir.h"

namespace lfgi::gpu {

class GpuTimer;

struct VirOptions {
  int resolution = 16;          // N
  float maxRange = 64.0f;       // m; surfels farther from a probe are not splatted into it
  float footprintScale = 1.3f;  // disc radius multiplier of the footprint test (see vir_splat.comp)
  int maxFootprintRadius =
      6;               // full splat (lod off): window half-size in texels (up to 13 x 13, near surfels only)
  int fillPasses = 2;  // hole fill passes (enclosed gaps only), 0..kMaxFillPasses
  // Hole fill: an enclosed hole is filled only when the splat found its texel-centre ray within
  // max(footprintScale, fillNearMiss) disc radii of some disc (a crack, not a window; shared/vir.h
  // LFGI_VIR_NEAR_MISS_SLOT). 0: every enclosed hole.
  float fillNearMiss = 1.5f;
  bool lod = true;         // splat a per-probe-block cut of the surfel LOD tree (see above)
  float lodTexels = 4.0f;  // LOD: a merged node may stand in for its surfels when <= this many texels wide
  // LOD: a foreshortened merged node (seen obliquely from every probe of the block) may be up to this x
  // lodTexels wide while its projected area stays within a lodTexels-wide node's; [1, 8], 1: the width
  // test alone (shared/vir.h virLodClassify)
  float lodElongation = 2.0f;
  int lodBlockProbes = 16;  // LOD: probes sharing one cut (consecutive along a Morton curve), [1, 32];
                            // 16 (2 x 2 x 4 of a grid) since the node-major splat: as fast as 8 and a
                            // finer cut (city cell, N = 8: texels > 5 % off 6.7 -> 3.4 %)
  float lodDepthTolerance = 0.01f;  // LOD: merged node thickness <= this x distance (relative depth error)
  // LOD: occlusion culling. > 0: cut and splat the nodes within this range (m) of each probe block first,
  // build a max-depth pyramid per probe map, then cut and splat the rest, dropping subtrees and pairs
  // hidden behind what the first pass drew (shared/vir.h LFGI_VIR_LOD_PASS_*). Exact: the output is
  // bit-identical to a run without it. 0 (or >= maxRange): one pass.
  float lodOcclusionRange = 0.0f;
  // Relighting: when the surfels (bytes), the probes and every option above but fillPasses equal the
  // previous run's, that run's per-texel winners (the 64-bit depth | node slots) still hold, so the clear,
  // cut and splat are skipped and only node radiance, resolve and fill run again with the new irradiance:
  // bit-identical to a fresh splat (the winners do not depend on irradiance). false: always splat
  // (benchmarks of the splat itself).
  bool reuseSplat = true;
  static constexpr int kMaxFillPasses = 8;

  // The ranges VirPass::run takes (finite floats, counts and sizes in range). Throws lfgi::Error naming
  // the bad field and its value.
  void validate() const;
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
  double splatMs = 0.0, resolveMs = 0.0, fillMs = 0.0;  // LOD: splatMs includes the cut
  double lodRadianceMs =
      0.0;  // LOD: per-node radiance (leaves + merged discs), inside gpuMs; 0 without irradiance
  double lodBuildMs = 0.0;  // LOD: CPU build + upload of the tree in this call (0 when reused), not in gpuMs
  uint64_t lodNodes = 0;    // LOD: nodes in the tree (leaves + merged)
  uint64_t splatPairs = 0;  // (disc, probe) pairs the splat visited: surfels x probes without LOD
  uint64_t splatAtomics = 0;      // LOD: 64-bit atomicMin calls counted on the device; 0 without LOD
  uint64_t splatTexelTests = 0;   // LOD: texel-centre ray / footprint tests of the splat (device count)
  uint64_t splatWindowPairs = 0;  // LOD: front-facing pairs splatted through the wrapped square window
  uint64_t occludedNodes = 0;     // LOD occlusion culling: far-pass cut nodes / subtrees dropped per block
  uint64_t occludedPairs = 0;     // LOD occlusion culling: far-pass (node, probe) pairs the splat dropped
  bool splatReused = false;       // VirOptions::reuseSplat hit: the previous run's winners; the splat
                                  // counters above are that run's, splatMs ~0
};

// The fields of shared::VirLodParams that shared/vir.h virLodClassify reads (res, maxRange, footprintScale,
// lodTexels, lodElongation, depthTolerance) from the options: what the CPU cut replay gpu::virLodCut takes.
shared::VirLodParams virLodClassifyParams(const VirOptions& o);

class VirPass {
 public:
  // Throws lfgi::Error if the device lacks 64-bit buffer atomics.
  explicit VirPass(Context& ctx);

  // Uploads, splats, resolves, fills, waits and reads back. surfelIrradiance: one irradiance E (rgb) per
  // surfel, or empty for zero (radiance = emission). Throws lfgi::Error on empty input, bad options,
  // a mismatched irradiance count, or a grid beyond the device's dispatch limits.
  ProbeAtlas run(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> probes,
                 const VirOptions& options, std::span<const glm::vec4> surfelIrradiance = {});

  // True when the two option sets give the same splat winners (every field but fillPasses / reuseSplat).
  static bool sameSplat(const VirOptions& a, const VirOptions& b);

 private:
  struct RunState;  // what the stages of one run() share (vir_pass.cpp)
  // Empty input, bad options (VirOptions::validate), a mismatched irradiance count or dispatch limits.
  void checkInputs(std::span<const shared::Surfel> surfels, std::span<const glm::vec3> probes,
                   const VirOptions& options, std::span<const glm::vec4> surfelIrradiance) const;
  // Uploads surfels and (LOD) builds the tree unless the cached copy matches; returns build ms.
  double prepareSurfels(std::span<const shared::Surfel> surfels, const VirOptions& options);
  // Probes (LOD: in block order) and irradiance (LOD: in leaf order) into their buffers.
  void uploadProbes(RunState& s, std::span<const glm::vec4> surfelIrradiance);
  // LOD: the probe blocks, the cut parameters and (occlusion culling) the HiZ layout.
  void prepareLodBlocks(RunState& s, ProbeAtlas& atlas);
  // Records and submits the whole run; LOD: again with a larger cut buffer while a block's cut overflows.
  void splatUntilTheCutFits(RunState& s, GpuTimer& timer);
  void recordClearsAndRadiance(RunState& s, VkCommandBuffer cmd);
  void recordSplat(RunState& s, VkCommandBuffer cmd);
  void recordLodCutAndSplat(RunState& s, VkCommandBuffer cmd, uint32_t pass);
  void recordResolve(RunState& s, VkCommandBuffer cmd);
  void recordFill(RunState& s, VkCommandBuffer cmd);
  // Splat counters, the kept splat (reuseSplat), timings and the readback of the maps.
  void finishAtlas(const RunState& s, const GpuTimer& timer, ProbeAtlas& atlas);
  void grow(Buffer& buffer, size_t bytes);
  Context& ctx_;
  Program splat_;
  Program resolve_;
  Program holefill_;
  Program lodRadiance_;
  Program lodCut_;
  Program lodSplat_;
  Program lodSplatFar_;  // the far pass of occlusion culling (vir_lod_splat_far.comp)
  Program lodResolve_;
  Program lodHiz_;
  // Resident state, reused across calls.
  std::vector<shared::Surfel> cachedSurfels_;
  bool cachedUploaded_ = false;   // surfelBuf_ holds cachedSurfels_
  float cachedLodScale_ = -1.0f;  // footprintScale of the resident tree; < 0: none
  VirLodTree tree_;
  uint32_t cutCapacity_ = 0;  // cut entries per block, grown when a block's cut overflows
  // The splat that slots_ holds (VirOptions::reuseSplat): valid until the surfels, probes or options change.
  bool splatValid_ = false;
  VirOptions splatOptions_;
  std::vector<glm::vec4> splatProbes_;
  std::vector<uint64_t> splatStats_;  // its LOD device counters (statsBuf_)
  Buffer surfelBuf_, probeBuf_, irrBuf_, slots_, distBuf_, normalBuf_, albedoBuf_, radianceBuf_;
  Buffer nodeBuf_, linkBuf_, cutNodeBuf_, childBuf_, rectBuf_, todoBuf_, nodeRadianceBuf_, blockBuf_, cutBuf_,
      cutCountBuf_, statsBuf_, boundsBuf_, hizBuf_;
};

}  // namespace lfgi::gpu
