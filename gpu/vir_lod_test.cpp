#include "gpu/vir_lod.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>

#include "core/error.h"
#include "gpu/vir_pass.h"
#include "shared/octahedral.h"
#include "test_util.h"

namespace lfgi::gpu {
namespace {

// A jittered grid of up-facing surfels on the plane y = h (x, z in [0, size)), albedo varying with x.
void addFloor(std::vector<shared::Surfel>& out, float size, float spacing, float h, uint32_t seed) {
  const int cells = int(std::lround(size / spacing));
  const float radius = spacing / std::sqrt(std::numbers::pi_v<float>);
  for (uint32_t j = 0; j < uint32_t(cells); ++j)
    for (uint32_t i = 0; i < uint32_t(cells); ++i) {
      const float jx = float(((i * 73856093u) ^ (j * 19349663u) ^ seed) % 1000u) / 1000.0f;
      const float jz = float(((i * 83492791u) ^ (j * 2971215073u) ^ seed) % 1000u) / 1000.0f;
      const glm::vec3 p((float(i) + jx) * spacing, h, (float(j) + jz) * spacing);
      out.push_back({glm::vec4(p, radius), glm::vec4(0.0f, 1.0f, 0.0f, 0.0f),
                     glm::vec4(p.x / size, 0.5f, 0.25f, 1.0f),
                     glm::vec4(0.0f, 0.0f, p.z > size * 0.5f ? 1.0f : 0.0f, 0.0f)});
    }
}

// Every surfel is one leaf; inner nodes conserve area and area-weighted albedo/emission, bound their
// children's footprint discs, sit above their children; the root is last.
TEST(VirLod, TreeConservesAreaAndBoundsChildren) {
  std::vector<shared::Surfel> surfels;
  addFloor(surfels, 16.0f, 0.25f, 0.0f, 1u);
  addFloor(surfels, 16.0f, 0.25f, 3.0f, 2u);  // a second floor 3 m above: same normal class, other plane
  const float fs = 1.5f;
  const VirLodTree tree = buildVirLodTree(surfels, {fs, 18.0f});
  ASSERT_EQ(tree.leafCount, surfels.size());
  ASSERT_EQ(tree.links.size(), tree.nodes.size());
  ASSERT_EQ(tree.levelStart.front(), 0u);
  ASSERT_EQ(tree.levelStart.back(), tree.nodes.size());
  std::vector<int> seen(surfels.size(), 0);
  for (uint32_t i = 0; i < tree.leafCount; ++i) {
    ASSERT_EQ(tree.links[i].childCount, 0u);
    ASSERT_LT(tree.links[i].surfel, surfels.size());
    ++seen[tree.links[i].surfel];
    EXPECT_EQ(tree.nodes[i].positionRadius, surfels[tree.links[i].surfel].positionRadius);
  }
  for (int s : seen) ASSERT_EQ(s, 1);
  std::vector<int> parents(tree.nodes.size(), 0);
  size_t coherentInner = 0;
  for (uint32_t i = tree.leafCount; i < tree.nodes.size(); ++i) {
    const shared::VirLodLink& l = tree.links[i];
    ASSERT_GE(l.childCount, 1u);
    ASSERT_LE(l.childCount, 8u);
    float area = 0.0f;
    glm::vec3 albedo(0.0f);
    for (uint32_t c = 0; c < l.childCount; ++c) {
      const uint32_t ch = tree.children[l.firstChild + c];
      ASSERT_LT(ch, i);  // children come first (the radiance pass runs level by level)
      ++parents[ch];
      area += tree.nodes[ch].normal.w;
      albedo += tree.nodes[ch].normal.w * glm::vec3(tree.nodes[ch].albedo);
      // The child's footprint lies in the parent's rectangle (coplanar floors: exact containment).
      const glm::vec4 rect = tree.rects[i];
      ASSERT_GE(rect.z, 0.0f);
      const glm::vec3 t1 = shared::octDecode(glm::vec2(rect.x, rect.y));
      const glm::vec3 t2 = glm::cross(glm::vec3(tree.nodes[i].normal), t1);
      const glm::vec3 dc = glm::vec3(tree.nodes[ch].positionRadius - tree.nodes[i].positionRadius);
      const float rc = tree.rects[ch].z >= 0.0f ? 0.0f : tree.nodes[ch].positionRadius.w * fs;
      const float ec1 = tree.rects[ch].z >= 0.0f ? tree.rects[ch].z : 0.0f,
                  ec2 = tree.rects[ch].z >= 0.0f ? tree.rects[ch].w : 0.0f;
      if (tree.nodes[i].emission.w < 1e-3f) {  // one floor below this node
        EXPECT_LE(std::abs(glm::dot(dc, t1)) + rc + ec1, rect.z * 1.0001f + 1e-4f);
        EXPECT_LE(std::abs(glm::dot(dc, t2)) + rc + ec2, rect.w * 1.0001f + 1e-4f);
      }
      EXPECT_NEAR(tree.nodes[i].positionRadius.w * fs, std::sqrt(rect.z * rect.z + rect.w * rect.w), 1e-4f);
    }
    EXPECT_NEAR(tree.nodes[i].normal.w, area, 1e-4f * area);
    EXPECT_NEAR(tree.nodes[i].albedo.x, albedo.x / area, 1e-4f);
    coherentInner += (l.flags & LFGI_VIR_LOD_COHERENT) ? 1 : 0;
  }
  for (uint32_t i = 0; i + 1 < tree.nodes.size(); ++i) ASSERT_EQ(parents[i], 1) << "node " << i;
  EXPECT_EQ(parents[tree.root()], 0);
  const float total = 2.0f * 16.0f * 16.0f;  // two 16 m x 16 m floors, disc areas sum to the floor area
  EXPECT_NEAR(tree.nodes[tree.root()].normal.w, total, 0.02f * total);
  // The root spans both floors (3 m apart): thickness 1.5 m about the mid plane, so the cut splats it
  // only from > 150 m (lodDepthTolerance 0.01). Every inner node has one normal (coherent).
  EXPECT_NEAR(tree.nodes[tree.root()].emission.w, 1.5f, 0.05f);
  EXPECT_EQ(coherentInner, tree.nodes.size() - tree.leafCount);
  // The cut's stackless walk (VirLodCutNode firstChild / skip), refining everything, visits every node
  // once, in the order of a stack walk that pushes children in reverse; its compact fields are the node's.
  {
    std::vector<uint32_t> stackOrder, stack{tree.root()}, skipOrder;
    while (!stack.empty()) {
      const uint32_t i = stack.back();
      stack.pop_back();
      stackOrder.push_back(i);
      for (uint32_t c = tree.links[i].childCount; c > 0; --c)
        stack.push_back(tree.children[tree.links[i].firstChild + c - 1]);
    }
    ASSERT_EQ(tree.cutNodes.size(), tree.nodes.size());
    for (uint32_t i = tree.root(); i != LFGI_VIR_LOD_NONE && skipOrder.size() <= tree.nodes.size();) {
      skipOrder.push_back(i);
      const shared::VirLodCutNode& c = tree.cutNodes[i];
      EXPECT_EQ(c.sphere, tree.nodes[i].positionRadius);
      EXPECT_EQ(c.normalCone.w, tree.nodes[i].albedo.w);
      EXPECT_EQ(c.thickness, tree.nodes[i].emission.w);
      EXPECT_EQ(c.firstChild == LFGI_VIR_LOD_NONE, tree.links[i].childCount == 0);
      EXPECT_EQ((c.flags & LFGI_VIR_LOD_ABOVE_FRONTIER) != 0, tree.up[i].y != ~0u);
      i = c.firstChild != LFGI_VIR_LOD_NONE ? c.firstChild : c.skip;
    }
    EXPECT_EQ(skipOrder, stackOrder);
  }
  std::printf("VIR LOD tree: %zu surfels -> %zu nodes, depth %d, %zu coherent inner nodes\n", surfels.size(),
              tree.nodes.size(), tree.maxDepth, coherentInner);

  // The frontier splits the tree: every leaf lies below exactly one frontier node (of a small subtree),
  // and every node above the frontier designates a frontier node below it.
  std::vector<int> underFrontier(tree.nodes.size(), 0);
  ASSERT_GT(tree.frontier.size(), 1u);
  for (size_t fi = 0; fi < tree.frontier.size(); ++fi) {
    std::vector<uint32_t> st{tree.frontier[fi]};
    size_t nodes = 0;
    while (!st.empty()) {
      const uint32_t x = st.back();
      st.pop_back();
      ++underFrontier[x];
      ++nodes;
      for (uint32_t c = 0; c < tree.links[x].childCount; ++c)
        st.push_back(tree.children[tree.links[x].firstChild + c]);
    }
    EXPECT_LE(nodes, VirLodTree::kFrontierSubtree);
    for (uint32_t a = tree.up[tree.frontier[fi]].x; a != ~0u; a = tree.up[a].x) {
      ASSERT_LT(tree.up[a].y, tree.frontier.size());
      if (tree.up[a].y == fi) {  // designated: no earlier frontier node below a
        for (size_t e = 0; e < fi; ++e) {
          uint32_t x = tree.frontier[e];
          while (x != ~0u && x != a) x = tree.up[x].x;
          EXPECT_NE(x, a);
        }
      }
    }
  }
  for (uint32_t i = 0; i < tree.leafCount; ++i) ASSERT_EQ(underFrontier[i], 1);

  // Deterministic: the same input gives the same tree.
  const VirLodTree again = buildVirLodTree(surfels, {fs, 18.0f});
  ASSERT_EQ(again.children, tree.children);
  EXPECT_EQ(std::memcmp(again.nodes.data(), tree.nodes.data(), tree.nodes.size() * sizeof(shared::Surfel)),
            0);
}

// VirLodTree::bounds (the far pass's occlusion culling drops whole subtrees by it): the sphere of radius
// bounds[i] about node i's centre holds every footprint below it, leaf discs (radius x footprintScale) and
// merged rectangles (half diagonal) alike. Two parallel floors and a tilted panel, so the top nodes mix
// planes.
TEST(VirLod, BoundsHoldEveryFootprintBelow) {
  std::vector<shared::Surfel> surfels;
  addFloor(surfels, 8.0f, 0.25f, 0.0f, 1u);
  addFloor(surfels, 8.0f, 0.25f, 3.0f, 2u);
  const std::vector<shared::Surfel> panel = test::panelSurfels(
      glm::vec3(2.0f, 6.0f, -1.0f), glm::normalize(glm::vec3(0.4f, 1.0f, -0.3f)), 24, 0.2f, 0.11f);
  surfels.insert(surfels.end(), panel.begin(), panel.end());
  const float fs = 1.3f;
  const VirLodTree tree = buildVirLodTree(surfels, {fs, 18.0f});
  ASSERT_EQ(tree.bounds.size(), tree.nodes.size());
  // Per node (every inner node, every 97th leaf): the farthest reach from its centre of its own footprint and
  // of every descendant's, by a walk of its subtree.
  size_t checked = 0;
  float loosest = 1.0f;
  for (uint32_t i = 0; i < tree.nodes.size();
       i = i < tree.leafCount ? std::min(i + 97u, tree.leafCount) : i + 1u) {
    const glm::vec3 c(tree.nodes[i].positionRadius);
    float reach = 0.0f;
    std::vector<uint32_t> st{i};
    while (!st.empty()) {
      const uint32_t x = st.back();
      st.pop_back();
      const glm::vec4 rect = tree.rects[x];
      const float own =
          rect.z >= 0.0f ? std::sqrt(rect.z * rect.z + rect.w * rect.w) : tree.nodes[x].positionRadius.w * fs;
      reach = std::max(reach, glm::length(glm::vec3(tree.nodes[x].positionRadius) - c) + own);
      for (uint32_t k = 0; k < tree.links[x].childCount; ++k)
        st.push_back(tree.children[tree.links[x].firstChild + k]);
    }
    ASSERT_LE(reach, tree.bounds[i] * (1.0f + 1e-6f)) << "node " << i << " of " << tree.nodes.size();
    loosest = std::max(loosest, tree.bounds[i] / std::max(reach, 1e-9f));
    ++checked;
  }
  EXPECT_GT(checked, tree.nodes.size() - tree.leafCount);
  // The build nests child spheres (triangle inequality), so a bound may exceed the farthest footprint, but
  // not by much: a sphere far too big would cull nothing.
  std::printf("VIR LOD bounds: %zu nodes checked, loosest bound %.3f x the farthest footprint\n", checked,
              loosest);
  EXPECT_LT(loosest, 1.5f);
}

TEST(VirLod, RejectsBadInput) {
  EXPECT_THROW(buildVirLodTree({}), Error);
  std::vector<shared::Surfel> s(2);
  s[1].positionRadius = glm::vec4(std::nanf(""), 0.0f, 0.0f, 0.1f);
  EXPECT_THROW(buildVirLodTree(s), Error);
  s[1].positionRadius = glm::vec4(1.0f, 0.0f, 0.0f, 0.1f);
  s[0].normal = s[1].normal = glm::vec4(0.0f, 1.0f, 0.0f, 0.0f);
  const VirLodTree one = buildVirLodTree(std::span(s).first(1));
  EXPECT_EQ(one.nodes.size(), 1u);
  EXPECT_EQ(one.root(), 0u);
  const VirLodTree two = buildVirLodTree(s);
  EXPECT_EQ(two.nodes.size(), 3u);
  EXPECT_EQ(two.links[two.root()].childCount, 2u);
}

// Probe blocks along the Morton curve: a 8 x 4 x 8 grid given row by row (x fastest) falls into compact
// blocks of 8 (2 x 2 x 2 probes: radius sqrt(3) / 2 spacing), not rows (radius 3.5 spacings).
TEST(VirLod, ProbeBlockOrderGroupsGridCubes) {
  std::vector<glm::vec3> probes;
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 8; ++x) probes.push_back(glm::vec3(10.0f, 2.0f, -5.0f) + 2.0f * glm::vec3(x, y, z));
  const std::vector<uint32_t> order = virProbeBlockOrder(probes);
  ASSERT_EQ(order.size(), probes.size());
  std::vector<int> seen(probes.size(), 0);
  for (uint32_t i : order) ++seen.at(i);
  for (int s : seen) ASSERT_EQ(s, 1);
  for (size_t b = 0; b < order.size(); b += 8) {
    glm::vec3 c(0.0f);
    for (size_t i = b; i < b + 8; ++i) c += probes[order[i]] / 8.0f;
    float r = 0.0f;
    for (size_t i = b; i < b + 8; ++i) r = std::max(r, glm::length(probes[order[i]] - c));
    EXPECT_NEAR(r, std::sqrt(3.0f), 1e-4f) << "block " << b / 8;
  }
  EXPECT_EQ(virProbeBlockOrder(probes), order);
}

// The cut's foreshortening rule (VirOptions::lodElongation, shared/vir.h virLodClassify): seen at a grazing
// angle, a floor is cut into far fewer nodes, each up to lodElongation x lodTexels wide but with the
// projected area of a lodTexels-wide one (checked against the |cos| at its rectangle's corners, not the
// classify's bound); seen from above, the rule changes little; with lodElongation 1 it is the width test.
TEST(VirLod, ForeshortenedNodesAreCutCoarserWithTheSameProjectedArea) {
  std::vector<shared::Surfel> surfels;
  addFloor(surfels, 64.0f, 0.5f, 0.0f, 7u);
  const VirLodTree tree = buildVirLodTree(surfels);
  VirOptions o;
  o.resolution = 16;
  o.maxRange = 1000.0f;
  struct Stats {
    size_t nodes = 0;
    float widest = 0.0f, largestArea = 0.0f;  // max w, max w^2 |cos| over accepted merged nodes
  };
  const auto cutStats = [&](glm::vec3 probe, float elongation) {
    o.lodElongation = elongation;
    const shared::VirLodParams lp = virLodClassifyParams(o);
    Stats st;
    for (const uint32_t i : virLodCut(tree, virLodBlock(std::span(&probe, 1)), lp)) {
      ++st.nodes;
      if (i < tree.leafCount) continue;
      const shared::Surfel& node = tree.nodes[i];
      const glm::vec3 pos(node.positionRadius), nrm(node.normal);
      const float w = node.positionRadius.w * lp.footprintScale * float(lp.res) / glm::length(pos - probe);
      const glm::vec4 rect = tree.rects[i];
      const glm::vec3 t1 = shared::octDecode(glm::vec2(rect.x, rect.y)), t2 = glm::cross(nrm, t1);
      float c = 0.0f;
      for (const float a : {-1.0f, 1.0f})
        for (const float b : {-1.0f, 1.0f})
          c = std::max(
              c, std::abs(glm::dot(nrm, glm::normalize(pos + a * rect.z * t1 + b * rect.w * t2 - probe))));
      st.widest = std::max(st.widest, w);
      st.largestArea = std::max(st.largestArea, w * w * c);
    }
    return st;
  };
  const float lt = o.lodTexels, lt2 = lt * lt;
  const glm::vec3 grazing(32.0f, 0.5f, -8.0f), above(32.0f, 40.0f, 32.0f);
  const Stats g1 = cutStats(grazing, 1.0f), g2 = cutStats(grazing, 2.0f), g4 = cutStats(grazing, 4.0f);
  const Stats a1 = cutStats(above, 1.0f), a2 = cutStats(above, 2.0f);
  std::printf(
      "floor cut nodes, lodElongation 1 / 2 / 4: grazing %zu / %zu / %zu (widest %.2f / %.2f / %.2f "
      "texels, largest w^2 cos %.2f / %.2f / %.2f), from above %zu / %zu\n",
      g1.nodes, g2.nodes, g4.nodes, g1.widest, g2.widest, g4.widest, g1.largestArea, g2.largestArea,
      g4.largestArea, a1.nodes, a2.nodes);
  EXPECT_LE(g1.widest, lt);
  EXPECT_LE(a1.widest, lt);
  EXPECT_GT(g2.widest, lt);  // the rule took effect
  EXPECT_LE(g2.widest, 2.0f * lt);
  EXPECT_LE(g4.widest, 4.0f * lt);
  for (const Stats& st : {g1, g2, g4, a1, a2}) EXPECT_LE(st.largestArea, lt2 * 1.0001f);
  EXPECT_LT(g2.nodes * 3, g1.nodes * 2);  // grazing: at least a third fewer nodes
  EXPECT_LE(g4.nodes, g2.nodes);
  EXPECT_GT(a2.nodes * 10, a1.nodes * 7);  // from above: hardly any node is foreshortened enough
  EXPECT_LE(a2.nodes, a1.nodes);
}

}  // namespace
}  // namespace lfgi::gpu
