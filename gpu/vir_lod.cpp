#include "gpu/vir_lod.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/error.h"
#include "shared/octahedral.h"

namespace lfgi::gpu {

namespace {

uint32_t spreadBits10(uint32_t v) {  // 10 bits -> every third bit of 30
  v &= 0x3FFu;
  v = (v | (v << 16)) & 0x030000FFu;
  v = (v | (v << 8)) & 0x0300F00Fu;
  v = (v | (v << 4)) & 0x030C30C3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

uint64_t morton30(glm::vec3 p, glm::vec3 lo, float toGrid) {  // 10 bits per axis of (p - lo) * toGrid
  const glm::uvec3 q(glm::clamp((p - lo) * toGrid, glm::vec3(0.0f), glm::vec3(1023.0f)));
  return spreadBits10(q.x) | (spreadBits10(q.y) << 1) | (spreadBits10(q.z) << 2);
}

uint32_t normalClass(glm::vec3 n) {  // dominant axis and sign: 0..5
  const glm::vec3 a = glm::abs(n);
  const uint32_t axis = a.x >= a.y && a.x >= a.z ? 0u : (a.y >= a.z ? 1u : 2u);
  return axis * 2u + (n[int(axis)] < 0.0f ? 1u : 0u);
}

constexpr float kBoundsMargin = 1.0f + 1e-5f;  // VirLodTree::bounds, against rounding in the sums

struct NodeExtra {               // build-time bounds of the leaves below a node
  float footprintRadius = 0.0f;  // m, covers every leaf's footprint disc
  float coneRad = 0.0f;          // max angle between the node normal and a leaf normal below
  float thickness = 0.0f;        // m, max leaf-centre distance from the node plane
  int depth = 0;
};

struct CloudGrid {  // the Morton grid over the cloud's bounding cube
  glm::vec3 lo;
  float toGrid;
};

CloudGrid validateSurfels(std::span<const shared::Surfel> surfels, const VirLodBuildOptions& o) {
  if (surfels.empty()) fail("VIR LOD: empty surfel cloud");
  if (surfels.size() > (size_t(1) << 31)) fail("VIR LOD: {} surfels exceed 2^31", surfels.size());
  if (!(std::isfinite(o.footprintScale) && o.footprintScale > 0.0f))
    fail("VIR LOD: footprintScale {} must be finite and > 0", o.footprintScale);
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (size_t i = 0; i < surfels.size(); ++i) {
    const glm::vec4 p = surfels[i].positionRadius;
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.w) &&
          p.w >= 0.0f))
      fail("VIR LOD: surfel {} has a non-finite position or a bad radius ({}, {}, {}, r {})", i, p.x, p.y,
           p.z, p.w);
    lo = glm::min(lo, glm::vec3(p));
    hi = glm::max(hi, glm::vec3(p));
  }
  const float extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-6f});
  const float toGrid = 1023.999f / extent;
  return {lo, toGrid};
}

std::vector<std::pair<uint64_t, uint32_t>> sortLeafKeys(std::span<const shared::Surfel> surfels, glm::vec3 lo,
                                                        float toGrid) {
  // Sort key: normal class, then plane offset dot(n, p) in 4096 buckets, then the Morton code: an octree
  // level only merges surfels of one class and (below the 10 Morton levels) one plane, so parallel walls
  // a few metres apart, which the cut could never splat as one rectangle, are never mixed below the top.
  float offLo = std::numeric_limits<float>::max(), offHi = -std::numeric_limits<float>::max();
  for (const shared::Surfel& sf : surfels) {
    const float off = glm::dot(glm::vec3(sf.normal), glm::vec3(sf.positionRadius));
    offLo = std::min(offLo, off);
    offHi = std::max(offHi, off);
  }
  const float toBucket = 4095.999f / std::max(offHi - offLo, 1e-6f);
  std::vector<std::pair<uint64_t, uint32_t>> keyed(surfels.size());
  for (size_t i = 0; i < surfels.size(); ++i) {
    const glm::vec3 p(surfels[i].positionRadius), nrm(surfels[i].normal);
    const uint64_t morton = morton30(p, lo, toGrid);
    const uint64_t bucket = uint64_t(std::clamp((glm::dot(nrm, p) - offLo) * toBucket, 0.0f, 4095.0f));
    keyed[i] = {(uint64_t(normalClass(nrm)) << 42) | (bucket << 30) | morton, uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  return keyed;
}

void addLeaves(VirLodTree& tree, std::vector<NodeExtra>& extra, std::span<const shared::Surfel> surfels,
               const std::vector<std::pair<uint64_t, uint32_t>>& keyed, const VirLodBuildOptions& o) {
  tree.leafCount = uint32_t(surfels.size());
  tree.nodes.reserve(surfels.size() * 3 / 2);
  tree.links.reserve(surfels.size() * 3 / 2);
  extra.reserve(surfels.size() * 3 / 2);
  for (const auto& [key, i] : keyed) {
    shared::Surfel s = surfels[i];
    const float r = s.positionRadius.w;
    s.normal.w = std::numbers::pi_v<float> * r * r;
    s.albedo.w = 1.0f;  // cosine of the normal cone: one normal
    tree.nodes.push_back(s);
    tree.links.push_back({0u, 0u, LFGI_VIR_LOD_COHERENT, i});
    tree.rects.push_back(glm::vec4(0.0f, 0.0f, -1.0f, -1.0f));
    tree.bounds.push_back(r * o.footprintScale * kBoundsMargin);
    extra.push_back({r * o.footprintScale, 0.0f, 0.0f, 0});
  }
  tree.levelStart.push_back(0);
}

// One inner node over the nodes current[c0, c1) (2..8 of one group); appends its (key, node) to next.
void mergeChildren(VirLodTree& tree, std::vector<NodeExtra>& extra,
                   const std::vector<std::pair<uint64_t, uint32_t>>& current, size_t c0, size_t c1,
                   const VirLodBuildOptions& o, float maxCone,
                   std::vector<std::pair<uint64_t, uint32_t>>& next) {
  float area = 0.0f;
  glm::vec3 centre(0.0f), nsum(0.0f), albedo(0.0f), emission(0.0f);
  for (size_t c = c0; c < c1; ++c) {
    const shared::Surfel& ch = tree.nodes[current[c].second];
    const float a = std::max(ch.normal.w, 1e-20f);
    area += a;
    centre += a * glm::vec3(ch.positionRadius);
    nsum += a * glm::vec3(ch.normal);
    albedo += a * glm::vec3(ch.albedo);
    emission += a * glm::vec3(ch.emission);
  }
  centre /= area;
  const float nlen = glm::length(nsum);
  const glm::vec3 n = nlen > 1e-12f ? nsum / nlen : glm::vec3(tree.nodes[current[c0].second].normal);
  const glm::vec3 t1 = shared::virRectAxis(n), t2 = glm::cross(n, t1);  // rectangle frame
  NodeExtra e;
  bool coherent = nlen > 1e-12f;
  glm::vec2 lo2(std::numeric_limits<float>::max()), hi2(-std::numeric_limits<float>::max());
  const uint32_t first = uint32_t(tree.children.size());
  for (size_t c = c0; c < c1; ++c) {
    const uint32_t ci = current[c].second;
    const shared::Surfel& ch = tree.nodes[ci];
    const NodeExtra& ce = extra[ci];
    const glm::vec3 d = glm::vec3(ch.positionRadius) - centre;
    const glm::vec2 uv(glm::dot(d, t1), glm::dot(d, t2));
    glm::vec2 half(ce.footprintRadius);  // a leaf disc (or its projection) lies within +-r
    const glm::vec4 cr = tree.rects[ci];
    if (cr.z >= 0.0f) {  // a child rectangle: its half axes projected onto t1, t2
      const glm::vec3 ct1 = shared::octDecode(glm::vec2(cr.x, cr.y));
      const glm::vec3 ct2 = glm::cross(glm::vec3(ch.normal), ct1);
      half = glm::vec2(cr.z * std::abs(glm::dot(ct1, t1)) + cr.w * std::abs(glm::dot(ct2, t1)),
                       cr.z * std::abs(glm::dot(ct1, t2)) + cr.w * std::abs(glm::dot(ct2, t2)));
    }
    lo2 = glm::min(lo2, uv - half);
    hi2 = glm::max(hi2, uv + half);
    const float cosA = std::clamp(glm::dot(n, glm::vec3(ch.normal)), -1.0f, 1.0f);
    e.coneRad = std::max(e.coneRad, std::acos(cosA) + ce.coneRad);
    e.thickness = std::max(e.thickness, std::abs(glm::dot(n, d)) + ce.thickness);
    e.depth = std::max(e.depth, ce.depth + 1);
    coherent = coherent && (tree.links[ci].flags & LFGI_VIR_LOD_COHERENT) != 0;
    tree.children.push_back(ci);
  }
  coherent = coherent && e.coneRad <= maxCone;
  const glm::vec2 mid = 0.5f * (lo2 + hi2), ext = 0.5f * (hi2 - lo2);
  const glm::vec3 rectCentre = centre + mid.x * t1 + mid.y * t2;
  e.footprintRadius = glm::length(ext);  // the rectangle's corners: bounds its angular extent
  float bound = e.footprintRadius;
  for (size_t c = c0; c < c1; ++c) {
    const uint32_t ci = current[c].second;
    bound =
        std::max(bound, glm::length(glm::vec3(tree.nodes[ci].positionRadius) - rectCentre) + tree.bounds[ci]);
  }
  tree.bounds.push_back(bound * kBoundsMargin);
  const uint32_t node = uint32_t(tree.nodes.size());
  tree.nodes.push_back(
      {glm::vec4(rectCentre, e.footprintRadius / o.footprintScale), glm::vec4(n, area),
       glm::vec4(albedo / area, std::cos(std::min(e.coneRad, 0.5f * std::numbers::pi_v<float>))),
       glm::vec4(emission / area, e.thickness)});
  tree.rects.push_back(glm::vec4(shared::octEncode(t1), ext.x, ext.y));
  tree.links.push_back({first, uint32_t(c1 - c0), coherent ? LFGI_VIR_LOD_COHERENT : 0u, ~0u});
  extra.push_back(e);
  next.push_back({current[c0].first, node});
}

// Builds the levels above the leaves; returns the last level's (key, node), a single entry.
std::vector<std::pair<uint64_t, uint32_t>> buildLevels(
    VirLodTree& tree, std::vector<NodeExtra>& extra, const std::vector<std::pair<uint64_t, uint32_t>>& keyed,
    const VirLodBuildOptions& o) {
  const float maxCone = o.coherentConeDeg * std::numbers::pi_v<float> / 180.0f;
  // (key, node) of the current level, in key order.
  std::vector<std::pair<uint64_t, uint32_t>> current(keyed.size());
  for (size_t i = 0; i < keyed.size(); ++i) current[i] = {keyed[i].first, uint32_t(i)};
  for (int level = 1; current.size() > 1; ++level) {
    tree.levelStart.push_back(uint32_t(tree.nodes.size()));
    const int shift = std::min(3 * level, 63);
    std::vector<std::pair<uint64_t, uint32_t>> next;
    for (size_t g = 0; g < current.size();) {
      size_t end = g + 1;
      while (end < current.size() && (current[end].first >> shift) == (current[g].first >> shift)) ++end;
      for (size_t c0 = g; c0 < end; c0 += 8) {  // at most 8 children: a dense leaf cell splits in chunks
        const size_t c1 = std::min(end, c0 + 8);
        if (c1 - c0 == 1) {
          next.push_back(current[c0]);
          continue;
        }
        mergeChildren(tree, extra, current, c0, c1, o, maxCone, next);
      }
      g = end;
    }
    current.swap(next);
  }
  return current;
}

void makeRootLast(VirLodTree& tree, std::vector<NodeExtra>& extra,
                  const std::vector<std::pair<uint64_t, uint32_t>>& current) {
  tree.levelStart.push_back(uint32_t(tree.nodes.size()));
  // The root must be the last node: true unless the last level passed a single node up unchanged.
  if (current.front().second != tree.root()) {
    const uint32_t r = current.front().second;
    tree.levelStart.back() = uint32_t(tree.nodes.size());
    const uint32_t first = uint32_t(tree.children.size());
    tree.children.push_back(r);
    tree.nodes.push_back(tree.nodes[r]);
    tree.links.push_back({first, 1u, 0u, ~0u});  // incoherent: always refined to its one child
    tree.rects.push_back(tree.rects[r]);
    tree.bounds.push_back(tree.bounds[r]);
    extra.push_back(extra[r]);
    ++extra.back().depth;
    tree.levelStart.push_back(uint32_t(tree.nodes.size()));
  }
  tree.maxDepth = extra.back().depth;
}

void buildFrontier(VirLodTree& tree) {
  // Frontier of small subtrees (children always precede their parent, so one ascending pass sizes them).
  std::vector<uint32_t> size(tree.nodes.size(), 1);
  tree.up.assign(tree.nodes.size(), glm::uvec2(~0u));
  for (uint32_t i = tree.leafCount; i < tree.nodes.size(); ++i)
    for (uint32_t c = 0; c < tree.links[i].childCount; ++c) {
      const uint32_t ch = tree.children[tree.links[i].firstChild + c];
      size[i] += size[ch];
      tree.up[ch].x = i;
    }
  std::vector<uint32_t> stack{tree.root()};  // depth first, children in order
  while (!stack.empty()) {
    const uint32_t i = stack.back();
    stack.pop_back();
    if (size[i] <= VirLodTree::kFrontierSubtree || tree.links[i].childCount == 0) {
      // The first frontier node below each not-yet-designated ancestor emits it.
      for (uint32_t a = tree.up[i].x; a != ~0u && tree.up[a].y == ~0u; a = tree.up[a].x)
        tree.up[a].y = uint32_t(tree.frontier.size());
      tree.frontier.push_back(i);
      continue;
    }
    for (uint32_t c = tree.links[i].childCount; c > 0; --c)
      stack.push_back(tree.children[tree.links[i].firstChild + c - 1]);
  }
}

void buildCutNodes(VirLodTree& tree) {
  // The cut's compact nodes; skip links top-down (a parent's index exceeds its children's).
  tree.cutNodes.resize(tree.nodes.size());
  for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
    const shared::Surfel& n = tree.nodes[i];
    const shared::VirLodLink& link = tree.links[i];
    shared::VirLodCutNode& c = tree.cutNodes[i];
    c.sphere = n.positionRadius;
    c.normalCone = glm::vec4(glm::vec3(n.normal), n.albedo.w);
    c.firstChild = link.childCount > 0 ? tree.children[link.firstChild] : LFGI_VIR_LOD_NONE;
    c.skip = LFGI_VIR_LOD_NONE;
    c.flags = link.flags | (tree.up[i].y != ~0u ? LFGI_VIR_LOD_ABOVE_FRONTIER : 0u);
    c.thickness = n.emission.w;
  }
  for (uint32_t i = tree.root() + 1; i-- > 0;)
    for (uint32_t c = 0; c < tree.links[i].childCount; ++c) {
      const uint32_t* ch = &tree.children[tree.links[i].firstChild];
      tree.cutNodes[ch[c]].skip = c + 1 < tree.links[i].childCount ? ch[c + 1] : tree.cutNodes[i].skip;
    }
}

}  // namespace

VirLodTree buildVirLodTree(std::span<const shared::Surfel> surfels, const VirLodBuildOptions& o) {
  const CloudGrid grid = validateSurfels(surfels, o);
  const std::vector<std::pair<uint64_t, uint32_t>> keyed = sortLeafKeys(surfels, grid.lo, grid.toGrid);

  VirLodTree tree;
  std::vector<NodeExtra> extra;
  addLeaves(tree, extra, surfels, keyed, o);
  const std::vector<std::pair<uint64_t, uint32_t>> current = buildLevels(tree, extra, keyed, o);
  makeRootLast(tree, extra, current);
  buildFrontier(tree);
  buildCutNodes(tree);
  return tree;
}

std::vector<uint32_t> virProbeBlockOrder(std::span<const glm::vec3> probes) {
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const glm::vec3& p : probes) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const float toGrid = 1023.999f / std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-6f});
  std::vector<std::pair<uint64_t, uint32_t>> keyed(probes.size());
  for (size_t i = 0; i < probes.size(); ++i) keyed[i] = {morton30(probes[i], lo, toGrid), uint32_t(i)};
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> order(probes.size());
  for (size_t i = 0; i < keyed.size(); ++i) order[i] = keyed[i].second;
  return order;
}

shared::VirLodBlock virLodBlock(std::span<const glm::vec3> probes) {
  if (probes.empty()) fail("VIR LOD: a probe block without probes");
  glm::vec3 c(0.0f);
  for (const glm::vec3& p : probes) c += p;
  c /= float(probes.size());
  float r = 0.0f;
  glm::vec3 e(0.0f);
  for (const glm::vec3& p : probes) {
    r = std::max(r, glm::length(p - c));
    e = glm::max(e, glm::abs(p - c));
  }
  return {glm::vec4(c, r * 1.0001f + 1e-6f), glm::vec4(e * 1.0001f + 1e-6f, 0.0f)};
}

std::vector<uint32_t> virLodCut(const VirLodTree& tree, const shared::VirLodBlock& block,
                                const shared::VirLodParams& params) {
  std::vector<uint32_t> cut;
  for (uint32_t i = tree.root(); i != LFGI_VIR_LOD_NONE;) {
    const shared::VirLodCutNode& node = tree.cutNodes[i];
    const int c = shared::virLodClassify(node, block, params);
    if (c == LFGI_VIR_LOD_ACCEPT) cut.push_back(i);
    i = c == LFGI_VIR_LOD_REFINE ? node.firstChild : node.skip;
  }
  return cut;
}

}  // namespace lfgi::gpu
