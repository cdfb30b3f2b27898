#include "gpu/probe_shading_pass.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi::gpu {

ShadingProbeSet packShadingProbes(std::span<const ShadingCellInput> cells, int levels) {
  if (cells.empty()) fail("probe shading: no cells given");
  if (levels < 1 || levels > 16) fail("probe shading: {} specular levels outside [1, 16]", levels);
  ShadingProbeSet s;
  s.specularLevels = levels;
  s.minSpacing = 1e30f;
  for (size_t c = 0; c < cells.size(); ++c) {
    const ProbeField* f = cells[c].field;
    if (!f) fail("probe shading: cell {} has no field", c);
    try {
      f->validate();
    } catch (const Error& e) {
      fail("probe shading: cell {}: {}", c, e.what());
    }
    if (c == 0) {
      s.resolution = f->resolution;
      s.irradianceResolution = f->irradianceResolution;
    } else if (f->resolution != s.resolution || f->irradianceResolution != s.irradianceResolution) {
      fail("probe shading: cell {} has resolutions {}/{}, cell 0 has {}/{} (all cells must agree)", c, f->resolution,
           f->irradianceResolution, s.resolution, s.irradianceResolution);
    }
    const int n = f->resolution, m = f->irradianceResolution;
    const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
    const int64_t count = f->probeCount();
    if (!cells[c].specular.empty() && cells[c].specular.size() != size_t(count) * size_t(levels) * n2 * 3)
      fail("probe shading: cell {}: specular holds {} floats, expected {} probes x {} levels x {}x{}x3", c,
           cells[c].specular.size(), count, levels, n, n);
    s.minSpacing = std::min({s.minSpacing, f->grid.spacing.x, f->grid.spacing.y, f->grid.spacing.z});
    shared::ShadeCell sc{glm::vec4(f->grid.origin, 0.0f), glm::vec4(f->grid.spacing, 0.0f),
                         glm::ivec4(f->grid.dims, int(s.probes.size()))};
    s.cells.push_back(sc);
    for (int64_t i = 0; i < count; ++i) {
      s.probes.push_back(glm::vec4(f->probePosition(i), f->isActive(i) ? 1.0f : 0.0f));
      const std::vector<float> irr = makeBordered(
          std::span<const float>(f->irradiance).subspan(size_t(i) * m2 * 3, m2 * 3), m, 3);
      for (size_t t = 0; t < irr.size() / 3; ++t)
        s.irradiance.push_back(glm::vec4(irr[t * 3], irr[t * 3 + 1], irr[t * 3 + 2], 0.0f));
      const std::vector<float> mom =
          makeBordered(std::span<const float>(f->distance).subspan(size_t(i) * n2 * 2, n2 * 2), n, 2);
      for (size_t t = 0; t < mom.size() / 2; ++t) s.moments.push_back(glm::vec2(mom[t * 2], mom[t * 2 + 1]));
      for (int l = 0; l < levels; ++l) {
        std::span<const float> src =
            cells[c].specular.empty()
                ? std::span<const float>(f->radiance).subspan(size_t(i) * n2 * 3, n2 * 3)
                : cells[c].specular.subspan((size_t(i) * size_t(levels) + size_t(l)) * n2 * 3, n2 * 3);
        const std::vector<float> b = makeBordered(src, n, 3);
        for (size_t t = 0; t < b.size() / 3; ++t) s.specular.push_back(glm::vec4(b[t * 3], b[t * 3 + 1], b[t * 3 + 2], 0.0f));
      }
    }
  }
  return s;
}

ShadeOutput createShadeOutput(Context& ctx, int width, int height) {
  if (width < 1 || height < 1) fail("shade output: size {}x{} must be at least 1x1", width, height);
  ShadeOutput o;
  o.width = width;
  o.height = height;
  const VkDeviceSize bytes = VkDeviceSize(width) * VkDeviceSize(height) * sizeof(glm::vec4);
  o.direct = createStorageBuffer(ctx, bytes);
  o.diffuse = createStorageBuffer(ctx, bytes);
  o.specular = createStorageBuffer(ctx, bytes);
  o.total = createStorageBuffer(ctx, bytes);
  return o;
}

ShadeOutputHost readShadeOutput(Context& ctx, const ShadeOutput& o) {
  ShadeOutputHost h;
  h.width = o.width;
  h.height = o.height;
  const size_t n = size_t(o.width) * size_t(o.height);
  for (auto [dst, src] : {std::pair{&h.direct, &o.direct}, std::pair{&h.diffuse, &o.diffuse},
                          std::pair{&h.specular, &o.specular}, std::pair{&h.total, &o.total}}) {
    dst->resize(n);
    readback<glm::vec4>(ctx, *src, *dst);
  }
  return h;
}

ProbeShadingPass::ProbeShadingPass(Context& ctx)
    : ctx_(ctx), program_(ctx, "probe_shade"), params_(createStorageBuffer(ctx, sizeof(shared::ShadeParams))) {}

void ProbeShadingPass::setProbes(const ShadingProbeSet& s) {
  const size_t probes = s.probes.size();
  const size_t mb = size_t(s.irradianceResolution + 2) * size_t(s.irradianceResolution + 2);
  const size_t nb = size_t(s.resolution + 2) * size_t(s.resolution + 2);
  if (probes == 0 || s.irradiance.size() != probes * mb || s.moments.size() != probes * nb ||
      s.specular.size() != probes * nb * size_t(s.specularLevels))
    fail("probe shading: inconsistent probe set ({} probes, {} irradiance, {} moment, {} specular texels)", probes,
         s.irradiance.size(), s.moments.size(), s.specular.size());
  cells_ = createStorageBuffer(ctx_, s.cells.size() * sizeof(shared::ShadeCell));
  probes_ = createStorageBuffer(ctx_, probes * sizeof(glm::vec4));
  irradiance_ = createStorageBuffer(ctx_, s.irradiance.size() * sizeof(glm::vec4));
  moments_ = createStorageBuffer(ctx_, s.moments.size() * sizeof(glm::vec2));
  specular_ = createStorageBuffer(ctx_, s.specular.size() * sizeof(glm::vec4));
  upload<shared::ShadeCell>(ctx_, cells_, s.cells);
  upload<glm::vec4>(ctx_, probes_, s.probes);
  upload<glm::vec4>(ctx_, irradiance_, s.irradiance);
  upload<glm::vec2>(ctx_, moments_, s.moments);
  upload<glm::vec4>(ctx_, specular_, s.specular);
  minSpacing_ = s.minSpacing;
  cellCount_ = uint32_t(s.cells.size());
  maps_ = glm::uvec4(uint32_t(s.irradianceResolution), uint32_t(s.resolution), uint32_t(s.specularLevels), 0);
  haveProbes_ = true;
}

void ProbeShadingPass::setView(const shared::SkyParams& sky, const shared::GpuCamera& camera, int width, int height,
                               const GpuSceneBuffers& scene, const ShadingOptions& o) {
  if (!haveProbes_) fail("probe shading: setView before setProbes");
  shared::ShadeParams p{};
  p.sky = sky;
  p.camera = camera;
  p.size = glm::uvec4(uint32_t(width), uint32_t(height), cellCount_, scene.nodeCount);
  p.maps = maps_;
  p.maps.w = (o.chebyshev ? 1u : 0u) | (o.backface ? 2u : 0u) | (o.sunShadows && scene.triangleCount > 0 ? 4u : 0u);
  p.bias = glm::vec4(o.normalBias >= 0.0f ? o.normalBias : 0.045f * minSpacing_,
                     o.viewBias >= 0.0f ? o.viewBias : 0.18f * minSpacing_, o.chebyshevFloor, o.maxDistance);
  if (!(std::isfinite(o.aoRadius) && o.aoRadius >= 0.0f)) fail("shading: aoRadius {} must be finite and >= 0", o.aoRadius);
  p.weights = glm::vec4(o.direct ? 1.0f : 0.0f, o.diffuse ? 1.0f : 0.0f, o.specular ? 1.0f : 0.0f,
                        scene.triangleCount > 0 ? o.aoRadius : 0.0f);
  upload<shared::ShadeParams>(ctx_, params_, std::span(&p, 1));
  width_ = width;
  height_ = height;
}

void ProbeShadingPass::record(VkCommandBuffer cmd, const GpuSceneBuffers& scene, const GBuffer& g,
                              ShadeOutput& out) const {
  if (!haveProbes_ || width_ == 0) fail("probe shading: record before setProbes/setView");
  if (g.width != width_ || g.height != height_ || out.width != width_ || out.height != height_)
    fail("probe shading: G-buffer {}x{} / output {}x{} differ from the view {}x{}", g.width, g.height, out.width,
         out.height, width_, height_);
  dispatch(ctx_, cmd, program_,
           {&params_, &cells_, &probes_, &irradiance_, &moments_, &specular_, &scene.nodes, &scene.triangles,
            &g.position, &g.normal, &g.albedo, &g.emission, &out.direct, &out.diffuse, &out.specular, &out.total},
           std::span<const std::byte>(), {uint32_t(width_), uint32_t(height_), 1});
}

}  // namespace lfgi::gpu
