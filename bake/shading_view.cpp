#include "bake/shading_view.h"

#include <algorithm>
#include <cmath>

#include "bake/shading_inputs.h"
#include "core/error.h"
#include "core/metrics.h"
#include "gpu/timing.h"
#include "worlds/gpu_materials.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {

ShadingRenderer::ShadingRenderer(gpu::Context& ctx, const worlds::TriangleMesh& mesh)
    : ctx_(ctx),
      scene_(gpu::buildGpuScene(mesh.positions, mesh.indices, mesh.triangleMaterial,
                                worlds::gpuMaterials(mesh))),
      buffers_(gpu::uploadGpuScene(ctx, scene_)),
      gbuffer_(ctx),
      shading_(ctx) {}

void ShadingRenderer::setProbes(std::span<const ProbeField* const> fields, int levels) {
  std::vector<gpu::ShadingCellInput> in;
  for (const ProbeField* f : fields) {
    if (!f) fail("ShadingRenderer::setProbes: null field");
    in.push_back({f, {}});
  }
  setCells(in, levels);
}

void ShadingRenderer::setCells(std::span<const gpu::ShadingCellInput> cells, int levels) {
  std::vector<gpu::ShadingCellInput> in(cells.begin(), cells.end());
  std::vector<std::vector<float>> spec(in.size());
  for (size_t k = 0; k < in.size(); ++k)
    if (in[k].field && in[k].specular.empty()) {
      spec[k] = prefilterSpecularLevels(*in[k].field, levels);
      in[k].specular = spec[k];
    }
  shading_.setProbes(gpu::packShadingProbes(in, levels));
}

ShadedView ShadingRenderer::render(const worlds::SkyModel& sky, const PinholeCamera& camera, int width,
                                   int height, const gpu::ShadingOptions& options) {
  validateCamera(camera);
  const shared::GpuCamera cam =
      gpu::makeGpuCamera(camera.position, camera.target, camera.verticalFovDeg, width, height);
  gbuffer_.setCamera(cam, width, height, buffers_, options.maxDistance);
  shading_.setView(sky.params, cam, width, height, buffers_, options);
  gpu::GBuffer g = gpu::createGBuffer(ctx_, width, height);
  gpu::ShadeOutput out = gpu::createShadeOutput(ctx_, width, height);
  gpu::GpuTimer timer(ctx_, 3);
  gpu::submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    gbuffer_.record(cmd, buffers_, g);
    gpu::memoryBarrier(cmd);
    timer.stamp(cmd, 1);
    shading_.record(cmd, buffers_, g, out);
    gpu::memoryBarrier(cmd);
    timer.stamp(cmd, 2);
  });
  ShadedView v;
  v.gbufferMs = timer.elapsedMs(0, 1);
  v.shadeMs = timer.elapsedMs(1, 2);
  const gpu::ShadeOutputHost h = gpu::readShadeOutput(ctx_, out);
  v.image =
      Image(width, height,
            {"R", "G", "B", "direct.R", "direct.G", "direct.B", "indirect_diffuse.R", "indirect_diffuse.G",
             "indirect_diffuse.B", "indirect_specular.R", "indirect_specular.G", "indirect_specular.B",
             "indirect.R", "indirect.G", "indirect.B", "weight", "ao", "fallback"});
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t p = size_t(y) * size_t(width) + size_t(x);
      std::span<float> px = v.image.pixel(x, y);
      for (size_t c = 0; c < 3; ++c) {
        px[c] = h.total[p][int(c)];
        px[3 + c] = h.direct[p][int(c)];
        px[6 + c] = h.diffuse[p][int(c)];
        px[9 + c] = h.specular[p][int(c)];
        px[12 + c] = h.diffuse[p][int(c)] + h.specular[p][int(c)];
      }
      px[15] = h.diffuse[p].w;
      px[16] = h.specular[p].w;
      px[17] = h.direct[p].w;
    }
  }
  return v;
}

gpu::ShadeOutputHost ShadingRenderer::shadePoints(const worlds::SkyModel& sky, const gpu::GBufferHost& points,
                                                  glm::vec3 eye, const gpu::ShadingOptions& options) {
  // Any camera basis works: the shader only uses its position (view vector) for shading points.
  const shared::GpuCamera cam =
      gpu::makeGpuCamera(eye, eye + glm::vec3(0.0f, 0.0f, -1.0f), 60.0f, points.width, points.height);
  shading_.setView(sky.params, cam, points.width, points.height, buffers_, options);
  gpu::GBuffer g = gpu::createGBuffer(ctx_, points.width, points.height);
  gpu::writeGBuffer(ctx_, points, g);
  gpu::ShadeOutput out = gpu::createShadeOutput(ctx_, points.width, points.height);
  gpu::submitAndWait(ctx_, [&](VkCommandBuffer cmd) { shading_.record(cmd, buffers_, g, out); });
  return gpu::readShadeOutput(ctx_, out);
}

namespace {
int channel(const Image& img, const std::string& name) {
  const int c = img.channelIndex(name);
  if (c < 0) fail("image has no channel '{}'", name);
  return c;
}
}  // namespace

std::vector<uint8_t> shadedSurfaceMask(const Image& shaded, const Image& ref, float emitterLevel) {
  std::vector<uint8_t> m(size_t(shaded.width) * size_t(shaded.height), 0);
  const int w = channel(shaded, "weight"), f = channel(shaded, "fallback"), d = channel(shaded, "direct.G"),
            rd = channel(ref, "direct.G");
  for (int y = 0; y < shaded.height; ++y)
    for (int x = 0; x < shaded.width; ++x)
      m[size_t(y) * size_t(shaded.width) + size_t(x)] =
          (shaded.at(x, y, w) > 0.0f || shaded.at(x, y, f) > 0.0f) && shaded.at(x, y, d) < emitterLevel &&
          ref.at(x, y, rd) < emitterLevel;
  return m;
}

double layerRelativeRms(const Image& a, const std::string& la, const Image& r, const std::string& lr,
                        const std::vector<uint8_t>* mask) {
  if (a.width != r.width || a.height != r.height)
    fail("layerRelativeRms: {}x{} vs {}x{}", a.width, a.height, r.width, r.height);
  std::vector<float> va, vr;
  const char* rgb[3] = {"R", "G", "B"};
  int ca[3], cr[3];
  for (int k = 0; k < 3; ++k) {
    ca[k] = channel(a, la + rgb[k]);
    cr[k] = channel(r, lr + rgb[k]);
  }
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      if (mask && !(*mask)[size_t(y) * size_t(a.width) + size_t(x)]) continue;
      for (int k = 0; k < 3; ++k) {
        va.push_back(a.at(x, y, ca[k]));
        vr.push_back(r.at(x, y, cr[k]));
      }
    }
  return relativeRms(va, vr);
}

Image errorHeatMap(const Image& a, const std::string& la, const Image& r, const std::string& lr) {
  auto lum = [](const Image& img, int x, int y, const int* c) {
    return 0.2126f * img.at(x, y, c[0]) + 0.7152f * img.at(x, y, c[1]) + 0.0722f * img.at(x, y, c[2]);
  };
  const char* rgb[3] = {"R", "G", "B"};
  int ca[3], cr[3];
  for (int k = 0; k < 3; ++k) {
    ca[k] = channel(a, la + rgb[k]);
    cr[k] = channel(r, lr + rgb[k]);
  }
  double mean = 0.0;
  for (int y = 0; y < r.height; ++y)
    for (int x = 0; x < r.width; ++x) mean += lum(r, x, y, cr);
  mean = std::max(mean / std::max(1.0, double(r.width) * double(r.height)), 1e-12);
  Image out(a.width, a.height, {"R", "G", "B"});
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const float e =
          std::clamp(float(std::abs(lum(a, x, y, ca) - lum(r, x, y, cr)) / mean) / 0.5f, 0.0f, 1.0f);
      // blue -> green -> yellow -> red
      const glm::vec3 c = e < 0.33f ? glm::mix(glm::vec3(0, 0, 0.5f), glm::vec3(0, 0.8f, 0), e / 0.33f)
                          : e < 0.66f
                              ? glm::mix(glm::vec3(0, 0.8f, 0), glm::vec3(1, 1, 0), (e - 0.33f) / 0.33f)
                              : glm::mix(glm::vec3(1, 1, 0), glm::vec3(1, 0, 0), (e - 0.66f) / 0.34f);
      for (int k = 0; k < 3; ++k) out.at(x, y, k) = c[k];
    }
  return out;
}

double roomFloorIndirect(ShadingRenderer& r, const worlds::SkyModel& sky, const worlds::Aabb& air,
                         bool chebyshev, int points) {
  gpu::GBufferHost g;
  g.height = 1;
  const float last = float(std::max(1, points - 1));
  for (int j = 0; j < points; ++j)
    for (int i = 0; i < points; ++i) {
      const float x = glm::mix(air.min.x + 0.3f, air.max.x - 0.3f, float(i) / last);
      const float z = glm::mix(air.min.z + 0.3f, air.max.z - 0.3f, float(j) / last);
      g.position.push_back(glm::vec4(x, air.min.y + 0.001f, z, 1.0f));
      g.normal.push_back(glm::vec4(0.0f, 1.0f, 0.0f, 1.0f));
      g.albedo.push_back(glm::vec4(0.5f, 0.5f, 0.5f, 0.0f));
      g.emission.push_back(glm::vec4(0.0f));
    }
  g.width = int(g.position.size());
  gpu::ShadingOptions o;
  o.chebyshev = chebyshev;
  o.direct = false;
  o.specular = false;
  const gpu::ShadeOutputHost s = r.shadePoints(sky, g, 0.5f * (air.min + air.max), o);
  double sum = 0.0;
  for (const glm::vec4& d : s.diffuse) sum += 0.2126 * d.x + 0.7152 * d.y + 0.0722 * d.z;
  return sum / double(s.diffuse.size());
}

LeakTestResult measureLeakTest(gpu::Context& ctx, const worlds::SyntheticWorld& world, worlds::CellCoord cc,
                               const worlds::SkyModel& sky, const CaptureOptions& co) {
  worlds::BuiltCell cell = worlds::buildCell(world, cc);
  if (cell.layout.leakTests.empty()) fail("cell {},{} has no leak-test house", cc.x, cc.z);
  const worlds::LeakTestSite& site = cell.layout.leakTests[0];
  const worlds::Room& lit = cell.layout.rooms[size_t(site.litRoom)];
  const worlds::Room& sealed = cell.layout.rooms[size_t(site.sealedRoom)];
  const worlds::Aabb house = cell.layout.buildings[size_t(site.building)].bounds;
  const ProbeGrid& grid = cell.probes.grid;
  LeakTestResult res;
  std::vector<uint8_t> active(size_t(grid.probeCount()), 0);
  const glm::vec3 margin = grid.spacing * 1.01f;
  for (int64_t i = 0; i < grid.probeCount(); ++i) {
    const glm::vec3 p = cell.probes.position(i);
    if (cell.probes.flags[size_t(i)] & worlds::kProbeDisabledSolid) continue;
    if (glm::all(glm::greaterThanEqual(p, house.min - margin)) &&
        glm::all(glm::lessThanEqual(p, house.max + margin))) {
      active[size_t(i)] = 1;
      ++res.probes;
    }
  }
  const EmbreeScene scene(cell.mesh, "leak-test cell");
  const ProbeField f = captureGridField(scene, sky, grid, cell.probes.offsets, active, co);
  ShadingRenderer r(ctx, cell.mesh);
  const ProbeField* fields[] = {&f};
  r.setProbes(fields, 1);
  res.litOn = roomFloorIndirect(r, sky, lit.air, true, 5);
  res.sealedOn = roomFloorIndirect(r, sky, sealed.air, true, 5);
  res.litOff = roomFloorIndirect(r, sky, lit.air, false, 5);
  res.sealedOff = roomFloorIndirect(r, sky, sealed.air, false, 5);
  return res;
}

}  // namespace lfgi::bake
