// EmbreeScene: a TriangleMesh built into an Embree 3 BVH, with closest-hit and occlusion queries. The
// ray tracer behind every ground-truth number (probe capture, reference images).
//
// Build: one triangle geometry, RTC_BUILD_QUALITY_HIGH, RTC_SCENE_FLAG_ROBUST (watertight-ish traversal:
// rays through shared edges and vertices do not slip between triangles, which matters for the sealed-room
// leak tests). Embree errors reported through its error callback become lfgi::Error carrying Embree's
// message ("Embree: <code>: <message>").
//
// Threading: construction is single-caller (Embree's builder may use TBB inside); intersect() and
// occluded() are const and safe to call from any number of threads at once. Queries are deterministic:
// the same ray gives the same hit on any thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>

#include <glm/glm.hpp>

#include "worlds/mesh.h"

namespace lfgi::bake {

struct RayHit {
  float t = 0.0f;               // distance along the (unit) ray direction
  uint32_t triangle = 0;        // index into the mesh's triangles
  glm::vec3 normal{0.0f};       // unit geometric normal of the triangle's front side (CCW, mesh convention)
  glm::vec2 barycentric{0.0f};  // Embree's (u, v): hit = (1-u-v) v0 + u v1 + v v2
  bool backface = false;        // the ray arrived from behind the front side (dot(dir, normal) > 0)
};

class EmbreeScene {
 public:
  // Validates the mesh (TriangleMesh::validate(what)) and builds the BVH. The scene keeps its own copy of
  // the mesh (materials are looked up through mesh()). An empty mesh is allowed (every ray misses).
  // Throws lfgi::Error on bad input or any Embree failure.
  explicit EmbreeScene(worlds::TriangleMesh mesh, std::string_view what = "mesh");
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;
  EmbreeScene(EmbreeScene&&) noexcept;
  EmbreeScene& operator=(EmbreeScene&&) noexcept;

  // Closest hit of origin + t dir for t in [tNear, tFar]; dir must be unit length (t is then metres).
  std::optional<RayHit> intersect(glm::vec3 origin, glm::vec3 dir, float tNear = 0.0f,
                                  float tFar = 1e30f) const;
  // True if anything lies on origin + t dir, t in [tNear, tFar] (any hit, front or back side).
  bool occluded(glm::vec3 origin, glm::vec3 dir, float tNear = 0.0f, float tFar = 1e30f) const;

  const worlds::TriangleMesh& mesh() const;
  // Unit front-side normal of every triangle (TriangleMesh::faceNormal), precomputed.
  const glm::vec3& faceNormal(uint32_t triangle) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lfgi::bake
