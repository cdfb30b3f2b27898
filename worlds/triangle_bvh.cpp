#include "worlds/triangle_bvh.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace lfgi::worlds {
namespace {

constexpr int kBins = 12;
constexpr uint32_t kLeafSize = 4;

float surfaceArea(glm::vec3 lo, glm::vec3 hi) {
  glm::vec3 d = glm::max(hi - lo, glm::vec3(0.0f));
  return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
}

// Slab test; returns the entry distance or +inf when the box is missed within (0, tMax).
float hitBox(glm::vec3 lo, glm::vec3 hi, glm::vec3 o, glm::vec3 invDir, float tMax) {
  glm::vec3 t0 = (lo - o) * invDir, t1 = (hi - o) * invDir;
  glm::vec3 tn = glm::min(t0, t1), tf = glm::max(t0, t1);
  float enter = std::max(std::max(tn.x, tn.y), std::max(tn.z, 0.0f));
  float exit = std::min(std::min(tf.x, tf.y), std::min(tf.z, tMax));
  return enter <= exit ? enter : INFINITY;
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh) {
  tris_.reserve(mesh.triangleCount());
  std::vector<glm::vec3> centroids;
  centroids.reserve(mesh.triangleCount());
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    glm::vec3 a = mesh.vertex(t, 0), b = mesh.vertex(t, 1), c = mesh.vertex(t, 2);
    if (glm::length(glm::cross(b - a, c - a)) <= 0.0f) continue;  // degenerate: never hit
    tris_.push_back({a, b - a, c - a, uint32_t(t)});
    centroids.push_back((a + b + c) / 3.0f);
  }
  nodes_.reserve(2 * tris_.size() / kLeafSize + 1);
  if (!tris_.empty()) build(0, uint32_t(tris_.size()), centroids, 0);
}

uint32_t TriangleBvh::build(uint32_t begin, uint32_t end, std::vector<glm::vec3>& centroids, int depth) {
  const uint32_t index = uint32_t(nodes_.size());
  nodes_.push_back({});
  glm::vec3 lo(INFINITY), hi(-INFINITY), clo(INFINITY), chi(-INFINITY);
  for (uint32_t i = begin; i < end; ++i) {
    const Tri& t = tris_[i];
    for (glm::vec3 p : {t.v0, t.v0 + t.e1, t.v0 + t.e2}) lo = glm::min(lo, p), hi = glm::max(hi, p);
    clo = glm::min(clo, centroids[i]);
    chi = glm::max(chi, centroids[i]);
  }
  nodes_[index].lo = lo;
  nodes_[index].hi = hi;
  const uint32_t n = end - begin;
  auto makeLeaf = [&] {
    nodes_[index].first = begin;
    nodes_[index].count = n;
    return index;
  };
  if (n <= kLeafSize || depth > 60) return makeLeaf();

  // Binned SAH over the axis of largest centroid extent.
  glm::vec3 ext = chi - clo;
  int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
  if (!(ext[axis] > 0.0f)) return makeLeaf();
  struct Bin {
    glm::vec3 lo{INFINITY}, hi{-INFINITY};
    uint32_t count = 0;
  };
  std::array<Bin, kBins> bins{};
  const float scale = float(kBins) / ext[axis];
  auto binOf = [&](uint32_t i) { return std::min(kBins - 1, int((centroids[i][axis] - clo[axis]) * scale)); };
  for (uint32_t i = begin; i < end; ++i) {
    Bin& b = bins[size_t(binOf(i))];
    const Tri& t = tris_[i];
    for (glm::vec3 p : {t.v0, t.v0 + t.e1, t.v0 + t.e2}) b.lo = glm::min(b.lo, p), b.hi = glm::max(b.hi, p);
    ++b.count;
  }
  std::array<float, kBins - 1> leftCost{};
  glm::vec3 l0(INFINITY), l1(-INFINITY);
  uint32_t lc = 0;
  for (int i = 0; i < kBins - 1; ++i) {
    l0 = glm::min(l0, bins[size_t(i)].lo), l1 = glm::max(l1, bins[size_t(i)].hi), lc += bins[size_t(i)].count;
    leftCost[size_t(i)] = lc ? surfaceArea(l0, l1) * float(lc) : 0.0f;
  }
  glm::vec3 r0(INFINITY), r1(-INFINITY);
  uint32_t rc = 0;
  float bestCost = INFINITY;
  int bestSplit = -1;
  for (int i = kBins - 1; i > 0; --i) {
    r0 = glm::min(r0, bins[size_t(i)].lo), r1 = glm::max(r1, bins[size_t(i)].hi), rc += bins[size_t(i)].count;
    float cost = leftCost[size_t(i - 1)] + (rc ? surfaceArea(r0, r1) * float(rc) : 0.0f);
    if (rc < n && rc > 0 && cost < bestCost) bestCost = cost, bestSplit = i;
  }
  if (bestSplit < 0 || bestCost >= surfaceArea(lo, hi) * float(n)) {
    if (n <= 16) return makeLeaf();
    bestSplit = kBins / 2;  // no SAH gain but too many triangles: split in the middle anyway
  }
  uint32_t mid = begin;
  for (uint32_t i = begin; i < end; ++i) {
    if (binOf(i) < bestSplit) {
      std::swap(tris_[i], tris_[mid]);
      std::swap(centroids[i], centroids[mid]);
      ++mid;
    }
  }
  if (mid == begin || mid == end) mid = begin + n / 2;  // all centroids in one bin
  build(begin, mid, centroids, depth + 1);
  uint32_t right = build(mid, end, centroids, depth + 1);
  nodes_[index].first = right;
  nodes_[index].count = 0;
  return index;
}

std::optional<TriangleBvh::Hit> TriangleBvh::intersect(glm::vec3 o, glm::vec3 d, float tMax,
                                                       float tMin) const {
  if (nodes_.empty()) return std::nullopt;
  const glm::vec3 invDir(1.0f / d.x, 1.0f / d.y, 1.0f / d.z);
  std::optional<Hit> best;
  float closest = tMax;
  // Stack of (node, entry distance): a popped node whose entry lies beyond the closest hit found since it
  // was pushed is skipped without testing its box again.
  struct Entry {
    uint32_t node;
    float enter;
  };
  Entry stack[128];
  int sp = 0;
  const float rootEnter = hitBox(nodes_[0].lo, nodes_[0].hi, o, invDir, closest);
  if (rootEnter == INFINITY) return std::nullopt;
  stack[sp++] = {0, rootEnter};
  while (sp > 0) {
    const Entry e = stack[--sp];
    if (e.enter > closest) continue;
    const Node& node = nodes_[e.node];
    if (node.count > 0) {
      for (uint32_t i = node.first; i < node.first + node.count; ++i) {
        const Tri& tr = tris_[i];
        // Moller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle Intersection".
        glm::vec3 p = glm::cross(d, tr.e2);
        float det = glm::dot(tr.e1, p);
        if (std::abs(det) < 1e-12f) continue;
        float inv = 1.0f / det;
        glm::vec3 s = o - tr.v0;
        float u = glm::dot(s, p) * inv;
        if (u < 0.0f || u > 1.0f) continue;
        glm::vec3 q = glm::cross(s, tr.e1);
        float v = glm::dot(d, q) * inv;
        if (v < 0.0f || u + v > 1.0f) continue;
        float t = glm::dot(tr.e2, q) * inv;
        if (t > tMin && t < closest) {
          closest = t;
          best = Hit{t, tr.original, det < 0.0f};  // det < 0: dir along the geometric normal e1 x e2
        }
      }
    } else {
      uint32_t left = e.node + 1, right = node.first;
      float tl = hitBox(nodes_[left].lo, nodes_[left].hi, o, invDir, closest);
      float tr = hitBox(nodes_[right].lo, nodes_[right].hi, o, invDir, closest);
      if (sp + 2 > 128) continue;  // depth is capped at 60 in build, so this cannot happen
      if (tl <= tr) {              // push the farther child first so the nearer is popped first
        if (tr != INFINITY) stack[sp++] = {right, tr};
        if (tl != INFINITY) stack[sp++] = {left, tl};
      } else {
        if (tl != INFINITY) stack[sp++] = {left, tl};
        if (tr != INFINITY) stack[sp++] = {right, tr};
      }
    }
  }
  return best;
}

}  // namespace lfgi::worlds
