// G-buffer of a pinhole view by compute ray casting (shaders/gbuffer_raycast.comp) through a BVH flattened
// into storage buffers. Chosen over a raster pipeline so the whole renderer stays compute-only (the same
// BVH also answers the shading pass's sun shadow rays); one ray per pixel through the pixel centre.
//
// The BVH: binned SAH over triangle centroids (Wald 2007, "On fast Construction of SAH-based Bounding
// Volume Hierarchies"), 12 bins per axis, leaves of <= 4 triangles, depth-first node order (the left
// child follows its parent), so traversal needs one stack entry per inner node visited (48 max in the
// shader; buildGpuBvh keeps depth <= 40 by falling back to median splits).
#pragma once

#include <glm/glm.hpp>

#include <span>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/program.h"
#include "shared/shading.h"

namespace lfgi::gpu {

// What the GPU ray caster needs of a mesh: flattened BVH, triangles in leaf order, materials.
struct GpuScene {
  std::vector<shared::GpuBvhNode> nodes;
  std::vector<shared::GpuTriangle> triangles;
  std::vector<shared::GpuMaterial> materials;
};

// Builds the BVH over an indexed triangle list (3 indices per triangle into positions, one material index
// per triangle into materials). Deterministic. Throws lfgi::Error naming the first out-of-range index or
// non-finite position. An empty list gives one empty node; passes then skip tracing (every ray misses).
GpuScene buildGpuScene(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                       std::span<const uint32_t> triangleMaterial,
                       std::vector<shared::GpuMaterial> materials);

// CPU closest hit against the same flattened data (tests compare the shader with it). Returns the index
// into scene.triangles or -1; t receives the distance.
int intersectGpuScene(const GpuScene& scene, glm::vec3 origin, glm::vec3 dir, float tMax, float& t);

// The scene on the device.
struct GpuSceneBuffers {
  Buffer nodes, triangles, materials;
  uint32_t nodeCount = 0, triangleCount = 0;
};
GpuSceneBuffers uploadGpuScene(Context& ctx, const GpuScene& scene);

// Camera basis as bake::cameraRayDirection (up = +Y). Throws lfgi::Error for a degenerate camera.
shared::GpuCamera makeGpuCamera(glm::vec3 position, glm::vec3 target, float verticalFovDeg, int width,
                                int height);

// Four vec4 per pixel; layout in shaders/shared/shading.h (GBufferParams).
struct GBuffer {
  int width = 0, height = 0;
  Buffer position, normal, albedo, emission;
};
GBuffer createGBuffer(Context& ctx, int width, int height);

struct GBufferHost {
  int width = 0, height = 0;
  std::vector<glm::vec4> position, normal, albedo, emission;
};
GBufferHost readGBuffer(Context& ctx, const GBuffer& g);
// Uploads host G-buffer data (tests and probes at chosen points). Throws if sizes disagree.
void writeGBuffer(Context& ctx, const GBufferHost& host, GBuffer& g);

class GBufferPass {
 public:
  explicit GBufferPass(Context& ctx);
  // Records the ray cast. params lives in a small storage buffer owned by the pass (set by setCamera).
  void record(VkCommandBuffer cmd, const GpuSceneBuffers& scene, GBuffer& g) const;
  void setCamera(const shared::GpuCamera& camera, int width, int height, const GpuSceneBuffers& scene,
                 float maxDistance = 1.0e4f);
  // setCamera recorded into cmd (recordBufferUpdate) instead of uploaded.
  void recordCamera(VkCommandBuffer cmd, const shared::GpuCamera& camera, int width, int height,
                    const GpuSceneBuffers& scene, float maxDistance = 1.0e4f);

 private:
  Context& ctx_;
  Program program_;
  Buffer params_;
};

}  // namespace lfgi::gpu
