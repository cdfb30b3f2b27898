// Test helper shared by the bake codec tests (shared_generator_test, codec_stability_test): the tiny
// capture cell they train on.
#pragma once

#include <span>
#include <string>
#include <utility>
#include <vector>

#include "bake/embree_scene.h"
#include "bake/generator_training.h"

namespace lfgi::test {

// A box [boxMin, boxMax] on a 60 m ground slab, captured by 8 probes at (+-4, {1, 4}, +-4): 8 x 8 maps,
// 4 x 4 irradiance, 4 spp, 1 bounce (~0.1 s per key).
inline bake::GeneratorTrainingSet boxOnGroundCell(glm::vec3 groundAlbedo, glm::vec3 wallAlbedo,
                                                  glm::vec3 boxMin, glm::vec3 boxMax,
                                                  std::span<const bake::LightingKeySpec> keys,
                                                  const std::string& name) {
  worlds::TriangleMesh mesh;
  worlds::Material ground, wall;
  ground.albedo = groundAlbedo;
  wall.albedo = wallAlbedo;
  const uint32_t g = mesh.addMaterial(ground), w = mesh.addMaterial(wall);
  mesh.addBox(glm::vec3(-30.0f, -1.0f, -30.0f), glm::vec3(30.0f, 0.0f, 30.0f), g);
  mesh.addBox(boxMin, boxMax, w);
  const bake::EmbreeScene scene(std::move(mesh), name);
  std::vector<glm::vec3> positions;
  for (float x : {-4.0f, 4.0f})
    for (float z : {-4.0f, 4.0f})
      for (float y : {1.0f, 4.0f}) positions.push_back(glm::vec3(x, y, z));
  bake::CaptureOptions o;
  o.resolution = 8;
  o.irradianceResolution = 4;
  o.samplesPerTexel = 4;
  o.maxBounces = 1;
  return bake::captureTrainingSet(scene, positions, glm::vec3(-4.0f, 1.0f, -4.0f),
                                  glm::vec3(4.0f, 4.0f, 4.0f), keys, o);
}

}  // namespace lfgi::test
