#include "bake/probe_capture.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <numbers>

#include "bake/parallel_work.h"
#include "bake/path_trace.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/octahedral.h"
#include "core/sh.h"

namespace lfgi::bake {
namespace {

using detail::PathRng;

uint64_t probeKey(uint64_t seed, glm::vec3 p) {
  uint64_t h = splitmix64Finalize(seed ^ 0x6c666769'70726f62ULL);
  h = splitmix64Finalize(h ^ std::bit_cast<uint32_t>(p.x));
  h = splitmix64Finalize(h ^ (uint64_t(std::bit_cast<uint32_t>(p.y)) << 32));
  return splitmix64Finalize(h ^ std::bit_cast<uint32_t>(p.z));
}

// Primary sample s of texel (i, j); draws the first two numbers of rng.
TexelSample primarySample(int i, int j, int n, int s, int samples, PathRng& rng) {
  const int k = int(std::sqrt(double(samples)));
  double a = rng.nextDouble();
  double b = rng.nextDouble();
  if (s < k * k) {
    a = (double(s % k) + a) / double(k);
    b = (double(s / k) + b) / double(k);
  }
  const double px = (double(i) + a) / double(n) * 2.0 - 1.0;
  const double pz = (double(j) + b) / double(n) * 2.0 - 1.0;
  glm::dvec3 d(px, 1.0 - std::abs(px) - std::abs(pz), pz);
  if (d.y < 0.0) {  // lower hemisphere: fold across |u| + |v| = 1 (area preserving), as octDecode
    d.x = (1.0 - std::abs(pz)) * (px >= 0.0 ? 1.0 : -1.0);
    d.z = (1.0 - std::abs(px)) * (pz >= 0.0 ? 1.0 : -1.0);
  }
  const double len = glm::length(d);
  TexelSample t;
  t.direction = glm::vec3(d / len);
  t.weight = 1.0 / (len * len * len);
  return t;
}

float luminance(glm::vec3 c) {
  return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}

bool finite(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void validatePosition(glm::vec3 p, size_t index) {
  if (!finite(p)) fail("probe {}: position ({}, {}, {}) is not finite", index, p.x, p.y, p.z);
}

// What every path of one probe's capture shares.
struct ProbeTracer {
  const EmbreeScene& scene;
  const worlds::SkyModel& sky;
  const detail::Discs& discs;
  const detail::PathOptions& po;
  glm::vec3 position;
  uint64_t key;
  int n;
  int S;
};

// Texel (i, j) of c's maps and its luminance standard error, from S weighted primary samples.
void captureTexel(const ProbeTracer& p, int i, int j, ProbeCapture& c, std::vector<float>& luminanceStdError,
                  uint64_t& localRays) {
  const EmbreeScene& scene = p.scene;
  const worlds::SkyModel& sky = p.sky;
  const detail::Discs& discs = p.discs;
  const detail::PathOptions& po = p.po;
  const glm::vec3 position = p.position;
  const uint64_t key = p.key;
  const int n = p.n, S = p.S;
  const int texel = j * n + i;
  // Weighted sums in double: sum w, sum w^2, and per channel (RGB, luminance) sum w f, sum w^2 f,
  // sum w^2 f^2 for the delta-method standard error of the ratio estimate.
  double sw = 0, sw2 = 0, swf[4] = {}, sw2f[4] = {}, sw2f2[4] = {};
  double sr = 0, sr2 = 0, sn[3] = {}, sa[3] = {};
  for (int s = 0; s < S; ++s) {
    PathRng rng(key, texel, s);
    const TexelSample ts = primarySample(i, j, n, s, S, rng);
    detail::FirstHit first;
    const glm::vec3 L =
        detail::tracePath(scene, sky, discs, po, position, ts.direction, rng, first, localRays);
    const double w = ts.weight;
    sw += w;
    sw2 += w * w;
    const double f[4] = {L.x, L.y, L.z, luminance(L)};
    for (int ch = 0; ch < 4; ++ch) {
      swf[ch] += w * f[ch];
      sw2f[ch] += w * w * f[ch];
      sw2f2[ch] += w * w * f[ch] * f[ch];
    }
    sr += w * first.r;
    sr2 += w * double(first.r) * double(first.r);
    for (int ch = 0; ch < 3; ++ch) {
      sn[ch] += w * first.normal[ch];
      sa[ch] += w * first.albedo[ch];
    }
  }
  const size_t t = size_t(texel);
  for (int ch = 0; ch < 4; ++ch) {
    const double mean = swf[ch] / sw;
    const double sq = sw2f2[ch] - 2.0 * mean * sw2f[ch] + mean * mean * sw2;
    const float se = float(std::sqrt(std::max(0.0, sq)) / sw);
    if (ch < 3) {
      c.radiance[t * 3 + size_t(ch)] = float(mean);
      c.radianceStdError[t * 3 + size_t(ch)] = se;
    } else {
      luminanceStdError[t] = se;
    }
  }
  c.distance[t * 2] = float(sr / sw);
  c.distance[t * 2 + 1] = float(sr2 / sw);
  for (int ch = 0; ch < 3; ++ch) {
    c.normal[t * 3 + size_t(ch)] = float(sn[ch] / sw);
    c.albedo[t * 3 + size_t(ch)] = float(sa[ch] / sw);
  }
}

// Discs on the primary segment: energy / Omega into the texel holding the disc centre; irradiance
// gets them analytically instead (see the header). The discs seen from position go to visible; returns the
// shadow rays traced.
uint64_t depositDiscs(const EmbreeScene& scene, const detail::Discs& discs, glm::vec3 position,
                      const CaptureOptions& o, const std::vector<double>& solidAngles, ProbeCapture& c,
                      std::vector<const worlds::DiscLight*>& visible) {
  const int n = o.resolution;
  uint64_t discRays = 0;
  for (int d = 0; d < discs.count; ++d) {
    const worlds::DiscLight& l = *discs.light[d];
    ++discRays;
    if (scene.occluded(position, l.direction, 0.0f, o.maxDistance)) continue;
    visible.push_back(&l);
    const glm::ivec2 tx = octDirectionTexel(l.direction, n);
    const size_t t = size_t(tx.y) * size_t(n) + size_t(tx.x);
    const glm::vec3 add = l.irradianceNormal() / float(solidAngles[t]);
    for (int ch = 0; ch < 3; ++ch) c.radiance[t * 3 + size_t(ch)] += add[ch];
  }
  return discRays;
}

double meanRelativeStdError(const ProbeCapture& c, const std::vector<float>& luminanceStdError,
                            size_t texels) {
  double relSum = 0.0;
  size_t relCount = 0;
  for (size_t t = 0; t < texels; ++t) {
    const float y = luminance(glm::vec3(c.radiance[t * 3], c.radiance[t * 3 + 1], c.radiance[t * 3 + 2]));
    if (y > 0.0f) {
      relSum += double(luminanceStdError[t]) / double(y);
      ++relCount;
    }
  }
  return relCount ? relSum / double(relCount) : 0.0;
}

// c's irradiance map: the radiance without discs integrated, plus each visible disc analytically.
void integrateIrradiance(ProbeCapture& c, const std::vector<float>& withoutDiscs,
                         const std::vector<const worlds::DiscLight*>& visible,
                         const std::vector<double>& solidAngles) {
  const int n = c.resolution, m = c.irradianceResolution;
  c.irradiance.assign(size_t(m) * size_t(m) * 3, 0.0f);
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < m; ++i) {
      const glm::vec3 nrm = octTexelDirection(i, j, m);
      glm::vec3 e = bruteForceIrradiance(withoutDiscs, n, nrm, solidAngles);
      for (const worlds::DiscLight* l : visible) e += l->irradiance(nrm);
      const size_t t = (size_t(j) * size_t(m) + size_t(i)) * 3;
      c.irradiance[t] = e.x;
      c.irradiance[t + 1] = e.y;
      c.irradiance[t + 2] = e.z;
    }
  }
}

ProbeCapture captureOne(const EmbreeScene& scene, const worlds::SkyModel& sky, glm::vec3 position,
                        const CaptureOptions& o, const std::vector<double>& solidAngles) {
  const int n = o.resolution;
  const int m = o.irradianceResolution;
  const int S = o.samplesPerTexel;
  const size_t texels = size_t(n) * size_t(n);
  ProbeCapture c;
  c.position = position;
  c.resolution = n;
  c.irradianceResolution = m;
  c.radiance.assign(texels * 3, 0.0f);
  c.radianceStdError.assign(texels * 3, 0.0f);
  c.distance.assign(texels * 2, 0.0f);
  c.normal.assign(texels * 3, 0.0f);
  c.albedo.assign(texels * 3, 0.0f);
  std::vector<float> luminanceStdError(texels, 0.0f);
  const uint64_t key = probeKey(o.seed, position);
  const detail::Discs discs = detail::activeDiscs(sky);
  detail::PathOptions po;
  po.maxBounces = o.maxBounces;
  po.rouletteAfter = o.rouletteAfter;
  po.maxDistance = o.maxDistance;
  std::atomic<uint64_t> rays{0};

  const ProbeTracer tracer{scene, sky, discs, po, position, key, n, S};

  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1), [&](const tbb::blocked_range<int>& rows) {
    uint64_t localRays = 0;
    for (int j = rows.begin(); j < rows.end(); ++j)
      for (int i = 0; i < n; ++i) captureTexel(tracer, i, j, c, luminanceStdError, localRays);
    rays.fetch_add(localRays, std::memory_order_relaxed);
  });

  // Discs on the primary segment go into the radiance map; irradiance gets them analytically instead.
  std::vector<float> withoutDiscs = c.radiance;
  std::vector<const worlds::DiscLight*> visible;
  const uint64_t discRays =
      o.primaryDiscs ? depositDiscs(scene, discs, position, o, solidAngles, c, visible) : 0;
  c.meanRelativeStdError = meanRelativeStdError(c, luminanceStdError, texels);
  integrateIrradiance(c, withoutDiscs, visible, solidAngles);
  c.rays = rays.load() + discRays;
  return c;
}

}  // namespace

uint64_t ProbeCapture::contentHash() const {
  uint64_t h = fnv1aValue(kFnv1aOffset, resolution);
  h = fnv1aValue(h, irradianceResolution);
  h = fnv1aValue(h, position);
  for (const std::vector<float>* v : {&radiance, &radianceStdError, &distance, &normal, &albedo, &irradiance})
    h = fnv1aSpan(h, *v);
  return h;
}

void validateCaptureOptions(const CaptureOptions& o) {
  auto range = [](const char* name, int v, int lo, int hi) {
    if (v < lo || v > hi) fail("CaptureOptions.{} = {} outside [{}, {}]", name, v, lo, hi);
  };
  range("resolution", o.resolution, 1, 256);
  range("irradianceResolution", o.irradianceResolution, 1, 256);
  range("samplesPerTexel", o.samplesPerTexel, 1, 65536);
  range("maxBounces", o.maxBounces, 0, 256);
  range("rouletteAfter", o.rouletteAfter, 1, 1 << 20);
  if (!(std::isfinite(o.maxDistance) && o.maxDistance > 0.0f))
    fail("CaptureOptions.maxDistance = {} must be finite and > 0", o.maxDistance);
}

std::vector<float> prefilterRadianceGgx(std::span<const float> radiance, int n, float roughness, int outN) {
  if (n < 1 || n > 256 || outN < 1 || outN > 256)
    fail("prefilterRadianceGgx: resolution {} -> {} outside [1, 256]", n, outN);
  if (radiance.size() != octInteriorFloats(n, 3))
    fail("prefilterRadianceGgx: {} floats for a {} x {} RGB map (expected {})", radiance.size(), n, n,
         octInteriorFloats(n, 3));
  if (!(roughness >= 0.0f && roughness <= 1.0f))
    fail("prefilterRadianceGgx: roughness {} outside [0, 1]", roughness);
  const std::vector<double> omega = octTexelSolidAngles(n);
  std::vector<glm::dvec3> dirs(size_t(n) * size_t(n));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) dirs[size_t(j * n + i)] = glm::dvec3(octTexelDirection(i, j, n));
  const double a = std::max(double(roughness) * double(roughness), 1e-3);
  const double a2 = a * a;
  std::vector<float> out(octInteriorFloats(outN, 3), 0.0f);
  for (int j = 0; j < outN; ++j) {
    for (int i = 0; i < outN; ++i) {
      const glm::dvec3 r(octTexelDirection(i, j, outN));
      glm::dvec3 sum(0.0);
      double wsum = 0.0;
      for (size_t t = 0; t < dirs.size(); ++t) {
        const double rw = glm::dot(r, dirs[t]);
        if (rw <= 0.0) continue;
        const double nh = glm::dot(r, glm::normalize(r + dirs[t]));
        const double d = nh * nh * (a2 - 1.0) + 1.0;
        const double w = a2 / (std::numbers::pi * d * d) * rw * omega[t];
        sum += w * glm::dvec3(radiance[t * 3], radiance[t * 3 + 1], radiance[t * 3 + 2]);
        wsum += w;
      }
      const size_t o = (size_t(j) * size_t(outN) + size_t(i)) * 3;
      for (int ch = 0; ch < 3; ++ch) out[o + size_t(ch)] = wsum > 0.0 ? float(sum[ch] / wsum) : 0.0f;
    }
  }
  return out;
}

TexelSample texelSample(int i, int j, int n, int s, int samplesPerTexel, uint64_t seed, glm::vec3 position) {
  if (n < 1 || i < 0 || j < 0 || i >= n || j >= n || s < 0 || samplesPerTexel < 1 || s >= samplesPerTexel)
    fail("texelSample: texel ({}, {}) sample {} outside an {} x {} map with {} samples", i, j, s, n, n,
         samplesPerTexel);
  PathRng rng(probeKey(seed, position), j * n + i, s);
  return primarySample(i, j, n, s, samplesPerTexel, rng);
}

ProbeCapture captureProbe(const EmbreeScene& scene, const worlds::SkyModel& sky, glm::vec3 position,
                          const CaptureOptions& options) {
  validateCaptureOptions(options);
  validatePosition(position, 0);
  return captureOne(scene, sky, position, options, octTexelSolidAngles(options.resolution));
}

CaptureResult captureProbes(const EmbreeScene& scene, const worlds::SkyModel& sky,
                            std::span<const glm::vec3> positions, const CaptureOptions& options,
                            bool showProgress) {
  validateCaptureOptions(options);
  for (size_t i = 0; i < positions.size(); ++i) validatePosition(positions[i], i);
  const std::vector<double> solidAngles = octTexelSolidAngles(options.resolution);
  const auto start = std::chrono::steady_clock::now();

  CaptureResult result;
  result.probes.resize(positions.size());
  result.done.assign(positions.size(), 0);
  const detail::ParallelWorkResult run =
      detail::runParallelInterruptible(positions.size(), "capture", "probes", showProgress, [&](size_t p) {
        result.probes[p] = captureOne(scene, sky, positions[p], options, solidAngles);
        result.done[p] = 1;
      });
  result.probesDone = run.done;
  result.interrupted = run.interrupted;
  for (size_t p = 0; p < positions.size(); ++p) {
    if (result.done[p]) result.rays += result.probes[p].rays;
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace lfgi::bake
