// Mesh materials in the GPU layout the ray caster and the probe shading pass read (shaders/shared/shading.h).
#pragma once

#include <vector>

#include "shared/shading.h"
#include "worlds/mesh.h"

namespace lfgi::worlds {

// One GpuMaterial per mesh material: albedo x (mean linear colour of its texture, if any), roughness,
// metallic, emission, double-sided flag. Textures are not sampled per pixel on the GPU (stated limit).
std::vector<shared::GpuMaterial> gpuMaterials(const TriangleMesh& mesh);

}  // namespace lfgi::worlds
