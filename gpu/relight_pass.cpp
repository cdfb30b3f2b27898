#include "gpu/relight_pass.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numbers>
#include <tuple>

#include "core/error.h"
#include "core/octahedral.h"
#include "gpu/timing.h"
#include "shared/octahedral.h"

namespace lfgi::gpu {

namespace {

Program requireInt64Atomics(Context& ctx, const char* name) {
  if (!ctx.features.shaderBufferInt64Atomics)
    fail("relight: device '{}' lacks shaderBufferInt64Atomics (64-bit buffer atomics)", ctx.info.name);
  return Program(ctx, name);
}

float luminance(glm::vec3 c) {
  return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}

void validate(const RelightOptions& o) {
  if (o.shadowResolution != 0 && (o.shadowResolution < 16 || o.shadowResolution > 4096))
    fail("relight: shadowResolution {} outside [16, 4096] (or 0 for auto)", o.shadowResolution);
  if (!(std::isfinite(o.shadowFootprintScale) && o.shadowFootprintScale > 0.0f))
    fail("relight: shadowFootprintScale {} must be finite and > 0", o.shadowFootprintScale);
  if (o.shadowMaxFootprintRadius < 0 || o.shadowMaxFootprintRadius > 64)
    fail("relight: shadowMaxFootprintRadius {} outside [0, 64]", o.shadowMaxFootprintRadius);
  if (!(std::isfinite(o.shadowBiasConstant) && o.shadowBiasConstant >= 0.0f) ||
      !(std::isfinite(o.shadowBiasSlope) && o.shadowBiasSlope >= 0.0f))
    fail("relight: shadow bias ({}, {}) must be finite and >= 0", o.shadowBiasConstant, o.shadowBiasSlope);
  if (o.irradianceResolution < 1 || o.irradianceResolution > 64)
    fail("relight: irradianceResolution {} outside [1, 64]", o.irradianceResolution);
  if (!std::isfinite(o.normalBias)) fail("relight: normalBias {} must be finite", o.normalBias);
  if (!(std::isfinite(o.missDistance) && o.missDistance > 0.0f))
    fail("relight: missDistance {} must be finite and > 0", o.missDistance);
  if (o.maxEmitterClusters < 1 || o.maxEmitterClusters > 256)
    fail("relight: maxEmitterClusters {} outside [1, 256]", o.maxEmitterClusters);
  if (o.maxEmitterSamples < 1 || o.maxEmitterSamples > 65536)
    fail("relight: maxEmitterSamples {} outside [1, 65536]", o.maxEmitterSamples);
  if (o.emitterShadowResolution < 4 || o.emitterShadowResolution > 256)
    fail("relight: emitterShadowResolution {} outside [4, 256]", o.emitterShadowResolution);
  if (!(std::isfinite(o.emitterBiasSlope) && o.emitterBiasSlope >= 0.0f))
    fail("relight: emitterBiasSlope {} must be finite and >= 0", o.emitterBiasSlope);
}

bool emits(const shared::Surfel& s) {
  return std::max({s.emission.x, s.emission.y, s.emission.z}) > 0.0f;
}

// Emitter NEE inputs: clusters (uniform grid over the emitters' bounds x the 6 dominant normal
// directions, the grid coarsened until at most maxEmitterClusters cells are occupied; the two sides of a
// double-sided lamp are two clusters), samples sorted by cluster, cluster centres pushed off the emitting
// surface along the mean normal by two mean radii (so the cluster's own discs face the centre and only
// cover directions behind the emitter).
struct EmitterSetup {
  std::vector<shared::RelightEmitter> samples;
  std::vector<glm::vec4> centres;
  float meanRadius = 0.0f;
};

EmitterSetup setupEmitters(std::span<const shared::Surfel> surfels, const RelightOptions& o) {
  EmitterSetup e;
  std::vector<uint32_t> idx;
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (size_t i = 0; i < surfels.size(); ++i)
    if (emits(surfels[i])) {
      idx.push_back(uint32_t(i));
      lo = glm::min(lo, glm::vec3(surfels[i].positionRadius));
      hi = glm::max(hi, glm::vec3(surfels[i].positionRadius));
    }
  if (idx.empty()) return e;
  float cell = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-3f}) / 8.0f;
  std::map<std::tuple<int, int, int, int>, std::vector<uint32_t>> clusters;
  for (;;) {
    clusters.clear();
    for (uint32_t i : idx) {
      const glm::ivec3 k = glm::ivec3(glm::floor((glm::vec3(surfels[i].positionRadius) - lo) / cell));
      const glm::vec3 n(surfels[i].normal), an = glm::abs(n);
      const int axis = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
      clusters[{k.x, k.y, k.z, 2 * axis + (n[axis] < 0.0f ? 1 : 0)}].push_back(i);
    }
    // A single cell per side is as coarse as the grid gets; the sides stay apart.
    if (int(clusters.size()) <= o.maxEmitterClusters ||
        cell > 4.0f * std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-3f}))
      break;
    cell *= 2.0f;
  }
  const size_t quota = std::max<size_t>(1, size_t(o.maxEmitterSamples) / clusters.size());
  for (const auto& [key, members] : clusters) {
    const uint32_t c = uint32_t(e.centres.size());
    glm::dvec3 centroid(0.0), normal(0.0);
    double area = 0.0, radius = 0.0;
    for (uint32_t i : members) {
      const double a =
          std::numbers::pi * double(surfels[i].positionRadius.w) * double(surfels[i].positionRadius.w);
      centroid += a * glm::dvec3(glm::vec3(surfels[i].positionRadius));
      normal += a * glm::dvec3(glm::vec3(surfels[i].normal));
      area += a;
      radius += double(surfels[i].positionRadius.w);
    }
    centroid /= std::max(area, 1e-30);
    radius /= double(members.size());
    const double nl = glm::length(normal);
    const glm::dvec3 offset = nl > 1e-6 * area ? normal / nl * (2.0 * radius) : glm::dvec3(0.0);
    e.centres.push_back(glm::vec4(glm::vec3(centroid + offset), 0.0f));
    const size_t stride = (members.size() + quota - 1) / quota;
    double sampled = 0.0;
    const size_t first = e.samples.size();
    for (size_t k = 0; k < members.size(); k += stride) {
      const shared::Surfel& s = surfels[members[k]];
      const float a = std::numbers::pi_v<float> * s.positionRadius.w * s.positionRadius.w;
      sampled += double(a);
      shared::RelightEmitter em{};
      em.positionArea = glm::vec4(glm::vec3(s.positionRadius), a);
      em.normalCluster = glm::vec4(glm::vec3(s.normal), glm::uintBitsToFloat(c));
      em.radiance = glm::vec4(glm::vec3(s.emission), 0.0f);
      e.samples.push_back(em);
    }
    const float scale = float(area / std::max(sampled, 1e-30));
    for (size_t k = first; k < e.samples.size(); ++k) e.samples[k].positionArea.w *= scale;
  }
  double r = 0.0;
  for (const shared::Surfel& s : surfels) r += double(s.positionRadius.w);
  e.meanRadius = float(r / double(surfels.size()));
  return e;
}

// Storage buffers of at least 16 bytes (an unused binding still needs a valid buffer).
Buffer storage(Context& ctx, size_t bytes) {
  return createStorageBuffer(ctx, std::max<size_t>(bytes, 16));
}

struct CheckedInputs {
  size_t probeCount;
  bool bounce;  // last frame's probe irradiance is used
};

CheckedInputs validateInputs(std::span<const shared::Surfel> surfels, const RelightProbes& probes,
                             const ProbeLighting* previous, const RelightOptions& o) {
  validate(o);
  if (surfels.empty()) fail("relight: no surfels");
  if (surfels.size() > 0xFFFFFFFFull) fail("relight: {} surfels exceed 2^32", surfels.size());
  probes.grid.validate();
  const size_t probeCount = size_t(probes.grid.probeCount());
  if (probes.positions.size() != probeCount)
    fail("relight: {} probe positions for a grid of {} probes", probes.positions.size(), probeCount);
  if (!probes.active.empty() && probes.active.size() != probeCount)
    fail("relight: {} probe active flags for a grid of {} probes", probes.active.size(), probeCount);
  const bool bounce = o.bounce && previous && !previous->irradiance.empty();
  if (bounce) {
    const size_t m2 = size_t(previous->irradianceResolution) * size_t(previous->irradianceResolution);
    const size_t n2 = size_t(previous->distanceResolution) * size_t(previous->distanceResolution);
    if (size_t(previous->probeCount) != probeCount || previous->irradiance.size() != m2 * probeCount ||
        previous->moments.size() != n2 * probeCount)
      fail("relight: previous probe lighting has {} probes ({} irradiance, {} moment texels), grid has {}",
           previous->probeCount, previous->irradiance.size(), previous->moments.size(), probeCount);
  }
  return {probeCount, bounce};
}

struct KeyDisc {
  bool keyOn;
  uint32_t shadowRes;
};

// Key disc: the brighter of sun and moon; with it on, its direction and shadow map frame.
KeyDisc setupKeyDisc(std::span<const shared::Surfel> surfels, const shared::SkyParams& sky,
                     const RelightOptions& o, shared::RelightFrame& frame, RelightResult& result) {
  const glm::vec3 sunE(sky.sunIrradiance), moonE(sky.moonIrradiance);
  const bool sunKey = luminance(sunE) >= luminance(moonE);
  const glm::vec3 keyE = sunKey ? sunE : moonE;
  glm::vec3 L = sunKey ? glm::vec3(sky.sunDirection) : glm::vec3(sky.moonDirection);
  const bool keyOn = o.sun && luminance(keyE) > 0.0f && glm::length(L) > 0.5f;
  uint32_t shadowRes = 1;
  if (keyOn) {
    L = glm::normalize(L);
    const glm::vec3 helper = std::abs(L.y) < 0.99f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    const glm::vec3 U = glm::normalize(glm::cross(helper, L));
    const glm::vec3 V = glm::cross(L, U);
    float umin = 1e30f, umax = -1e30f, vmin = 1e30f, vmax = -1e30f, hmax = -1e30f;
    double radiusSum = 0.0;
    for (const shared::Surfel& s : surfels) {
      const glm::vec3 p(s.positionRadius);
      const float r = s.positionRadius.w * o.shadowFootprintScale;
      const float u = glm::dot(p, U), v = glm::dot(p, V), h = glm::dot(p, L);
      if (!(std::isfinite(u) && std::isfinite(v) && std::isfinite(h) && std::isfinite(r)))
        fail("relight: surfel at ({}, {}, {}) is not finite", p.x, p.y, p.z);
      umin = std::min(umin, u - r), umax = std::max(umax, u + r);
      vmin = std::min(vmin, v - r), vmax = std::max(vmax, v + r);
      hmax = std::max(hmax, h + r);
      radiusSum += double(s.positionRadius.w);
    }
    const float extent = std::max({umax - umin, vmax - vmin, 1e-3f}) * 1.001f;
    if (o.shadowResolution > 0) {
      shadowRes = uint32_t(o.shadowResolution);
    } else {
      const double texel = 0.75 * std::max(radiusSum / double(surfels.size()), 1e-4);
      shadowRes = uint32_t(std::clamp(std::ceil(double(extent) / texel), 64.0, 2048.0));
    }
    const float ts = extent / float(shadowRes);
    frame.keyDirection = glm::vec4(L, sunKey ? 1.0f : 2.0f);
    frame.keyIrradiance = glm::vec4(keyE, 0.0f);
    frame.shadowAxisU = glm::vec4(U, umin);
    frame.shadowAxisV = glm::vec4(V, vmin);
    frame.shadowDepth = glm::vec4(hmax + 1.0f, ts, o.shadowBiasConstant, o.shadowBiasSlope);
    result.shadowResolution = int(shadowRes);
    result.shadowTexelM = ts;
    result.keyDirection = L;
  }
  return {keyOn, shadowRes};
}

// One VIR-splatted octahedral depth map per emitter cluster (a single 0 without emitters).
std::vector<float> emitterShadowMaps(VirPass& emitterShadow, std::span<const shared::Surfel> surfels,
                                     const EmitterSetup& em, const RelightOptions& o,
                                     shared::RelightFrame& frame, RelightResult& result) {
  std::vector<float> emitterDepth(1, 0.0f);
  const int emitterRes = o.emitterShadowResolution;
  if (!em.samples.empty()) {
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const shared::Surfel& s : surfels) {
      lo = glm::min(lo, glm::vec3(s.positionRadius));
      hi = glm::max(hi, glm::vec3(s.positionRadius));
    }
    VirOptions vo;
    vo.resolution = emitterRes;
    vo.maxRange = 2.0f * glm::length(hi - lo) + 1.0f;
    std::vector<glm::vec3> centres;
    for (const glm::vec4& c : em.centres) centres.push_back(glm::vec3(c));
    const ProbeAtlas maps = emitterShadow.run(surfels, centres, vo);
    result.emitterShadowMs = maps.gpuMs;
    emitterDepth.resize(maps.distance.size());
    for (size_t t = 0; t < maps.distance.size(); ++t)
      emitterDepth[t] = maps.normal[t].w == LFGI_VIR_HOLE ? 1e30f : maps.distance[t].x;
    // Receiver pushed one mean radius along its normal; depth bias one mean radius + slope x texel angle
    // (an octahedral texel spans ~sqrt(4 pi) / N rad) x distance.
    frame.emitters =
        glm::uvec4(uint32_t(em.samples.size()), uint32_t(em.centres.size()), uint32_t(emitterRes), 0u);
    frame.emitterBias =
        glm::vec4(em.meanRadius, em.meanRadius,
                  o.emitterBiasSlope * std::sqrt(4.0f * std::numbers::pi_v<float>) / float(emitterRes), 0.0f);
    result.emitterClusters = int(em.centres.size());
    result.emitterSamples = int(em.samples.size());
  }
  return emitterDepth;
}

}  // namespace

RelightPass::RelightPass(Context& ctx)
    : ctx_(ctx),
      shadowSplat_(requireInt64Atomics(ctx, "relight_shadow_splat")),
      surfels_(ctx, "relight_surfels"),
      probeIrradiance_(ctx, "relight_probe_irradiance"),
      probeMoments_(ctx, "relight_probe_moments"),
      prefilter_(ctx, "relight_prefilter_ggx"),
      emitterShadow_(ctx),
      emitterProbes_(ctx) {}

RelightResult RelightPass::relight(std::span<const shared::Surfel> surfels, const RelightProbes& probes,
                                   const shared::SkyParams& sky, const ProbeLighting* previous,
                                   const RelightOptions& o) {
  const CheckedInputs checked = validateInputs(surfels, probes, previous, o);
  const size_t probeCount = checked.probeCount;
  const bool bounce = checked.bounce;

  shared::RelightFrame frame{};
  frame.sky = sky;
  RelightResult result;
  result.irradiance.resize(surfels.size());
  const KeyDisc key = setupKeyDisc(surfels, sky, o, frame, result);
  const bool keyOn = key.keyOn;
  const uint32_t shadowRes = key.shadowRes;
  // Emitter NEE: samples, cluster centres and one VIR-splatted octahedral depth map per cluster.
  const EmitterSetup em = o.emitterNee ? setupEmitters(surfels, o) : EmitterSetup{};
  std::vector<float> emitterDepth = emitterShadowMaps(emitterShadow_, surfels, em, o, frame, result);

  const glm::vec3 sp = probes.grid.spacing;
  const float normalBias = o.normalBias >= 0.0f ? o.normalBias : 0.2f * std::min({sp.x, sp.y, sp.z});
  frame.gridOrigin = glm::vec4(probes.grid.origin, 0.0f);
  frame.gridSpacing = glm::vec4(sp, normalBias);
  frame.gridDims = glm::ivec4(probes.grid.dims, int(probeCount));

  std::vector<glm::vec4> probe4(probeCount);
  for (size_t i = 0; i < probeCount; ++i)
    probe4[i] = glm::vec4(probes.positions[i], probes.active.empty() || probes.active[i] ? 1.0f : 0.0f);

  shared::RelightParams params{};
  params.surfelCount = uint32_t(surfels.size());
  params.probeCount = uint32_t(probeCount);
  params.shadowRes = shadowRes;
  params.maxFootprintRadius = uint32_t(o.shadowMaxFootprintRadius);
  params.irradianceRes = bounce ? uint32_t(previous->irradianceResolution) : 1u;
  params.distanceRes = bounce ? uint32_t(previous->distanceResolution) : 1u;
  params.flags = (keyOn ? LFGI_RELIGHT_SUN : 0u) | (bounce ? LFGI_RELIGHT_BOUNCE : 0u) |
                 (o.chebyshev ? LFGI_RELIGHT_CHEBYSHEV : 0u) |
                 (em.samples.empty() ? 0u : LFGI_RELIGHT_EMITTERS);
  params.footprintScale = o.shadowFootprintScale;
  params.missDistance = o.missDistance;

  Buffer surfelBuf = storage(ctx_, surfels.size_bytes());
  Buffer frameBuf = storage(ctx_, sizeof(frame));
  Buffer slots = storage(ctx_, size_t(shadowRes) * shadowRes * sizeof(uint64_t));
  Buffer probeBuf = storage(ctx_, probe4.size() * sizeof(glm::vec4));
  Buffer irrBuf = storage(ctx_, bounce ? previous->irradiance.size() * sizeof(glm::vec4) : 0);
  Buffer momBuf = storage(ctx_, bounce ? previous->moments.size() * sizeof(glm::vec2) : 0);
  Buffer outBuf = storage(ctx_, surfels.size() * sizeof(glm::vec4));
  Buffer emitterBuf = storage(ctx_, em.samples.size() * sizeof(shared::RelightEmitter));
  Buffer centreBuf = storage(ctx_, em.centres.size() * sizeof(glm::vec4));
  Buffer emitterDepthBuf = storage(ctx_, emitterDepth.size() * sizeof(float));
  if (!em.samples.empty()) {
    upload<shared::RelightEmitter>(ctx_, emitterBuf, em.samples);
    upload<glm::vec4>(ctx_, centreBuf, em.centres);
    upload<float>(ctx_, emitterDepthBuf, emitterDepth);
  }
  upload<shared::Surfel>(ctx_, surfelBuf, surfels);
  upload<shared::RelightFrame>(ctx_, frameBuf, std::span(&frame, 1));
  upload<glm::vec4>(ctx_, probeBuf, probe4);
  if (bounce) {
    upload<glm::vec4>(ctx_, irrBuf, previous->irradiance);
    upload<glm::vec2>(ctx_, momBuf, previous->moments);
  }

  GpuTimer timer(ctx_, 3);
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    vkCmdFillBuffer(cmd, slots.handle(), 0, VK_WHOLE_SIZE, 0xFFFFFFFFu);
    memoryBarrier(cmd);
    timer.stamp(cmd, 0);
    if (keyOn)
      dispatch(ctx_, cmd, shadowSplat_, {&surfelBuf, &frameBuf, &slots}, params, {params.surfelCount, 1, 1});
    memoryBarrier(cmd);
    timer.stamp(cmd, 1);
    dispatch(ctx_, cmd, surfels_,
             {&surfelBuf, &frameBuf, &slots, &probeBuf, &irrBuf, &momBuf, &outBuf, &emitterBuf, &centreBuf,
              &emitterDepthBuf},
             params, {params.surfelCount, 1, 1});
    memoryBarrier(cmd);
    timer.stamp(cmd, 2);
  });
  result.shadowMs = timer.elapsedMs(0, 1);
  result.lightMs = timer.elapsedMs(1, 2);
  readback<glm::vec4>(ctx_, outBuf, result.irradiance);
  return result;
}

uint32_t probeSkyFlags(const RelightOptions& o) {
  return (o.skyInProbes ? LFGI_RELIGHT_SKY : 0u) | (o.filledTexelsSeeSky ? LFGI_RELIGHT_FILLED_SKY : 0u);
}

// max(0, n_o . w_t) dOmega_t for output texel o of an M x M irradiance map and input texel t of an N x N
// map (the table convolve() uploads; also the CPU's sparse updates in relightFrame).
class CosineWeights {
 public:
  CosineWeights(int n, int m)
      : omega_(octTexelSolidAngles(n)), normals_(size_t(m) * size_t(m)), dirs_(size_t(n) * size_t(n)) {
    for (uint32_t o = 0; o < normals_.size(); ++o)
      normals_[o] = shared::octTexelDirection(glm::uvec2(o % uint32_t(m), o / uint32_t(m)), uint32_t(m));
    for (uint32_t t = 0; t < dirs_.size(); ++t)
      dirs_[t] = shared::octTexelDirection(glm::uvec2(t % uint32_t(n), t / uint32_t(n)), uint32_t(n));
  }
  float weight(uint32_t o, uint32_t t) const {
    const double c = double(glm::dot(normals_[o], dirs_[t]));
    return c > 0.0 ? float(c * omega_[t]) : 0.0f;
  }
  size_t outputs() const { return normals_.size(); }

 private:
  std::vector<double> omega_;
  std::vector<glm::vec3> normals_, dirs_;
};

ProbeLighting RelightPass::convolve(const ProbeAtlas& atlas, const shared::SkyParams& sky,
                                    const RelightOptions& o, const ProbeLighting* sameGeometry) {
  validate(o);
  const size_t n2 = size_t(atlas.resolution) * size_t(atlas.resolution);
  const size_t texels = n2 * size_t(atlas.probeCount);
  if (atlas.resolution < 1 || atlas.probeCount < 1 || atlas.radiance.size() != texels ||
      atlas.normal.size() != texels || atlas.distance.size() != texels)
    fail("relight: atlas of {} probes at N={} has {} radiance, {} normal, {} distance texels",
         atlas.probeCount, atlas.resolution, atlas.radiance.size(), atlas.normal.size(),
         atlas.distance.size());
  if (sameGeometry &&
      (sameGeometry->distanceResolution != atlas.resolution || sameGeometry->probeCount != atlas.probeCount ||
       sameGeometry->moments.size() != texels))
    fail("relight: moments of {} probes at N={} ({} texels) given for an atlas of {} probes at N={}",
         sameGeometry->probeCount, sameGeometry->distanceResolution, sameGeometry->moments.size(),
         atlas.probeCount, atlas.resolution);
  const uint32_t m = uint32_t(o.irradianceResolution);
  ProbeLighting out;
  out.irradianceResolution = int(m);
  out.distanceResolution = atlas.resolution;
  out.probeCount = atlas.probeCount;
  out.irradiance.resize(size_t(m) * m * size_t(atlas.probeCount));
  if (!sameGeometry) out.moments.resize(texels);

  // Probe-independent tables (see relight_probe_irradiance.comp): cosine x solid-angle weights of each
  // input texel for every group of 16 output texels, and the sky radiance of each input texel.
  const uint32_t n = uint32_t(atlas.resolution), groups = (m * m + 15) / 16;
  const CosineWeights cw(atlas.resolution, int(m));
  std::vector<glm::vec4> weights(size_t(groups) * n2 * 4, glm::vec4(0.0f)), skyTable(n2);
  for (uint32_t t = 0; t < n2; ++t) {
    skyTable[t] =
        glm::vec4(shared::skyRadiance(sky, shared::octTexelDirection(glm::uvec2(t % n, t / n), n)), 0.0f);
    for (uint32_t o2 = 0; o2 < m * m; ++o2)
      weights[(size_t(o2 / 16) * n2 + t) * 4 + (o2 % 16) / 4][int(o2 % 4)] = cw.weight(o2, t);
  }
  shared::RelightParams params{};
  params.probeCount = uint32_t(atlas.probeCount);
  params.irradianceRes = m;
  params.distanceRes = n;
  params.flags = probeSkyFlags(o);
  params.missDistance = o.missDistance;

  Buffer radBuf = storage(ctx_, texels * sizeof(glm::vec4));
  Buffer normalBuf = storage(ctx_, texels * sizeof(glm::vec4));
  Buffer distBuf = storage(ctx_, (sameGeometry ? 1 : texels) * sizeof(glm::vec2));
  Buffer weightBuf = storage(ctx_, weights.size() * sizeof(glm::vec4));
  Buffer skyBuf = storage(ctx_, skyTable.size() * sizeof(glm::vec4));
  Buffer irrBuf = storage(ctx_, out.irradiance.size() * sizeof(glm::vec4));
  Buffer momBuf = storage(ctx_, (sameGeometry ? 1 : texels) * sizeof(glm::vec2));
  upload<glm::vec4>(ctx_, radBuf, atlas.radiance);
  upload<glm::vec4>(ctx_, normalBuf, atlas.normal);
  if (!sameGeometry) upload<glm::vec2>(ctx_, distBuf, atlas.distance);
  upload<glm::vec4>(ctx_, weightBuf, weights);
  upload<glm::vec4>(ctx_, skyBuf, skyTable);
  GpuTimer timer(ctx_, 2);
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    dispatch(ctx_, cmd, probeIrradiance_, {&radBuf, &normalBuf, &weightBuf, &skyBuf, &irrBuf}, params,
             {params.probeCount, groups, 1});
    if (!sameGeometry)
      dispatch(ctx_, cmd, probeMoments_, {&distBuf, &normalBuf, &momBuf}, params,
               {params.distanceRes, params.distanceRes, params.probeCount});
    memoryBarrier(cmd);
    timer.stamp(cmd, 1);
  });
  out.gpuMs = timer.elapsedMs(0, 1);
  readback<glm::vec4>(ctx_, irrBuf, out.irradiance);
  if (sameGeometry)
    out.moments = sameGeometry->moments;
  else
    readback<glm::vec2>(ctx_, momBuf, out.moments);
  return out;
}

std::vector<glm::vec4> RelightPass::prefilterGgx(std::span<const glm::vec4> radiance, int n, int probeCount,
                                                 float roughness, int outN, double* gpuMs) {
  if (n < 1 || n > 256 || outN < 1 || outN > 256)
    fail("relight: GGX prefilter resolution {} -> {} outside [1, 256]", n, outN);
  if (!(roughness >= 0.0f && roughness <= 1.0f)) fail("relight: GGX roughness {} outside [0, 1]", roughness);
  const size_t n2 = size_t(n) * size_t(n), m2 = size_t(outN) * size_t(outN);
  if (probeCount < 1 || radiance.size() != n2 * size_t(probeCount))
    fail("relight: GGX prefilter got {} radiance texels for {} probes of {} x {}", radiance.size(),
         probeCount, n, n);
  const std::vector<double> omega = octTexelSolidAngles(n);
  const std::vector<float> omegaF(omega.begin(), omega.end());
  Buffer radBuf = storage(ctx_, radiance.size_bytes());
  Buffer omegaBuf = storage(ctx_, omegaF.size() * sizeof(float));
  Buffer outBuf = storage(ctx_, m2 * size_t(probeCount) * sizeof(glm::vec4));
  upload<glm::vec4>(ctx_, radBuf, radiance);
  upload<float>(ctx_, omegaBuf, omegaF);
  const shared::RelightPrefilterParams params{uint32_t(n), uint32_t(outN), uint32_t(probeCount), roughness};
  GpuTimer timer(ctx_, 2);
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    dispatch(ctx_, cmd, prefilter_, {&radBuf, &omegaBuf, &outBuf}, params,
             {uint32_t(outN), uint32_t(outN), uint32_t(probeCount)});
    memoryBarrier(cmd);
    timer.stamp(cmd, 1);
  });
  if (gpuMs) *gpuMs = timer.elapsedMs(0, 1);
  std::vector<glm::vec4> out(m2 * size_t(probeCount));
  readback<glm::vec4>(ctx_, outBuf, out);
  return out;
}

RelightResult relightFrame(RelightPass& relight, VirPass& vir, std::span<const shared::Surfel> surfels,
                           const RelightProbes& probes, const shared::SkyParams& sky,
                           const VirOptions& virOptions, const RelightOptions& options, CellLighting& state) {
  const bool nee = options.emitterNee && std::any_of(surfels.begin(), surfels.end(), emits);
  const ProbeLighting* previous = nullptr;
  if (state.frames > 0)
    previous = nee && !state.reflected.irradiance.empty() ? &state.reflected : &state.probes;
  RelightResult result = relight.relight(surfels, probes, sky, previous, options);
  if (!nee) {
    state.atlas = vir.run(surfels, probes.positions, virOptions, result.irradiance);
    state.probes = relight.convolve(state.atlas, sky, options);
    state.reflected = {};
  } else {
    std::vector<shared::Surfel> dark(surfels.begin(), surfels.end()), lamps;
    for (shared::Surfel& s : dark)
      if (emits(s)) {
        lamps.push_back(s);
        s.emission = glm::vec4(0.0f);
      }
    state.atlas = vir.run(dark, probes.positions, virOptions, result.irradiance);
    state.reflected = relight.convolve(state.atlas, sky, options);
    // The emitters alone: where one of them is the nearest surface of a texel (same distance as in the
    // full splat), its emission joins that texel's reflected radiance. Their splat depends only on the
    // emitter surfels, the probes and the splat options, so its texels are kept in state.
    ProbeAtlas& a = state.atlas;
    const bool cached =
        virOptions.reuseSplat && state.emitterTexelsValid && state.emitterSurfels.size() == lamps.size() &&
        std::memcmp(state.emitterSurfels.data(), lamps.data(), lamps.size() * sizeof(shared::Surfel)) == 0 &&
        state.emitterProbes == probes.positions && VirPass::sameSplat(virOptions, state.emitterOptions);
    if (!cached) {
      const ProbeAtlas lit = relight.emitterProbeVir().run(lamps, probes.positions, virOptions);
      state.emitterTexels.clear();
      for (size_t t = 0; t < lit.normal.size(); ++t)
        if (lit.normal[t].w == LFGI_VIR_COVERED)
          state.emitterTexels.push_back({uint32_t(t), lit.distance[t].x, glm::vec3(lit.radiance[t])});
      state.emitterSurfels = std::move(lamps);
      state.emitterProbes = probes.positions;
      state.emitterOptions = virOptions;
      state.emitterTexelsValid = true;
      a.gpuMs += lit.gpuMs;
    }
    // The probe irradiance with the emitters: the convolution is linear in radiance, so it is the
    // emission-free one plus the cosine sums of the few texels the emitters brightened, on the CPU (a
    // second full convolve took ~1.5 s per frame on a 15 k-probe city cell; same moments, same distances).
    state.probes = state.reflected;
    state.probes.gpuMs = 0.0;
    const uint32_t n2 = uint32_t(a.resolution * a.resolution);
    const CosineWeights cw(a.resolution, state.probes.irradianceResolution);
    const uint32_t flags = probeSkyFlags(options);
    for (const EmitterTexel& e : state.emitterTexels) {
      if (a.normal[e.texel].w == LFGI_VIR_HOLE || e.distance > a.distance[e.texel].x * 1.001f + 1e-5f)
        continue;
      a.radiance[e.texel] += glm::vec4(e.radiance, 0.0f);
      if (shared::relightTexelSeesSky(a.normal[e.texel].w, flags)) continue;  // the convolution reads the sky
      glm::vec4* out = &state.probes.irradiance[size_t(e.texel / n2) * cw.outputs()];
      for (uint32_t o = 0; o < cw.outputs(); ++o)
        out[o] += glm::vec4(e.radiance * cw.weight(o, e.texel % n2), 0.0f);
    }
  }
  state.surfelIrradiance = result.irradiance;
  ++state.frames;
  return result;
}

}  // namespace lfgi::gpu
