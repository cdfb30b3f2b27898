// GPU pass: the cubemap-rasterization baseline that VIR (vir_pass.h) is measured against.
// A Vulkan 1.3 graphics pipeline (dynamic rendering, headless, the same code on lavapipe and on GPUs)
// rasterizes every triangle of a scene into the 6 faces (90-degree frusta, depth test) of every probe,
// writing a G-buffer (normal + distance, albedo, emission); a compute pass then resamples the faces to
// the N x N octahedral layout of VIR (shared/octahedral.h texel centres), so both produce the same
// ProbeAtlas channels: distance moments (r, r^2), normal (w coverage: 0 sky, 1 covered), albedo,
// radiance (= emission: geometry capture, no lighting; VIR with zero surfel irradiance gives the same).
//
// Batching: the face tiles (F x F each) of many probes share one atlas image set (tile of probe p, face f
// = p * 6 + f, row-major), one draw per (probe, face) with its own viewport and scissor, all triangles
// each draw (no per-face culling: a cubemap capture renders the cell). As many probes as fit in
// maxAtlasTexels go in one batch; every batch (render, copy to buffers, resample) is recorded into ONE
// command buffer and submitted once. The atlas is copied to storage buffers (vkCmdCopyImageToBuffer)
// because gpu/ programs bind buffers only; the copy is timed separately.
//
// Accuracy: resampling is nearest-face-texel; the distance is re-intersected with the plane of the face
// texel's triangle along the exact octahedral texel-centre ray (see cubemap_raster_resample.comp), so on
// flat-shaded geometry it is exact away from silhouettes.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/graphics.h"
#include "gpu/program.h"
#include "gpu/vir_pass.h"
#include "shared/cubemap_raster.h"

namespace lfgi::gpu {

// Flat-shaded triangles as the raster consumes them (vertex pulling: 3 vertices per triangle).
struct CubemapScene {
  std::vector<glm::vec4> vertices;                 // 3 per triangle, w = 1
  std::vector<shared::CubemapTriangle> triangles;  // one per triangle

  // Adds triangle a-b-c (counter-clockwise from the front); the normal is the geometric one.
  void addTriangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 albedo,
                   glm::vec3 emission = glm::vec3(0.0f));
  size_t triangleCount() const { return triangles.size(); }
};

struct CubemapRasterOptions {
  int resolution = 16;               // N of the octahedral output, [1, 1024]
  int faceResolution = 0;            // F texels per face side, [1, 4096]; 0: F = N (6 N^2 face samples)
  float nearPlane = 0.01f;           // m, > 0
  int64_t maxAtlasTexels = 1 << 22;  // per batch (memory: 36 B/texel of images + 32 B/texel of copies)
};

struct CubemapCapture {
  ProbeAtlas atlas;  // gpuMs = everything; splatMs = raster, resolveMs = copy + resample; no fill passes
  double rasterMs = 0.0, copyMs = 0.0, resampleMs = 0.0;
  int faceResolution = 0;
  int probesPerBatch = 0;
  int batches = 0;
};

class CubemapRaster {
 public:
  explicit CubemapRaster(Context& ctx);

  // Uploads, renders and resamples every batch in one submit, waits and reads back. Throws lfgi::Error on
  // empty input, a vertex/triangle count mismatch, bad options, or an atlas beyond the device limits.
  CubemapCapture run(const CubemapScene& scene, std::span<const glm::vec3> probes,
                     const CubemapRasterOptions& options);

 private:
  Context& ctx_;
  GraphicsProgram raster_;
  Program resample_;
};

}  // namespace lfgi::gpu
