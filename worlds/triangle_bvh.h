// A CPU bounding-volume hierarchy over a TriangleMesh for the ray queries that worlds/ needs (probe
// placement: inside-solid and sky visibility tests). Embree stays in bake/ (the design keeps it there);
// this is small, deterministic and fast enough for per-cell placement (binned SAH build, Wald 2007,
// "On fast Construction of SAH-based Bounding Volume Hierarchies"; Moller-Trumbore intersection).
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <optional>
#include <vector>

#include "worlds/mesh.h"

namespace lfgi::worlds {

class TriangleBvh {
 public:
  // Copies the triangles of mesh (the mesh need not outlive the BVH). O(n log n).
  explicit TriangleBvh(const TriangleMesh& mesh);

  struct Hit {
    float t = 0.0f;         // distance along the (unit) direction
    uint32_t triangle = 0;  // index into the mesh's triangles
    bool backface = false;  // the ray hit the back side (geometric normal points along the ray)
  };
  // Closest hit with t in (tMin, tMax); dir must be unit length. Triangles are double-sided for hits.
  std::optional<Hit> intersect(glm::vec3 origin, glm::vec3 dir, float tMax = 1e30f, float tMin = 1e-5f) const;

  size_t triangleCount() const { return tris_.size(); }
  size_t nodeCount() const { return nodes_.size(); }

 private:
  struct Tri {
    glm::vec3 v0, e1, e2;
    uint32_t original;
  };
  struct Node {
    glm::vec3 lo, hi;
    uint32_t first;  // leaf: first triangle; inner: right child (left child is this + 1)
    uint32_t count;  // leaf: triangle count (> 0); inner: 0
  };
  uint32_t build(uint32_t begin, uint32_t end, std::vector<glm::vec3>& centroids, int depth);
  std::vector<Tri> tris_;
  std::vector<Node> nodes_;
};

}  // namespace lfgi::worlds
