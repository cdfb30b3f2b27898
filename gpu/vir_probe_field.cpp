#include "gpu/vir_probe_field.h"

#include <algorithm>
#include <chrono>
#include <climits>

#include "core/error.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/sh.h"
#include "shared/octahedral.h"
#include "shared/relight.h"
#include "shared/vir.h"

namespace lfgi::gpu {

namespace {

void checkInputs(std::span<const shared::Surfel> surfels, const ProbeGrid& grid,
                 std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                 const VirFieldOptions& o, const ProbeField* seed) {
  grid.validate();
  const size_t count = size_t(grid.probeCount());
  if (!offsets.empty() && offsets.size() != count)
    fail("virProbeField: {} probe offsets for a grid of {} probes", offsets.size(), count);
  if (!active.empty() && active.size() != count)
    fail("virProbeField: {} active flags for a grid of {} probes", active.size(), count);
  if (o.resolution < 4 || o.resolution > 64)
    fail("virProbeField: resolution {} outside [4, 64]", o.resolution);
  if (o.irradianceResolution < 1 || o.irradianceResolution > 64)
    fail("virProbeField: irradiance resolution {} outside [1, 64]", o.irradianceResolution);
  if (o.frames < 1 || o.frames > 64) fail("virProbeField: frames {} outside [1, 64]", o.frames);
  if (!(o.maxRange > 0.0f)) fail("virProbeField: maxRange {} must be > 0", o.maxRange);
  if (surfels.empty() && !o.noSurfelsIsSky) fail("virProbeField: no surfels");
  const int n = o.resolution, m = o.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  if (seed && (seed->probeCount() != grid.probeCount() || seed->grid.dims != grid.dims ||
               seed->resolution != n || seed->irradianceResolution != m ||
               seed->irradiance.size() != count * m2 * 3 || seed->distance.size() != count * n2 * 2))
    fail(
        "virProbeField: the seed field ({} probes, n {}, m {}) does not match the grid ({} probes, n {}, m "
        "{})",
        seed->probeCount(), seed->resolution, seed->irradianceResolution, count, n, m);
}

// The field of the whole grid, every probe inactive and zero.
void resetField(const ProbeGrid& grid, std::span<const glm::vec3> offsets, const VirFieldOptions& o,
                ProbeField& f) {
  const size_t count = size_t(grid.probeCount());
  const int n = o.resolution, m = o.irradianceResolution;
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  f.grid = grid;
  f.resolution = n;
  f.irradianceResolution = m;
  if (o.storeOffsets)
    f.offsets.assign(offsets.begin(), offsets.end());
  else
    f.offsets.clear();
  f.active.assign(count, 0);
  f.radiance.assign(count * n2 * 3, 0.0f);
  f.distance.assign(count * n2 * 2, 0.0f);
  f.irradiance.assign(count * m2 * 3, 0.0f);
  f.normal.clear();
  f.albedo.clear();
}

// The box of lattice indices holding active probes, as relit: its probes at lattice + offsets, their
// indices in the grid, and the bounds of their positions.
struct SubGrid {
  RelightProbes probes;
  std::vector<size_t> toFull;
  glm::vec3 boxLo = glm::vec3(1e30f), boxHi = glm::vec3(-1e30f);
};

SubGrid activeSubGrid(const ProbeGrid& grid, std::span<const glm::vec3> offsets,
                      std::span<const uint8_t> active, glm::ivec3 lo, glm::ivec3 hi) {
  auto isActive = [&](size_t i) { return active.empty() || active[i] != 0; };
  SubGrid out;
  ProbeGrid sub = grid;
  sub.dims = hi - lo + 1;
  sub.origin = grid.probePosition(lo);
  RelightProbes& probes = out.probes;
  probes.grid = sub;
  std::vector<size_t>& toFull = out.toFull;
  toFull.reserve(size_t(sub.probeCount()));
  probes.positions.reserve(size_t(sub.probeCount()));
  glm::vec3& boxLo = out.boxLo;
  glm::vec3& boxHi = out.boxHi;
  for (int64_t k = 0; k < sub.probeCount(); ++k) {
    const size_t i = size_t(grid.linearIndex(lo + sub.probeCoord(k)));
    toFull.push_back(i);
    const glm::vec3 p =
        grid.probePosition(grid.probeCoord(int64_t(i))) + (offsets.empty() ? glm::vec3(0.0f) : offsets[i]);
    probes.positions.push_back(p);
    probes.active.push_back(isActive(i) ? 1 : 0);
    boxLo = glm::min(boxLo, p);
    boxHi = glm::max(boxHi, p);
  }
  return out;
}

// Sky radiance per texel direction (no discs).
std::vector<glm::vec3> skyTexelRadiance(const shared::SkyParams& sky, int n) {
  const size_t n2 = size_t(n) * size_t(n);
  std::vector<glm::vec3> skyL(n2);
  for (size_t t = 0; t < n2; ++t)
    skyL[t] = shared::skyRadiance(
        sky,
        shared::octTexelDirection(glm::uvec2(uint32_t(t % size_t(n)), uint32_t(t / size_t(n))), uint32_t(n)));
  return skyL;
}

// The seed's irradiance and moments as the last frame's probe lighting of the relit probes.
void seedLighting(const ProbeField& seed, std::span<const size_t> toFull, int n, int m, ProbeLighting& pl) {
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  pl.irradianceResolution = m;
  pl.distanceResolution = n;
  pl.probeCount = int(toFull.size());
  pl.irradiance.resize(toFull.size() * m2);
  pl.moments.resize(toFull.size() * n2);
  for (size_t k = 0; k < toFull.size(); ++k) {
    const size_t i = toFull[k];
    for (size_t t = 0; t < m2; ++t) {
      const float* e = &seed.irradiance[(i * m2 + t) * 3];
      pl.irradiance[k * m2 + t] = glm::vec4(e[0], e[1], e[2], 0.0f);
    }
    for (size_t t = 0; t < n2; ++t)
      pl.moments[k * n2 + t] =
          glm::vec2(seed.distance[(i * n2 + t) * 2], seed.distance[(i * n2 + t) * 2 + 1]);
  }
}

// Sky-only probes (no surfel near): irradiance of the sky map, the same texel sum as the convolution.
std::vector<float> skyMapIrradiance(const std::vector<glm::vec3>& skyL, int n, int m) {
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  std::vector<float> skyIrradiance;
  std::vector<float> map(n2 * 3);
  for (size_t t = 0; t < n2; ++t)
    for (int c = 0; c < 3; ++c) map[t * 3 + size_t(c)] = skyL[t][c];
  const std::vector<double> omega = octTexelSolidAngles(n);
  skyIrradiance.resize(m2 * 3);
  for (size_t t = 0; t < m2; ++t) {
    const glm::vec3 e =
        bruteForceIrradiance(map, n, octTexelDirection(int(t % size_t(m)), int(t / size_t(m)), m), omega);
    for (int c = 0; c < 3; ++c) skyIrradiance[t * 3 + size_t(c)] = e[c];
  }
  return skyIrradiance;
}

// What the stages writing the field read.
struct FieldInputs {
  const SubGrid& sub;
  const CellLighting& state;
  const std::vector<glm::vec3>& skyL;
  const std::vector<float>& skyIrradiance;
  bool skyOnly;  // no surfel near the probes
  float miss;
  uint32_t skyFlags;
};

// The active probes' maps into the field: the last frame's (or the sky's).
void writeProbes(const FieldInputs& in, int n, int m, ProbeField& f) {
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(m) * size_t(m);
  const std::vector<size_t>& toFull = in.sub.toFull;
  const RelightProbes& probes = in.sub.probes;
  const CellLighting& state = in.state;
  const std::vector<glm::vec3>& skyL = in.skyL;
  const std::vector<float>& skyIrradiance = in.skyIrradiance;
  const float miss = in.miss;
  const uint32_t skyFlags = in.skyFlags;
  const ProbeAtlas& atlas = state.atlas;
  for (size_t k = 0; k < toFull.size(); ++k) {
    const size_t i = toFull[k];
    if (!probes.active[k]) continue;
    f.active[i] = 1;
    float* rad = &f.radiance[i * n2 * 3];
    float* dist = &f.distance[i * n2 * 2];
    float* irr = &f.irradiance[i * m2 * 3];
    if (in.skyOnly) {
      for (size_t t = 0; t < n2; ++t) {
        for (int c = 0; c < 3; ++c) rad[t * 3 + size_t(c)] = skyL[t][c];
        dist[t * 2] = miss;
        dist[t * 2 + 1] = miss * miss;
      }
      std::copy(skyIrradiance.begin(), skyIrradiance.end(), irr);
    } else {
      for (size_t t = 0; t < n2; ++t) {
        const size_t a = k * n2 + t;
        // As the relight convolution: texels no surfel covered (and, with filledTexelsSeeSky, those only
        // the hole fill covered) see the sky.
        const bool seesSky = shared::relightTexelSeesSky(atlas.normal[a].w, skyFlags);
        const glm::vec3 L = seesSky ? skyL[t] : glm::vec3(atlas.radiance[a]);
        for (int c = 0; c < 3; ++c) rad[t * 3 + size_t(c)] = L[c];
        dist[t * 2] = state.probes.moments[a].x;
        dist[t * 2 + 1] = state.probes.moments[a].y;
      }
      for (size_t t = 0; t < m2; ++t)
        for (int c = 0; c < 3; ++c) irr[t * 3 + size_t(c)] = state.probes.irradiance[k * m2 + t][c];
    }
  }
}

}  // namespace

VirFieldRelighter::VirFieldRelighter(Context& ctx) : relight_(ctx), vir_(ctx) {}

void VirFieldRelighter::run(std::span<const shared::Surfel> surfels, const ProbeGrid& grid,
                            std::span<const glm::vec3> offsets, std::span<const uint8_t> active,
                            const shared::SkyParams& sky, const VirFieldOptions& o, ProbeField& f,
                            const ProbeField* seed, VirFieldStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  checkInputs(surfels, grid, offsets, active, o, seed);
  const size_t count = size_t(grid.probeCount());
  const int n = o.resolution, m = o.irradianceResolution;

  auto isActive = [&](size_t i) { return active.empty() || active[i] != 0; };
  glm::ivec3 lo(INT32_MAX), hi(INT32_MIN);
  for (size_t i = 0; i < count; ++i)
    if (isActive(i)) {
      const glm::ivec3 c = grid.probeCoord(int64_t(i));
      lo = glm::min(lo, c);
      hi = glm::max(hi, c);
    }
  resetField(grid, offsets, o, f);
  VirFieldStats local;
  VirFieldStats& st = stats ? *stats : local;
  st = VirFieldStats{};
  if (lo.x == INT32_MAX) return;  // nothing active

  const SubGrid sub = activeSubGrid(grid, offsets, active, lo, hi);
  const RelightProbes& probes = sub.probes;
  const glm::vec3 boxLo = sub.boxLo, boxHi = sub.boxHi;
  near_.clear();
  for (const shared::Surfel& s : surfels) {
    const glm::vec3 p(s.positionRadius);
    const glm::vec3 d = glm::max(glm::max(boxLo - p, p - boxHi), glm::vec3(0.0f));
    if (glm::dot(d, d) <= o.maxRange * o.maxRange) near_.push_back(s);
  }
  if (near_.empty() && !o.noSurfelsIsSky)
    fail("virProbeField: no surfel within {} m of the active probes", o.maxRange);

  VirOptions vo = o.vir;
  vo.resolution = n;
  vo.maxRange = o.maxRange;
  RelightOptions ro = o.relight;
  ro.irradianceResolution = m;
  const float miss = ro.missDistance;

  const std::vector<glm::vec3> skyL = skyTexelRadiance(sky, n);

  CellLighting state;
  if (!near_.empty()) {
    if (seed) {
      seedLighting(*seed, sub.toFull, n, m, state.probes);
      state.frames = 1;  // relightFrame reads state.probes as the last frame's lighting
      st.seeded = true;
    }
    for (int frame = 0; frame < o.frames; ++frame) {
      if (o.checkInterrupt && InterruptGuard::interrupted())
        fail("VIR probes interrupted after {} of {} frames", frame, o.frames);
      const RelightResult r = relightFrame(relight_, vir_, near_, probes, sky, vo, ro, state);
      st.gpuMs += r.shadowMs + r.lightMs + r.emitterShadowMs + state.atlas.gpuMs + state.probes.gpuMs;
    }
  }

  std::vector<float> skyIrradiance;
  if (near_.empty()) skyIrradiance = skyMapIrradiance(skyL, n, m);
  writeProbes({sub, state, skyL, skyIrradiance, near_.empty(), miss, probeSkyFlags(ro)}, n, m, f);
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  st.surfels = near_.size();
  st.probes = probes.positions.size();
  f.validate();
}

void VirFieldRelighter::regenerateMoments(std::span<const shared::Surfel> surfels,
                                          std::span<const glm::vec3> offsets, const VirFieldOptions& options,
                                          ProbeField& field, ProbeField& scratch, VirFieldStats* stats) {
  const size_t count = size_t(field.probeCount()), n2 = size_t(field.resolution) * size_t(field.resolution);
  if (field.distance.size() != count * n2 * 2)
    fail("regenerateMoments: {} distance floats for {} probes of {}x{} maps", field.distance.size(), count,
         field.resolution, field.resolution);
  VirFieldOptions o = options;
  o.resolution = field.resolution;
  o.irradianceResolution = field.irradianceResolution;
  o.frames = 1;
  o.storeOffsets = false;
  o.relight.sun = false;
  o.relight.bounce = false;
  run(surfels, field.grid, offsets, field.active, shared::SkyParams{}, o, scratch, nullptr, stats);
  for (size_t i = 0; i < count; ++i)
    if (field.isActive(int64_t(i)))
      std::copy_n(scratch.distance.begin() + ptrdiff_t(i * n2 * 2), n2 * 2,
                  field.distance.begin() + ptrdiff_t(i * n2 * 2));
}

}  // namespace lfgi::gpu
