// Triangle meshes: the one geometry type that worlds/ produces (synthetic cells, glTF import) and that
// surfel sampling, probe placement, export and (later) Embree capture consume.
//
// Conventions: metres, right-handed, +Y up. Triangles are counter-clockwise seen from the front (the
// side their geometric normal points to). Every triangle has a material; a material has a category,
// so world statistics can be counted per kind of surface.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace lfgi::worlds {

// What a surface is, for statistics and for tests that look for GI failure modes.
enum class SurfaceCategory : uint8_t {
  kTerrain,
  kRoad,
  kWall,      // exterior walls
  kInterior,  // interior walls, floors, ceilings
  kRoof,
  kGlass,     // window panes (treated as diffuse for now)
  kEmissive,  // lamps, lit windows
  kProp,      // arcades, overhangs, pillars
  kImported,  // anything from glTF
  kCount
};
std::string_view categoryName(SurfaceCategory c);

// An 8-bit sRGB RGBA texture (glTF base colour). Sampling converts to linear.
struct Texture {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgba;  // width * height * 4, row-major, top row first

  // Linear RGB at uv with repeat wrapping and nearest-texel lookup (glTF default wrap).
  glm::vec3 sampleLinear(glm::vec2 uv) const;
};

struct Material {
  std::string name;
  glm::vec3 albedo{0.5f};    // linear base colour factor
  glm::vec3 emission{0.0f};  // linear emitted radiance, W/(sr m^2) in scene units
  float roughness = 1.0f;
  float metallic = 0.0f;
  int albedoTexture = -1;  // index into TriangleMesh::textures, multiplied with albedo
  SurfaceCategory category = SurfaceCategory::kImported;
  bool doubleSided = false;
};

struct Aabb {
  glm::vec3 min{1e30f};
  glm::vec3 max{-1e30f};
  void extend(glm::vec3 p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  void extend(const Aabb& b) {
    min = glm::min(min, b.min);
    max = glm::max(max, b.max);
  }
  bool empty() const { return min.x > max.x; }
  glm::vec3 size() const { return empty() ? glm::vec3(0.0f) : max - min; }
};

struct TriangleMesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec2> uvs;              // empty, or one per position
  std::vector<uint32_t> indices;           // 3 per triangle, into positions
  std::vector<uint32_t> triangleMaterial;  // one per triangle, into materials
  std::vector<Material> materials;
  std::vector<Texture> textures;

  size_t triangleCount() const { return indices.size() / 3; }
  // Adds a material and returns its index.
  uint32_t addMaterial(Material m);
  // Adds a triangle (a, b, c counter-clockwise from the front) with its own three vertices.
  void addTriangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material);
  // Adds a planar quad a-b-c-d (counter-clockwise from the front) as two triangles.
  void addQuad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t material);
  // Adds an axis-aligned box [lo, hi] with outward-facing triangles (12 triangles).
  void addBox(glm::vec3 lo, glm::vec3 hi, uint32_t material);
  // The same box with inward-facing triangles: a closed room seen from inside (furnace tests, probes).
  void addInwardBox(glm::vec3 lo, glm::vec3 hi, uint32_t material);
  // Appends another mesh (materials and textures are appended and re-indexed).
  void append(const TriangleMesh& other);

  glm::vec3 vertex(size_t tri, int k) const { return positions[indices[tri * 3 + size_t(k)]]; }
  // Geometric normal (unit; zero for a degenerate triangle) and area of triangle tri.
  glm::vec3 faceNormal(size_t tri) const;
  double triangleArea(size_t tri) const;
  double totalArea() const;
  Aabb bounds() const;
  // Triangles per category.
  std::vector<size_t> categoryTriangleCounts() const;

  // Throws lfgi::Error naming `what` if an index, material or texture reference is out of range, the
  // uv count is wrong, or a position is not finite.
  void validate(std::string_view what) const;

  // 64-bit content hash (XXH3) of positions, uvs, indices, triangle materials and material parameters:
  // equal hashes mean bit-identical geometry (the determinism tests and incremental rebake use it).
  uint64_t contentHash() const;
};

}  // namespace lfgi::worlds
