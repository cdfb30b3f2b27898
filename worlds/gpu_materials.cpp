#include "worlds/gpu_materials.h"

#include <algorithm>

namespace lfgi::worlds {

std::vector<shared::GpuMaterial> gpuMaterials(const TriangleMesh& mesh) {
  std::vector<shared::GpuMaterial> out;
  out.reserve(mesh.materials.size());
  for (const Material& m : mesh.materials) {
    glm::vec3 albedo = m.albedo;
    if (m.albedoTexture >= 0 && size_t(m.albedoTexture) < mesh.textures.size()) {
      const Texture& t = mesh.textures[size_t(m.albedoTexture)];
      glm::dvec3 sum(0.0);
      const int step = std::max(1, std::max(t.width, t.height) / 64);
      size_t count = 0;
      for (int y = 0; y < t.height; y += step)
        for (int x = 0; x < t.width; x += step, ++count)
          sum += glm::dvec3(t.sampleLinear(
              glm::vec2((float(x) + 0.5f) / float(t.width), (float(y) + 0.5f) / float(t.height))));
      if (count > 0) albedo *= glm::vec3(sum / double(count));
    }
    shared::GpuMaterial g{};
    g.albedo = glm::vec4(albedo, m.roughness);
    g.emission = glm::vec4(m.emission, m.metallic);
    g.flags = glm::vec4(m.doubleSided ? 1.0f : 0.0f, 0.0f, 0.0f, 0.0f);
    out.push_back(g);
  }
  return out;
}

}  // namespace lfgi::worlds
