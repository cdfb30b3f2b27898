// Surfel level-of-detail hierarchy for VIR (gpu/vir_pass.h with VirOptions::lod): a tree whose leaves are
// the surfels and whose inner nodes are merged discs, so a probe can splat a "cut" through it — per
// subtree the coarsest node whose disc stays below ~1 texel of the probe's map — instead of every surfel.
// Point-based GI does the same for far geometry (Christensen 2008, "Point-Based Approximate Color
// Bleeding"; Bunnell 2005): per-probe work then scales with the map's texels x depth complexity, not
// with the cell's surfel count. Pure CPU (no Vulkan): built once per surfel set, uploaded by VirPass.
//
// Construction (deterministic): surfels sorted by (dominant normal axis, 30-bit Morton code of the
// position in the cloud's bounding cube); level l groups the previous level's nodes that share the key
// with its 3 l low bits dropped (an octree per normal class, at most 8 children per node; a group of one
// is passed up unchanged), until one root remains. An inner node's disc: area-weighted centroid, normal,
// albedo and emission; area = sum of the children's; radius = the bounding radius of the children's
// footprint discs (max |c_i - c| + r_i x footprintScale) divided by footprintScale, so the splat's
// `radius x footprintScale` covers every child disc. Nodes whose children are not one plane (normal cone
// > coherentConeDeg or thickness > coherentThickness x footprint radius) are flagged incoherent and
// always refined: merging a building corner or two floors into one disc would put a surface where there
// is none.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "shared/surfel.h"
#include "shared/vir.h"

namespace lfgi::gpu {

struct VirLodBuildOptions {
  float footprintScale = 1.5f;     // as VirOptions::footprintScale (inner radii are stored divided by it)
  float coherentConeDeg = 18.0f;   // max angle between an inner node's normal and any leaf normal below it
  float coherentThickness = 0.2f;  // max plane deviation of the leaves below, x the node's footprint radius
};

struct VirLodTree {
  // Leaves first (node i < leafCount is surfel leafSurfel[i], in key order), then inner nodes level by
  // level; the root is the last node. Inner node radius: footprint radius / footprintScale; normal.w: area.
  std::vector<shared::Surfel> nodes;
  std::vector<shared::VirLodLink> links;  // one per node
  std::vector<uint32_t> children;         // node indices, referenced by links[i].firstChild/childCount
  std::vector<uint32_t> levelStart;       // level l = nodes [levelStart[l], levelStart[l + 1]); level 0: leaves
  uint32_t leafCount = 0;
  uint32_t root() const { return uint32_t(nodes.size() - 1); }
  int maxDepth = 0;  // longest root-to-leaf path, in edges
  // The cut walk is split into independent walks of small subtrees (vir_lod_cut.comp): `frontier` holds
  // their roots (every subtree of <= kFrontierSubtree nodes whose parent's is larger, in depth-first
  // order); up[i] = (parent or ~0u, for a node above the frontier: the index in `frontier` of the first
  // frontier node below it, which emits the node when the walk stops there; else ~0u).
  static constexpr uint32_t kFrontierSubtree = 2048;
  std::vector<uint32_t> frontier;
  std::vector<glm::uvec2> up;
};

// Throws lfgi::Error on an empty cloud, non-finite positions or radii, or more than 2^31 surfels.
VirLodTree buildVirLodTree(std::span<const shared::Surfel> surfels, const VirLodBuildOptions& options = {});

}  // namespace lfgi::gpu
