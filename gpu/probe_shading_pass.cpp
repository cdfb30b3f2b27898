#include "gpu/probe_shading_pass.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi::gpu {

namespace {

// The fallback irradiance E(n) = a + b.x n.x + b.y n.y + b.z n.z of an SH L1 radiance (shIrradiance is
// linear in n: a and b from its values at the +-axes).
void packShadeCellFallback(const ShL1& sh, shared::ShadeCell& out) {
  glm::vec3 plus[3], minus[3];
  for (int a = 0; a < 3; ++a) {
    glm::vec3 d(0.0f);
    d[a] = 1.0f;
    plus[a] = shIrradiance(sh, d);
    minus[a] = shIrradiance(sh, -d);
  }
  out.fallback[0] = glm::vec4(0.5f * (plus[0] + minus[0]), 0.0f);
  for (int a = 0; a < 3; ++a) out.fallback[1 + a] = glm::vec4(0.5f * (plus[a] - minus[a]), 0.0f);
}

bool ownsXZ(const shared::ShadeCell& c, glm::vec2 q) {
  const glm::vec2 lo(c.origin.x, c.origin.z);
  const glm::vec2 hi = lo + glm::vec2(float(c.dims.x) * c.spacing.x, float(c.dims.z) * c.spacing.z);
  return q.x >= lo.x && q.y >= lo.y && q.x < hi.x && q.y < hi.y;
}

// The fallback neighbour table of every cell (shared::ShadeCell::fallbackCells): the cell owning this
// cell's centre + (dx, dz) x box size, clamped per axis where there is none (StreamingManager clamps at the
// world edge), else the cell itself.
void linkFallbackCells(std::vector<shared::ShadeCell>& cells) {
  for (size_t c = 0; c < cells.size(); ++c) {
    const shared::ShadeCell& me = cells[c];
    const glm::vec2 size(float(me.dims.x) * me.spacing.x, float(me.dims.z) * me.spacing.z);
    const glm::vec2 centre = glm::vec2(me.origin.x, me.origin.z) + 0.5f * size;
    auto find = [&](int dx, int dz) -> int {
      if (dx == 0 && dz == 0) return int(c);
      const glm::vec2 q = centre + glm::vec2(float(dx), float(dz)) * size;
      for (size_t i = 0; i < cells.size(); ++i)
        if (i != c && ownsXZ(cells[i], q)) return int(i);
      return -1;
    };
    int table[9];
    for (int dz = -1; dz <= 1; ++dz)
      for (int dx = -1; dx <= 1; ++dx) {
        int n = find(dx, dz);
        if (n < 0) {
          const int cx = dx != 0 && find(dx, 0) < 0 ? 0 : dx, cz = dz != 0 && find(0, dz) < 0 ? 0 : dz;
          n = find(cx, cz);
        }
        table[(dz + 1) * 3 + dx + 1] = n < 0 ? int(c) : n;
      }
    for (int k = 0; k < 9; ++k) cells[c].fallbackCells[k / 4][k % 4] = table[k];
    for (int k = 9; k < 12; ++k) cells[c].fallbackCells[k / 4][k % 4] = int(c);
  }
}

// Appends field's probes and bordered maps (irradiance, moments, `levels` specular levels: `specular`, or
// the raw radiance at every level when it is empty) to s.
void appendFieldMaps(const ProbeField& f, std::span<const float> specular, int levels, ShadingProbeSet& s) {
  const int n = f.resolution, m = f.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  for (int64_t i = 0; i < f.probeCount(); ++i) {
    s.probes.push_back(glm::vec4(f.probePosition(i), f.isActive(i) ? 1.0f : 0.0f));
    const std::vector<float> irr =
        makeBordered(std::span<const float>(f.irradiance).subspan(size_t(i) * m2 * 3, m2 * 3), m, 3);
    for (size_t t = 0; t < irr.size() / 3; ++t)
      s.irradiance.push_back(glm::vec4(irr[t * 3], irr[t * 3 + 1], irr[t * 3 + 2], 0.0f));
    const std::vector<float> mom =
        makeBordered(std::span<const float>(f.distance).subspan(size_t(i) * n2 * 2, n2 * 2), n, 2);
    for (size_t t = 0; t < mom.size() / 2; ++t) s.moments.push_back(glm::vec2(mom[t * 2], mom[t * 2 + 1]));
    for (int l = 0; l < levels; ++l) {
      std::span<const float> src =
          specular.empty() ? std::span<const float>(f.radiance).subspan(size_t(i) * n2 * 3, n2 * 3)
                           : specular.subspan((size_t(i) * size_t(levels) + size_t(l)) * n2 * 3, n2 * 3);
      const std::vector<float> b = makeBordered(src, n, 3);
      for (size_t t = 0; t < b.size() / 3; ++t)
        s.specular.push_back(glm::vec4(b[t * 3], b[t * 3 + 1], b[t * 3 + 2], 0.0f));
    }
  }
}

}  // namespace

ShadingProbeSet packShadingProbes(std::span<const ShadingCellInput> cells, int levels) {
  if (cells.empty()) fail("probe shading: no cells given");
  if (levels < 1 || levels > 16) fail("probe shading: {} specular levels outside [1, 16]", levels);
  ShadingProbeSet s;
  s.specularLevels = levels;
  s.minSpacing = 1e30f;
  bool haveResolution = false;
  for (size_t c = 0; c < cells.size(); ++c) {
    const ShadingCellInput& in = cells[c];
    for (int k = 0; k < 4; ++k)
      if (!std::isfinite(in.fallback.c[size_t(k)].x + in.fallback.c[size_t(k)].y +
                         in.fallback.c[size_t(k)].z))
        fail("probe shading: cell {}: fallback SH coefficient {} is not finite", c, k);
    if (in.fallbackOnly) {
      if (in.field) fail("probe shading: cell {} is fallback-only but has a field", c);
      try {
        in.box.validate();
      } catch (const Error& e) {
        fail("probe shading: cell {}: fallback-only box: {}", c, e.what());
      }
      shared::ShadeCell sc{glm::vec4(in.box.origin, 0.0f),
                           glm::vec4(in.box.spacing, 1.0f),
                           glm::ivec4(in.box.dims, -1),
                           {},
                           {}};
      packShadeCellFallback(in.fallback, sc);
      s.cells.push_back(sc);
      continue;
    }
    const ProbeField* f = in.field;
    if (!f)
      fail("probe shading: cell {} has no field (a cell shaded from its SH L1 alone is fallbackOnly)", c);
    if (!(in.fade >= 0.0f && in.fade <= 1.0f))
      fail("probe shading: cell {}: fade {} outside [0, 1]", c, in.fade);
    try {
      f->validate();
    } catch (const Error& e) {
      fail("probe shading: cell {}: {}", c, e.what());
    }
    if (!haveResolution) {
      s.resolution = f->resolution;
      s.irradianceResolution = f->irradianceResolution;
      haveResolution = true;
    } else if (f->resolution != s.resolution || f->irradianceResolution != s.irradianceResolution) {
      fail("probe shading: cell {} has resolutions {}/{}, an earlier cell has {}/{} (all cells must agree)",
           c, f->resolution, f->irradianceResolution, s.resolution, s.irradianceResolution);
    }
    const int n = f->resolution;
    const size_t n2 = size_t(n) * size_t(n);
    const int64_t count = f->probeCount();
    if (!in.specular.empty() && in.specular.size() != size_t(count) * size_t(levels) * n2 * 3)
      fail("probe shading: cell {}: specular holds {} floats, expected {} probes x {} levels x {}x{}x3", c,
           in.specular.size(), count, levels, n, n);
    s.minSpacing = std::min({s.minSpacing, f->grid.spacing.x, f->grid.spacing.y, f->grid.spacing.z});
    shared::ShadeCell sc{glm::vec4(f->grid.origin, in.fade),
                         glm::vec4(f->grid.spacing, 0.0f),
                         glm::ivec4(f->grid.dims, int(s.probes.size())),
                         {},
                         {}};
    packShadeCellFallback(in.fallback, sc);
    s.cells.push_back(sc);
    appendFieldMaps(*f, in.specular, levels, s);
  }
  if (!haveResolution) {  // fallback-only: no maps are read; 1 x 1 keeps the layout well-formed
    s.resolution = 1;
    s.irradianceResolution = 1;
    s.minSpacing = 1.0f;
  }
  linkFallbackCells(s.cells);
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
    : ctx_(ctx),
      program_(ctx, "probe_shade"),
      params_(createStorageBuffer(ctx, sizeof(shared::ShadeParams))) {}

void ProbeShadingPass::setProbes(const ShadingProbeSet& s) {
  const size_t probes = s.probes.size();
  const size_t mb = size_t(s.irradianceResolution + 2) * size_t(s.irradianceResolution + 2);
  const size_t nb = size_t(s.resolution + 2) * size_t(s.resolution + 2);
  if (s.cells.empty() || s.irradiance.size() != probes * mb || s.moments.size() != probes * nb ||
      s.specular.size() != probes * nb * size_t(s.specularLevels))
    fail(
        "probe shading: inconsistent probe set ({} cells, {} probes, {} irradiance, {} moment, {} specular "
        "texels)",
        s.cells.size(), probes, s.irradiance.size(), s.moments.size(), s.specular.size());
  cells_ = createStorageBuffer(ctx_, s.cells.size() * sizeof(shared::ShadeCell));
  upload<shared::ShadeCell>(ctx_, cells_, s.cells);
  // Every cell fallback-only: no probe is read, but each binding needs a buffer (one zero element).
  auto store = [&]<typename T>(Buffer& b, const std::vector<T>& v) {
    const std::vector<T> one(1, T(0));
    const std::vector<T>& src = v.empty() ? one : v;
    b = createStorageBuffer(ctx_, src.size() * sizeof(T));
    upload<T>(ctx_, b, src);
  };
  store(probes_, s.probes);
  store(irradiance_, s.irradiance);
  store(moments_, s.moments);
  store(specular_, s.specular);
  minSpacing_ = s.minSpacing;
  cellCount_ = uint32_t(s.cells.size());
  maps_ = glm::uvec4(uint32_t(s.irradianceResolution), uint32_t(s.resolution), uint32_t(s.specularLevels), 0);
  pool_ = {};
  haveProbes_ = true;
}

size_t ProbeShadingPass::deviceBytes() const {
  size_t sum = 0;
  for (const Buffer* b : {&params_, &cells_, &probes_, &irradiance_, &moments_, &specular_})
    sum += size_t(b->size());
  return sum;
}

void ProbeShadingPass::reservePool(int slots, int64_t probesPerSlot, int irradianceResolution, int resolution,
                                   int specularLevels) {
  if (slots < 1 || probesPerSlot < 1 || irradianceResolution < 1 || resolution < 1 || specularLevels < 1 ||
      specularLevels > 16)
    fail("probe shading: pool of {} slots x {} probes, maps {}/{}, {} levels (each >= 1, levels <= 16)",
         slots, probesPerSlot, irradianceResolution, resolution, specularLevels);
  const VkDeviceSize probes = VkDeviceSize(slots) * VkDeviceSize(probesPerSlot);
  const VkDeviceSize mb = VkDeviceSize(irradianceResolution + 2) * VkDeviceSize(irradianceResolution + 2);
  const VkDeviceSize nb = VkDeviceSize(resolution + 2) * VkDeviceSize(resolution + 2);
  probes_ = createStorageBuffer(ctx_, probes * sizeof(glm::vec4));
  fillBuffer(ctx_, probes_, 0);  // every probe inactive until its slot is uploaded
  irradiance_ = createStorageBuffer(ctx_, probes * mb * sizeof(glm::vec4));
  moments_ = createStorageBuffer(ctx_, probes * nb * sizeof(glm::vec2));
  specular_ = createStorageBuffer(ctx_, probes * nb * VkDeviceSize(specularLevels) * sizeof(glm::vec4));
  pool_ = {slots, probesPerSlot};
  maps_ = glm::uvec4(uint32_t(irradianceResolution), uint32_t(resolution), uint32_t(specularLevels), 0);
  haveProbes_ = false;  // setPoolCells gives the cells
}

size_t ProbeShadingPass::uploadPoolSlot(int slot, const ProbeField& field) {
  if (pool_.slots == 0) fail("probe shading: uploadPoolSlot before reservePool");
  if (slot < 0 || slot >= pool_.slots) fail("probe shading: pool slot {} outside [0, {})", slot, pool_.slots);
  field.validate();
  if (field.probeCount() > pool_.probesPerSlot || uint32_t(field.irradianceResolution) != maps_.x ||
      uint32_t(field.resolution) != maps_.y)
    fail("probe shading: a field of {} probes, maps {}/{} does not fit a pool slot of {} probes, maps {}/{}",
         field.probeCount(), field.irradianceResolution, field.resolution, pool_.probesPerSlot, maps_.x,
         maps_.y);
  ShadingProbeSet one;
  appendFieldMaps(field, {}, int(maps_.z), one);
  const VkDeviceSize first = VkDeviceSize(slot) * VkDeviceSize(pool_.probesPerSlot);
  auto put = [&]<typename T>(Buffer& b, const std::vector<T>& v, VkDeviceSize perProbe) {
    upload<T>(ctx_, b, v, first * perProbe * sizeof(T));
  };
  const VkDeviceSize mb = VkDeviceSize(maps_.x + 2) * (maps_.x + 2),
                     nb = VkDeviceSize(maps_.y + 2) * (maps_.y + 2);
  put(probes_, one.probes, 1);
  put(irradiance_, one.irradiance, mb);
  put(moments_, one.moments, nb);
  put(specular_, one.specular, nb * maps_.z);
  return one.probes.size() * sizeof(glm::vec4) + one.irradiance.size() * sizeof(glm::vec4) +
         one.moments.size() * sizeof(glm::vec2) + one.specular.size() * sizeof(glm::vec4);
}

void ProbeShadingPass::setPoolCells(std::span<const ShadingCellInput> cells, std::span<const int> slots) {
  if (pool_.slots == 0) fail("probe shading: setPoolCells before reservePool");
  if (cells.empty() || slots.size() != cells.size())
    fail("probe shading: setPoolCells with {} cells and {} slots", cells.size(), slots.size());
  std::vector<shared::ShadeCell> out;
  float minSpacing = 1e30f;
  for (size_t c = 0; c < cells.size(); ++c) {
    const ShadingCellInput& in = cells[c];
    const bool full = !in.fallbackOnly;
    if (full && (!in.field || slots[c] < 0 || slots[c] >= pool_.slots))
      fail("probe shading: pool cell {} is full but has no field or slot {} outside [0, {})", c, slots[c],
           pool_.slots);
    if (full && !(in.fade >= 0.0f && in.fade <= 1.0f))
      fail("probe shading: cell {}: fade {} outside [0, 1]", c, in.fade);
    const ProbeGrid& g = full ? in.field->grid : in.box;
    g.validate();
    if (full) minSpacing = std::min({minSpacing, g.spacing.x, g.spacing.y, g.spacing.z});
    const int first = full ? int(int64_t(slots[c]) * pool_.probesPerSlot) : -1;
    shared::ShadeCell sc{glm::vec4(g.origin, full ? in.fade : 0.0f),
                         glm::vec4(g.spacing, full ? 0.0f : 1.0f),
                         glm::ivec4(g.dims, first),
                         {},
                         {}};
    packShadeCellFallback(in.fallback, sc);
    out.push_back(sc);
  }
  linkFallbackCells(out);
  if (out.size() != cellCount_ || !cells_.handle())
    cells_ = createStorageBuffer(ctx_, out.size() * sizeof(shared::ShadeCell));
  upload<shared::ShadeCell>(ctx_, cells_, out);
  cellCount_ = uint32_t(out.size());
  minSpacing_ = minSpacing < 1e30f ? minSpacing : 1.0f;
  haveProbes_ = true;
}

shared::ShadeParams ProbeShadingPass::viewParams(const shared::SkyParams& sky,
                                                 const shared::GpuCamera& camera, int width, int height,
                                                 const GpuSceneBuffers& scene, const ShadingOptions& o) {
  if (!haveProbes_) fail("probe shading: setView before setProbes");
  if (!(std::isfinite(o.aoRadius) && o.aoRadius >= 0.0f))
    fail("shading: aoRadius {} must be finite and >= 0", o.aoRadius);
  shared::ShadeParams p{};
  p.sky = sky;
  p.camera = camera;
  p.size = glm::uvec4(uint32_t(width), uint32_t(height), cellCount_, scene.nodeCount);
  p.maps = maps_;
  p.maps.w =
      (o.chebyshev ? 1u : 0u) | (o.backface ? 2u : 0u) | (o.sunShadows && scene.triangleCount > 0 ? 4u : 0u);
  p.bias = glm::vec4(o.normalBias >= 0.0f ? o.normalBias : 0.045f * minSpacing_,
                     o.viewBias >= 0.0f ? o.viewBias : 0.18f * minSpacing_, o.chebyshevFloor, o.maxDistance);
  p.weights = glm::vec4(o.direct ? 1.0f : 0.0f, o.diffuse ? 1.0f : 0.0f, o.specular ? 1.0f : 0.0f,
                        scene.triangleCount > 0 ? o.aoRadius : 0.0f);
  width_ = width;
  height_ = height;
  return p;
}

void ProbeShadingPass::setView(const shared::SkyParams& sky, const shared::GpuCamera& camera, int width,
                               int height, const GpuSceneBuffers& scene, const ShadingOptions& o) {
  const shared::ShadeParams p = viewParams(sky, camera, width, height, scene, o);
  upload<shared::ShadeParams>(ctx_, params_, std::span(&p, 1));
}

void ProbeShadingPass::recordView(VkCommandBuffer cmd, const shared::SkyParams& sky,
                                  const shared::GpuCamera& camera, int width, int height,
                                  const GpuSceneBuffers& scene, const ShadingOptions& o) {
  const shared::ShadeParams p = viewParams(sky, camera, width, height, scene, o);
  recordBufferUpdate(cmd, params_, std::as_bytes(std::span(&p, 1)));
}

void ProbeShadingPass::record(VkCommandBuffer cmd, const GpuSceneBuffers& scene, const GBuffer& g,
                              ShadeOutput& out) const {
  if (!haveProbes_ || width_ == 0) fail("probe shading: record before setProbes/setView");
  if (g.width != width_ || g.height != height_ || out.width != width_ || out.height != height_)
    fail("probe shading: G-buffer {}x{} / output {}x{} differ from the view {}x{}", g.width, g.height,
         out.width, out.height, width_, height_);
  dispatch(
      ctx_, cmd, program_,
      {&params_, &cells_, &probes_, &irradiance_, &moments_, &specular_, &scene.nodes, &scene.triangles,
       &g.position, &g.normal, &g.albedo, &g.emission, &out.direct, &out.diffuse, &out.specular, &out.total},
      std::span<const std::byte>(), {uint32_t(width_), uint32_t(height_), 1});
}

}  // namespace lfgi::gpu
