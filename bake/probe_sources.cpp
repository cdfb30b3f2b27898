#include "bake/probe_sources.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "bake/path_trace.h"
#include "bake/shading_inputs.h"
#include "core/error.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/quantize.h"
#include "core/sh.h"
#include "gpu/relight_pass.h"
#include "shared/octahedral.h"
#include "shared/relight.h"
#include "shared/vir.h"

namespace lfgi::bake {

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

namespace {

void checkGridInputs(const ProbeGrid& grid, std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                     const char* what) {
  grid.validate();
  const size_t count = size_t(grid.probeCount());
  if (!offsets.empty() && offsets.size() != count)
    fail("{}: {} probe offsets for a grid of {} probes", what, offsets.size(), count);
  if (!active.empty() && active.size() != count)
    fail("{}: {} active flags for a grid of {} probes", what, active.size(), count);
}

}  // namespace

ProbeField virProbeField(gpu::Context& ctx, std::span<const worlds::Surfel> surfels, const ProbeGrid& grid,
                         std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                         const worlds::SkyModel& sky, const VirProbeOptions& o, VirProbeStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  checkGridInputs(grid, offsets, active, "virProbeField");
  if (o.resolution < 4 || o.resolution > 64) fail("virProbeField: resolution {} outside [4, 64]", o.resolution);
  if (o.frames < 1 || o.frames > 64) fail("virProbeField: frames {} outside [1, 64]", o.frames);
  if (!(o.maxRange > 0.0f)) fail("virProbeField: maxRange {} must be > 0", o.maxRange);
  if (surfels.empty()) fail("virProbeField: no surfels");

  // Only the box of lattice indices that holds active probes is relit and splatted (VIR's cost is per
  // (surfel, probe) pair), and only surfels within maxRange of that box.
  const size_t count = size_t(grid.probeCount());
  auto isActive = [&](size_t i) { return active.empty() || active[i] != 0; };
  glm::ivec3 lo(INT32_MAX), hi(INT32_MIN);
  for (size_t i = 0; i < count; ++i)
    if (isActive(i)) {
      const glm::ivec3 c = grid.probeCoord(int64_t(i));
      lo = glm::min(lo, c);
      hi = glm::max(hi, c);
    }
  ProbeField f;
  f.grid = grid;
  f.resolution = o.resolution;
  f.irradianceResolution = o.irradianceResolution;
  f.offsets.assign(offsets.begin(), offsets.end());
  f.active.assign(count, 0);
  const int n = o.resolution, m = o.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  f.radiance.assign(count * n2 * 3, 0.0f);
  f.distance.assign(count * n2 * 2, 0.0f);
  f.irradiance.assign(count * m2 * 3, 0.0f);
  if (lo.x == INT32_MAX) return f;  // nothing active

  ProbeGrid sub = grid;
  sub.dims = hi - lo + 1;
  sub.origin = grid.probePosition(lo);
  gpu::RelightProbes probes;
  probes.grid = sub;
  std::vector<size_t> toFull;
  glm::vec3 boxLo(1e30f), boxHi(-1e30f);
  for (int64_t k = 0; k < sub.probeCount(); ++k) {
    const size_t i = size_t(grid.linearIndex(lo + sub.probeCoord(k)));
    toFull.push_back(i);
    const glm::vec3 p = grid.probePosition(grid.probeCoord(int64_t(i))) + (offsets.empty() ? glm::vec3(0.0f) : offsets[i]);
    probes.positions.push_back(p);
    probes.active.push_back(isActive(i) ? 1 : 0);
    boxLo = glm::min(boxLo, p);
    boxHi = glm::max(boxHi, p);
  }
  std::vector<worlds::Surfel> near;
  for (const worlds::Surfel& s : surfels) {
    const glm::vec3 p(s.positionRadius);
    const glm::vec3 d = glm::max(glm::max(boxLo - p, p - boxHi), glm::vec3(0.0f));
    if (glm::dot(d, d) <= o.maxRange * o.maxRange) near.push_back(s);
  }
  if (near.empty()) fail("virProbeField: no surfel within {} m of the active probes", o.maxRange);

  gpu::RelightPass relight(ctx);
  gpu::VirPass vir(ctx);
  gpu::VirOptions vo;
  vo.resolution = n;
  vo.maxRange = o.maxRange;
  gpu::RelightOptions ro;
  ro.irradianceResolution = m;
  gpu::CellLighting state;
  double gpuMs = 0.0;
  for (int frame = 0; frame < o.frames; ++frame) {
    if (InterruptGuard::interrupted()) fail("VIR probes interrupted after {} of {} frames", frame, o.frames);
    const gpu::RelightResult r = gpu::relightFrame(relight, vir, near, probes, sky.params, vo, ro, state);
    gpuMs += r.shadowMs + r.lightMs + state.atlas.gpuMs + state.probes.gpuMs;
  }

  const gpu::ProbeAtlas& atlas = state.atlas;
  std::vector<glm::vec3> skyDir(n2);
  std::vector<glm::vec3> skyL(n2);
  for (size_t t = 0; t < n2; ++t) {
    skyDir[t] = shared::octTexelDirection(glm::uvec2(uint32_t(t % size_t(n)), uint32_t(t / size_t(n))), uint32_t(n));
    skyL[t] = worlds::skyRadiance(sky, skyDir[t]);
  }
  for (size_t k = 0; k < toFull.size(); ++k) {
    const size_t i = toFull[k];
    if (!probes.active[k]) continue;
    f.active[i] = 1;
    for (size_t t = 0; t < n2; ++t) {
      const size_t a = k * n2 + t;
      // As the relight convolution: texels no surfel covered, or only the hole fill covered, see the sky.
      const bool covered = atlas.normal[a].w == LFGI_VIR_COVERED;
      const glm::vec3 L = covered ? glm::vec3(atlas.radiance[a]) : skyL[t];
      for (int c = 0; c < 3; ++c) f.radiance[(i * n2 + t) * 3 + size_t(c)] = L[c];
      f.distance[(i * n2 + t) * 2] = state.probes.moments[a].x;
      f.distance[(i * n2 + t) * 2 + 1] = state.probes.moments[a].y;
    }
    for (size_t t = 0; t < m2; ++t)
      for (int c = 0; c < 3; ++c) f.irradiance[(i * m2 + t) * 3 + size_t(c)] = state.probes.irradiance[k * m2 + t][c];
  }
  if (stats) {
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    stats->gpuMs = gpuMs;
    stats->surfels = near.size();
    stats->probes = probes.positions.size();
  }
  f.validate();
  return f;
}

ProbeField codecProbeField(const CellFile& cell, const std::string& what, const EmbreeScene& scene,
                           const worlds::SkyModel& sky, int resolution, int irradianceResolution, float missDistance) {
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
    GeneratorCpu decoder(dequantizeWeights(cell.generator->weights));
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
      fail("{}: {} latent floats for {} active probes of dimension {}", what, latents.size(), activeIndex.size(), L);
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
      std::copy_n(dense.radiance.begin() + ptrdiff_t(k * n2 * 3), n2 * 3, f.radiance.begin() + ptrdiff_t(i * n2 * 3));
      std::copy_n(dense.distance.begin() + ptrdiff_t(k * n2 * 2), n2 * 2, f.distance.begin() + ptrdiff_t(i * n2 * 2));
      std::copy_n(dense.normal.begin() + ptrdiff_t(k * n2 * 3), n2 * 3, f.normal.begin() + ptrdiff_t(i * n2 * 3));
      std::copy_n(dense.albedo.begin() + ptrdiff_t(k * n2 * 3), n2 * 3, f.albedo.begin() + ptrdiff_t(i * n2 * 3));
    }
    // Decoded maps may dip below zero or violate r^2 >= r^2 slightly; the shading pass assumes neither.
    for (float& v : f.radiance) v = std::max(v, 0.0f);
    for (size_t t = 0; t < f.distance.size(); t += 2) {
      f.distance[t] = std::max(f.distance[t], 0.0f);
      f.distance[t + 1] = std::max(f.distance[t + 1], f.distance[t] * f.distance[t]);
    }
  } else {
    if (resolution < 1 || resolution > 256) fail("{}: resolution {} outside [1, 256]", what, resolution);
    f.resolution = resolution;
    const int n = resolution;
    const size_t n2 = size_t(n) * size_t(n);
    if (cell.fallback.shHalf.size() < 12) fail("{}: the cell file has no SH L1 fallback", what);
    ShL1 sh;
    for (int k = 0; k < 12; ++k) sh.c[size_t(k / 3)][k % 3] = halfToFloat(cell.fallback.shHalf[size_t(k)]);
    std::vector<float> map(n2 * 3);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const glm::vec3 L = glm::max(shEvaluate<4>(sh, octTexelDirection(i, j, n)), glm::vec3(0.0f));
        for (int ch = 0; ch < 3; ++ch) map[size_t(j * n + i) * 3 + size_t(ch)] = L[ch];
      }
    f.radiance.assign(count * n2 * 3, 0.0f);
    f.distance.assign(count * n2 * 2, 0.0f);
    for (int64_t i : activeIndex) {
      std::copy(map.begin(), map.end(), f.radiance.begin() + ptrdiff_t(size_t(i) * n2 * 3));
      for (size_t t = 0; t < n2; ++t) {
        f.distance[(size_t(i) * n2 + t) * 2] = missDistance;
        f.distance[(size_t(i) * n2 + t) * 2 + 1] = missDistance * missDistance;
      }
    }
  }

  const int n = f.resolution, m = irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  // The bake trains on maps with the sun/moon deposited in one texel; a generator reproduces that spike
  // blurred over its neighbours, so subtracting the exact disc energy afterwards leaves a residual that is
  // small against the total irradiance (the bake's stored error) but large against the indirect light
  // (measured on a world cell at noon: shaded indirect rel RMS 0.67). Instead, where a probe sees a disc,
  // the disc's texel and its 8 neighbours are replaced by the analytic sky (no disc) before the
  // irradiance is integrated: the sky there is known, the decoded spike is not.
  const detail::Discs discs = detail::activeDiscs(sky);
  for (int d = 0; d < discs.count; ++d) {
    const glm::vec3 dir = discs.light[d]->direction;
    const glm::ivec2 c = octDirectionTexel(dir, n);
    for (int64_t i : activeIndex) {
      if (scene.occluded(f.probePosition(i), dir, 0.0f, missDistance)) continue;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const glm::ivec2 t = shared::relightOctWrap(c + glm::ivec2(dx, dy), n);
          const glm::vec3 L = worlds::skyRadiance(sky, octTexelDirection(t.x, t.y, n));
          for (int ch = 0; ch < 3; ++ch) f.radiance[(size_t(i) * n2 + size_t(t.y * n + t.x)) * 3 + size_t(ch)] = L[ch];
        }
    }
  }
  const std::vector<double> omega = octTexelSolidAngles(n);
  f.irradiance.assign(count * m2 * 3, 0.0f);
  for (int64_t i : activeIndex) {
    const std::span<const float> rad(f.radiance.data() + size_t(i) * n2 * 3, n2 * 3);
    for (size_t t = 0; t < m2; ++t) {
      const glm::vec3 e = bruteForceIrradiance(rad, n, octTexelDirection(int(t % size_t(m)), int(t / size_t(m)), m), omega);
      for (int c = 0; c < 3; ++c) f.irradiance[(size_t(i) * m2 + t) * 3 + size_t(c)] = e[c];
    }
  }
  f.validate();
  return f;
}

}  // namespace lfgi::bake
