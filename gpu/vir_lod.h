// Surfel level-of-detail hierarchy for VIR (gpu/vir_pass.h with VirOptions::lod): a tree whose leaves are
// the surfels and whose inner nodes are merged discs, so a probe can splat a "cut" through it — per
// subtree the coarsest node whose disc stays below ~1 texel of the probe's map — instead of every surfel.
// Point-based GI does the same for far geometry (Christensen 2008, "Point-Based Approximate Color
// Bleeding"; Bunnell 2005): per-probe work then scales with the map's texels x depth complexity, not
// with the cell's surfel count. Pure CPU (no Vulkan): built once per surfel set, uploaded by VirPass.
//
// Construction (deterministic): surfels sorted by (dominant normal axis, plane offset dot(n, p) in 4096
// buckets, 30-bit Morton code of the position in the cloud's bounding cube); level l groups the previous
// level's nodes that share the key with its 3 l low bits dropped (an octree per normal class and plane,
// at most 8 children per node; a group of one is passed up unchanged), until one root remains. An inner node
// is a rectangle in the plane through the area-weighted centroid with the area-weighted normal: the bounding
// box, in a frame whose first axis is a world axis projected into the plane, of its children's footprints
// (leaf discs of radius r x footprintScale, child rectangles), so it covers every surfel footprint below it,
// and its edges follow the axis-aligned walls of the city (a bounding disc overhung building edges by ~0.2 of
// its size and put surfaces in front of the sky). Albedo and emission are area-weighted (albedo.a: the cosine
// of the normal cone, the largest angle between the node normal and a leaf normal below, capped at 90
// degrees; leaves 1), area the children's sum; radius = the rectangle's half diagonal / footprintScale
// (bounds its angular size); emission.a = thickness, the largest distance of a leaf centre from the plane
// (the cut only splats a node whose thickness is small next to its distance). Nodes whose normal cone exceeds
// coherentConeDeg are flagged incoherent and always refined: a building corner merged into one rectangle
// would put a surface where there is none.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "shared/surfel.h"
#include "shared/vir.h"

namespace lfgi::gpu {

struct VirLodBuildOptions {
  float footprintScale = 1.3f;    // as VirOptions::footprintScale (inner radii are stored divided by it)
  float coherentConeDeg = 18.0f;  // max angle between an inner node's normal and any leaf normal below it
};

struct VirLodTree {
  // Leaves first (node i < leafCount is surfel leafSurfel[i], in key order), then inner nodes level by
  // level; the root is the last node. Inner node radius: footprint radius / footprintScale; normal.w: area.
  std::vector<shared::Surfel> nodes;
  std::vector<shared::VirLodLink> links;  // one per node
  // One per node: inner (octEncode(t1).xy, half extent along t1, along t2 = cross(normal, t1)), centred
  // at the node position; leaves (0, 0, -1, -1): a disc of radius r x footprintScale.
  std::vector<glm::vec4> rects;
  // One per node: radius of a sphere about the node centre that holds every footprint of its subtree
  // (leaf discs at footprintScale, the node's and its descendants' rectangles): occlusion culling of
  // whole subtrees (vir_lod_cut.comp's far pass).
  std::vector<float> bounds;
  std::vector<uint32_t> children;    // node indices, referenced by links[i].firstChild/childCount
  std::vector<uint32_t> levelStart;  // level l = nodes [levelStart[l], levelStart[l + 1]); level 0: leaves
  uint32_t leafCount = 0;
  uint32_t root() const { return uint32_t(nodes.size() - 1); }
  int maxDepth = 0;  // longest root-to-leaf path, in edges
  // The cut walk is split into independent walks of small subtrees (vir_lod_cut.comp): `frontier` holds
  // their roots (every subtree of <= kFrontierSubtree nodes whose parent's is larger, in depth-first
  // order); up[i] = (parent or ~0u, for a node above the frontier: the index in `frontier` of the first
  // frontier node below it; else ~0u). The cut's top stage walks the nodes with up[i].y != ~0u
  // (cutNodes' LFGI_VIR_LOD_ABOVE_FRONTIER) and lists the frontier subtrees it reaches; frontier.size()
  // bounds that list.
  static constexpr uint32_t kFrontierSubtree = 2048;
  std::vector<uint32_t> frontier;
  std::vector<glm::uvec2> up;
  // One per node: what the cut reads (shared/vir.h VirLodCutNode: centre, radius, normal cone, thickness,
  // flags with LFGI_VIR_LOD_ABOVE_FRONTIER) and the first-child / skip links of its stackless walk.
  std::vector<shared::VirLodCutNode> cutNodes;
};

// Throws lfgi::Error on an empty cloud, non-finite positions or radii, or more than 2^31 surfels.
VirLodTree buildVirLodTree(std::span<const shared::Surfel> surfels, const VirLodBuildOptions& options = {});

// Probe indices sorted along a Morton curve of the positions (10 bits per axis over their bounding cube;
// ties by index): runs of consecutive entries are spatially compact, e.g. 2 x 2 x 2 probes of a grid
// (VirPass's probe blocks). A permutation of [0, probes.size()); deterministic.
std::vector<uint32_t> virProbeBlockOrder(std::span<const glm::vec3> probes);

// The cut's bounds of a probe block (VirPass's blocks, the CPU replay's): centroid, radius and per-axis
// extents about the centroid, padded by 1e-4 relative + 1e-6 m against rounding. Empty span: throws.
shared::VirLodBlock virLodBlock(std::span<const glm::vec3> probes);

// CPU replay of vir_lod_cut.comp for one probe block (virLodBlock): the nodes the walk emits
// (shared/vir.h virLodClassify; depth first, the device's order differs and the splat ignores it). params:
// the fields virLodClassify reads (gpu::virLodClassifyParams). The same stackless walk over
// VirLodTree::cutNodes as the device's, in one stage.
std::vector<uint32_t> virLodCut(const VirLodTree& tree, const shared::VirLodBlock& block,
                                const shared::VirLodParams& params);

}  // namespace lfgi::gpu
