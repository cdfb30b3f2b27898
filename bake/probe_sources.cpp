#include "bake/probe_sources.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "bake/path_trace.h"
#include "bake/shading_inputs.h"
#include "core/cell_fallback.h"
#include "core/error.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/quantize.h"
#include "core/sh.h"
#include "gpu/vir_probe_field.h"
#include "shared/octahedral.h"
#include "shared/relight.h"
#include "shared/vir.h"

namespace lfgi::bake {

namespace {

void reportStats(const gpu::VirFieldStats& st, VirProbeStats* stats) {
  if (!stats) return;
  stats->seconds = st.seconds;
  stats->gpuMs = st.gpuMs;
  stats->surfels = st.surfels;
  stats->probes = st.probes;
}

}  // namespace

worlds::TriangleMesh meshWithBackFaces(const worlds::TriangleMesh& mesh) {
  worlds::TriangleMesh out = mesh;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    if (!mesh.materials[mesh.triangleMaterial[t]].doubleSided) continue;
    out.indices.push_back(mesh.indices[3 * t]);
    out.indices.push_back(mesh.indices[3 * t + 2]);
    out.indices.push_back(mesh.indices[3 * t + 1]);
    out.triangleMaterial.push_back(mesh.triangleMaterial[t]);
  }
  return out;
}

ProbeField virProbeField(gpu::VirFieldRelighter& relighter, std::span<const worlds::Surfel> surfels,
                         const ProbeGrid& grid, std::span<const glm::vec3> offsets,
                         std::span<const uint8_t> active, const worlds::SkyModel& sky,
                         const VirProbeOptions& o, VirProbeStats* stats) {
  gpu::VirFieldOptions vo;
  vo.resolution = o.resolution;
  vo.irradianceResolution = o.irradianceResolution;
  vo.frames = o.frames;
  vo.maxRange = o.maxRange;
  gpu::VirFieldStats st;
  ProbeField f;
  relighter.run(surfels, grid, offsets, active, sky.params, vo, f, nullptr, &st);
  reportStats(st, stats);
  return f;
}

ProbeField virProbeField(gpu::Context& ctx, std::span<const worlds::Surfel> surfels, const ProbeGrid& grid,
                         std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                         const worlds::SkyModel& sky, const VirProbeOptions& o, VirProbeStats* stats) {
  gpu::VirFieldRelighter relighter(ctx);
  return virProbeField(relighter, surfels, grid, offsets, active, sky, o, stats);
}

void regenerateVirMoments(gpu::VirFieldRelighter& relighter, std::span<const worlds::Surfel> surfels,
                          std::span<const glm::vec3> offsets, ProbeField& field, float maxRange,
                          VirProbeStats* stats) {
  gpu::VirFieldOptions vo;
  vo.maxRange = maxRange;
  gpu::VirFieldStats st;
  ProbeField scratch;
  relighter.regenerateMoments(surfels, offsets, vo, field, scratch, &st);
  reportStats(st, stats);
}

void regenerateVirMoments(gpu::Context& ctx, std::span<const worlds::Surfel> surfels,
                          std::span<const glm::vec3> offsets, ProbeField& field, float maxRange,
                          VirProbeStats* stats) {
  gpu::VirFieldRelighter relighter(ctx);
  regenerateVirMoments(relighter, surfels, offsets, field, maxRange, stats);
}

namespace {

// The active probes' maps decoded by the cell's generator and scattered into f's grid (f.resolution set).
void decodeGeneratorMaps(const CellFile& cell, const std::string& what, const worlds::SkyModel& sky,
                         const ResolvedSharedModel* shared, std::span<const int64_t> activeIndex,
                         size_t count, ProbeField& f) {
  GeneratorCpu decoder(resolveCellWeights(*cell.generator, shared, what));
  const GeneratorArch& arch = decoder.arch();
  f.resolution = arch.outputResolution();
  const size_t L = size_t(arch.latentDim);
  // Decode the active probes only (latent row k = k-th active probe), then scatter into the grid.
  std::vector<float> latents;
  if (arch.latentSource == LatentSource::PositionFourier) {
    latents.resize(activeIndex.size() * L);
    const glm::vec3 ext = cell.grid.boxMax() - cell.grid.origin;
    for (size_t k = 0; k < activeIndex.size(); ++k) {
      const glm::vec3 p = cell.grid.probePosition(cell.grid.probeCoord(activeIndex[k]));
      glm::vec3 q;
      for (int a = 0; a < 3; ++a)
        q[a] = ext[a] > 0.0f ? std::clamp((p[a] - cell.grid.origin[a]) / ext[a], 0.0f, 1.0f) : 0.5f;
      positionLatent(q, arch.fourierOctaves, std::span(latents).subspan(k * L, L));
    }
  } else {
    latents = dequantizeLatents(cell.generator->latents);
  }
  if (latents.size() != activeIndex.size() * L)
    fail("{}: {} latent floats for {} active probes of dimension {}", what, latents.size(),
         activeIndex.size(), L);
  const auto c = conditioningVector(sky.state.timeOfDayHours, sky.state.overcast);
  std::span<const float> cond;
  if (arch.condDim == kConditioningDim) cond = std::span<const float>(c.data(), c.size());
  ProbeField dense;
  dense.grid = ProbeGrid{};
  dense.grid.dims = glm::ivec3(int(activeIndex.size()), 1, 1);
  dense.resolution = f.resolution;
  decodeProbeField(decoder, latents, cond, cell.outputScale, dense);
  const size_t n2 = size_t(f.resolution) * size_t(f.resolution);
  f.radiance.assign(count * n2 * 3, 0.0f);
  f.distance.assign(count * n2 * 2, 0.0f);
  f.normal.assign(count * n2 * 3, 0.0f);
  f.albedo.assign(count * n2 * 3, 0.0f);
  for (size_t k = 0; k < activeIndex.size(); ++k) {
    const size_t i = size_t(activeIndex[k]);
    std::copy_n(dense.radiance.begin() + ptrdiff_t(k * n2 * 3), n2 * 3,
                f.radiance.begin() + ptrdiff_t(i * n2 * 3));
    std::copy_n(dense.distance.begin() + ptrdiff_t(k * n2 * 2), n2 * 2,
                f.distance.begin() + ptrdiff_t(i * n2 * 2));
    std::copy_n(dense.normal.begin() + ptrdiff_t(k * n2 * 3), n2 * 3,
                f.normal.begin() + ptrdiff_t(i * n2 * 3));
    std::copy_n(dense.albedo.begin() + ptrdiff_t(k * n2 * 3), n2 * 3,
                f.albedo.begin() + ptrdiff_t(i * n2 * 3));
  }
  // Decoded maps may dip below zero or violate r^2 >= r^2 slightly; the shading pass assumes neither.
  for (float& v : f.radiance) v = std::max(v, 0.0f);
  for (size_t t = 0; t < f.distance.size(); t += 2) {
    f.distance[t] = std::max(f.distance[t], 0.0f);
    f.distance[t + 1] = std::max(f.distance[t + 1], f.distance[t] * f.distance[t]);
  }
}

// The active probes' radiance and irradiance (cosine convolution of the SH, clamped at 0, as the streaming
// source decodes) from the cell's SH L1 fallback (a per-probe fallback: each probe's own entry) and
// distances at missDistance (f.resolution set).
void fallbackMaps(const CellFile& cell, const std::string& what, const worlds::SkyModel& sky, int resolution,
                  float missDistance, std::span<const int64_t> activeIndex, size_t count, ProbeField& f) {
  if (resolution < 1 || resolution > 256) fail("{}: resolution {} outside [1, 256]", what, resolution);
  f.resolution = resolution;
  const int n = resolution;
  const size_t n2 = size_t(n) * size_t(n);
  if (cell.fallback.shHalf.size() < 12) fail("{}: the cell file has no SH L1 fallback", what);
  // The stored keys blended at this sky's time of day and overcast (as the streaming source decodes).
  const float hours = sky.state.timeOfDayHours, overcast = sky.state.overcast;
  const bool perProbe = cell.fallback.kind == CellFallback::Kind::PerProbe;
  const FallbackKeyBlend blend = fallbackKeyBlend(cell.fallback, hours, overcast);
  const size_t entries = fallbackEntries(cell);
  const int m = f.irradianceResolution;
  const size_t m2 = size_t(m) * size_t(m);
  std::vector<float> map(n2 * 3), irr(m2 * 3);
  auto evaluate = [&](const ShL1& sh) { shProbeMaps(sh, n, m, map.data(), irr.data()); };
  if (!perProbe) evaluate(cellFileFallback(cell, hours, overcast));
  f.radiance.assign(count * n2 * 3, 0.0f);
  f.distance.assign(count * n2 * 2, 0.0f);
  f.irradiance.assign(count * m2 * 3, 0.0f);
  for (size_t k = 0; k < activeIndex.size(); ++k) {
    const size_t i = size_t(activeIndex[k]);
    if (perProbe) evaluate(fallbackEntry(cell.fallback, entries, k, blend));
    std::copy(map.begin(), map.end(), f.radiance.begin() + ptrdiff_t(i * n2 * 3));
    std::copy(irr.begin(), irr.end(), f.irradiance.begin() + ptrdiff_t(i * m2 * 3));
    for (size_t t = 0; t < n2; ++t) {
      f.distance[(i * n2 + t) * 2] = missDistance;
      f.distance[(i * n2 + t) * 2 + 1] = missDistance * missDistance;
    }
  }
}

// Every active probe's irradiance map (m x m) integrated from its radiance.
void integrateIrradiance(ProbeField& f, std::span<const int64_t> activeIndex, size_t count, int m) {
  const int n = f.resolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  const std::vector<double> omega = octTexelSolidAngles(n);
  f.irradiance.assign(count * m2 * 3, 0.0f);
  for (int64_t i : activeIndex) {
    const std::span<const float> rad(f.radiance.data() + size_t(i) * n2 * 3, n2 * 3);
    for (size_t t = 0; t < m2; ++t) {
      const glm::vec3 e =
          bruteForceIrradiance(rad, n, octTexelDirection(int(t % size_t(m)), int(t / size_t(m)), m), omega);
      for (int c = 0; c < 3; ++c) f.irradiance[(size_t(i) * m2 + t) * 3 + size_t(c)] = e[c];
    }
  }
}

}  // namespace

ProbeField codecProbeField(const CellFile& cell, const std::string& what, const worlds::SkyModel& sky,
                           int resolution, int irradianceResolution, float missDistance,
                           const ResolvedSharedModel* shared) {
  cell.validate(what);
  if (irradianceResolution < 1 || irradianceResolution > 64)
    fail("{}: irradiance resolution {} outside [1, 64]", what, irradianceResolution);
  ProbeField f;
  f.grid = cell.grid;
  f.active = cell.active;
  f.irradianceResolution = irradianceResolution;
  const size_t count = size_t(f.probeCount());
  std::vector<int64_t> activeIndex;
  for (size_t i = 0; i < count; ++i)
    if (f.isActive(int64_t(i))) activeIndex.push_back(int64_t(i));
  if (activeIndex.empty()) fail("{}: the cell file holds no active probe", what);

  if (cell.generator) {
    decodeGeneratorMaps(cell, what, sky, shared, activeIndex, count, f);
    integrateIrradiance(f, activeIndex, count, irradianceResolution);
  } else {
    fallbackMaps(cell, what, sky, resolution, missDistance, activeIndex, count, f);
  }
  f.validate();
  return f;
}

}  // namespace lfgi::bake
