#include "worlds/mesh.h"

#include <xxhash.h>

#include <cmath>
#include <utility>

#include "core/error.h"

namespace lfgi::worlds {

std::string_view categoryName(SurfaceCategory c) {
  switch (c) {
    case SurfaceCategory::kTerrain:
      return "terrain";
    case SurfaceCategory::kRoad:
      return "road";
    case SurfaceCategory::kWall:
      return "wall";
    case SurfaceCategory::kInterior:
      return "interior";
    case SurfaceCategory::kRoof:
      return "roof";
    case SurfaceCategory::kGlass:
      return "glass";
    case SurfaceCategory::kEmissive:
      return "emissive";
    case SurfaceCategory::kProp:
      return "prop";
    case SurfaceCategory::kImported:
      return "imported";
    case SurfaceCategory::kCount:
      break;
  }
  return "unknown";
}

namespace {
float srgbToLinear(uint8_t v) {
  float c = float(v) / 255.0f;
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}
}  // namespace

glm::vec3 Texture::sampleLinear(glm::vec2 uv) const {
  if (width <= 0 || height <= 0) return glm::vec3(1.0f);
  float u = uv.x - std::floor(uv.x), v = uv.y - std::floor(uv.y);
  int x = std::min(width - 1, int(u * float(width)));
  int y = std::min(height - 1, int(v * float(height)));
  const uint8_t* p = &rgba[(size_t(y) * size_t(width) + size_t(x)) * 4];
  return {srgbToLinear(p[0]), srgbToLinear(p[1]), srgbToLinear(p[2])};
}

uint32_t TriangleMesh::addMaterial(Material m) {
  materials.push_back(std::move(m));
  return uint32_t(materials.size() - 1);
}

void TriangleMesh::addTriangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material) {
  uint32_t base = uint32_t(positions.size());
  positions.insert(positions.end(), {a, b, c});
  if (!uvs.empty()) uvs.insert(uvs.end(), 3, glm::vec2(0.0f));
  indices.insert(indices.end(), {base, base + 1, base + 2});
  triangleMaterial.push_back(material);
}

void TriangleMesh::addQuad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t material) {
  uint32_t base = uint32_t(positions.size());
  positions.insert(positions.end(), {a, b, c, d});
  if (!uvs.empty()) uvs.insert(uvs.end(), 4, glm::vec2(0.0f));
  indices.insert(indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  triangleMaterial.insert(triangleMaterial.end(), {material, material});
}

void TriangleMesh::addBox(glm::vec3 lo, glm::vec3 hi, uint32_t material) {
  const glm::vec3 p[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                          {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  addQuad(p[1], p[0], p[3], p[2], material);  // -Z
  addQuad(p[4], p[5], p[6], p[7], material);  // +Z
  addQuad(p[0], p[4], p[7], p[3], material);  // -X
  addQuad(p[5], p[1], p[2], p[6], material);  // +X
  addQuad(p[3], p[7], p[6], p[2], material);  // +Y
  addQuad(p[0], p[1], p[5], p[4], material);  // -Y
}

void TriangleMesh::addInwardBox(glm::vec3 lo, glm::vec3 hi, uint32_t material) {
  const size_t first = indices.size();
  addBox(lo, hi, material);
  for (size_t i = first; i < indices.size(); i += 3) std::swap(indices[i + 1], indices[i + 2]);
}

void TriangleMesh::append(const TriangleMesh& o) {
  const uint32_t vbase = uint32_t(positions.size());
  const uint32_t mbase = uint32_t(materials.size());
  const int tbase = int(textures.size());
  if (uvs.empty() && !o.uvs.empty()) uvs.assign(positions.size(), glm::vec2(0.0f));
  positions.insert(positions.end(), o.positions.begin(), o.positions.end());
  if (!uvs.empty()) {
    if (o.uvs.empty())
      uvs.insert(uvs.end(), o.positions.size(), glm::vec2(0.0f));
    else
      uvs.insert(uvs.end(), o.uvs.begin(), o.uvs.end());
  }
  for (uint32_t i : o.indices) indices.push_back(vbase + i);
  for (uint32_t m : o.triangleMaterial) triangleMaterial.push_back(mbase + m);
  for (Material m : o.materials) {
    if (m.albedoTexture >= 0) m.albedoTexture += tbase;
    materials.push_back(std::move(m));
  }
  textures.insert(textures.end(), o.textures.begin(), o.textures.end());
}

glm::vec3 TriangleMesh::faceNormal(size_t tri) const {
  glm::vec3 n = glm::cross(vertex(tri, 1) - vertex(tri, 0), vertex(tri, 2) - vertex(tri, 0));
  float len = glm::length(n);
  return len > 0.0f ? n / len : glm::vec3(0.0f);
}

double TriangleMesh::triangleArea(size_t tri) const {
  glm::dvec3 a(vertex(tri, 0)), b(vertex(tri, 1)), c(vertex(tri, 2));
  return 0.5 * glm::length(glm::cross(b - a, c - a));
}

double TriangleMesh::totalArea() const {
  double sum = 0.0;
  for (size_t t = 0; t < triangleCount(); ++t) sum += triangleArea(t);
  return sum;
}

Aabb TriangleMesh::bounds() const {
  Aabb box;
  for (const glm::vec3& p : positions) box.extend(p);
  return box;
}

std::vector<size_t> TriangleMesh::categoryTriangleCounts() const {
  std::vector<size_t> counts(size_t(SurfaceCategory::kCount), 0);
  for (uint32_t m : triangleMaterial) ++counts[size_t(materials[m].category)];
  return counts;
}

void TriangleMesh::validate(std::string_view what) const {
  if (indices.size() % 3 != 0) fail("{}: index count {} is not a multiple of 3", what, indices.size());
  if (triangleMaterial.size() != triangleCount())
    fail("{}: {} triangle materials for {} triangles", what, triangleMaterial.size(), triangleCount());
  if (!uvs.empty() && uvs.size() != positions.size())
    fail("{}: {} uvs for {} positions", what, uvs.size(), positions.size());
  for (size_t i = 0; i < indices.size(); ++i)
    if (indices[i] >= positions.size())
      fail("{}: index {} at position {} is out of range ({} vertices)", what, indices[i], i,
           positions.size());
  for (size_t t = 0; t < triangleMaterial.size(); ++t)
    if (triangleMaterial[t] >= materials.size())
      fail("{}: triangle {} uses material {} of {}", what, t, triangleMaterial[t], materials.size());
  for (const Material& m : materials)
    if (m.albedoTexture >= int(textures.size()))
      fail("{}: material '{}' uses texture {} of {}", what, m.name, m.albedoTexture, textures.size());
  for (size_t i = 0; i < positions.size(); ++i)
    if (!std::isfinite(positions[i].x) || !std::isfinite(positions[i].y) || !std::isfinite(positions[i].z))
      fail("{}: vertex {} is not finite", what, i);
}

uint64_t TriangleMesh::contentHash() const {
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  auto add = [&](const void* data, size_t bytes) { XXH3_64bits_update(state, data, bytes); };
  add(positions.data(), positions.size() * sizeof(glm::vec3));
  add(uvs.data(), uvs.size() * sizeof(glm::vec2));
  add(indices.data(), indices.size() * sizeof(uint32_t));
  add(triangleMaterial.data(), triangleMaterial.size() * sizeof(uint32_t));
  for (const Material& m : materials) {
    const float params[8] = {m.albedo.r,   m.albedo.g,   m.albedo.b,  m.emission.r,
                             m.emission.g, m.emission.b, m.roughness, m.metallic};
    add(params, sizeof(params));
    const int32_t ints[3] = {m.albedoTexture, int32_t(m.category), m.doubleSided ? 1 : 0};
    add(ints, sizeof(ints));
  }
  for (const Texture& t : textures) add(t.rgba.data(), t.rgba.size());
  uint64_t h = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  return h;
}

}  // namespace lfgi::worlds
