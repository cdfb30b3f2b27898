#include "bake/probe_capture.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <optional>

#include "bake/brdf.h"
#include "core/error.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/sh.h"

namespace lfgi::bake {
namespace {

constexpr float kInvPi = float(1.0 / std::numbers::pi);

// splitmix64's finaliser (Steele, Lea & Flood 2014): a strong 64-bit mix for counter-based streams.
uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

uint64_t probeKey(uint64_t seed, glm::vec3 p) {
  uint64_t h = mix64(seed ^ 0x6c666769'70726f62ULL);
  h = mix64(h ^ std::bit_cast<uint32_t>(p.x));
  h = mix64(h ^ (uint64_t(std::bit_cast<uint32_t>(p.y)) << 32));
  return mix64(h ^ std::bit_cast<uint32_t>(p.z));
}

// Random numbers of one path: element `counter` of the stream `key`, independent of thread and order.
class PathRng {
 public:
  PathRng(uint64_t probe, int texel, int sample)
      : key_(mix64(probe ^ mix64((uint64_t(uint32_t(texel)) << 32) | uint32_t(sample)))) {}
  double nextDouble() { return double(next() >> 11) * 0x1.0p-53; }
  float nextFloat() { return float(next() >> 40) * 0x1.0p-24f; }

 private:
  uint64_t next() { return mix64(key_ + (++counter_) * 0x9e3779b97f4a7c15ULL); }
  uint64_t key_;
  uint64_t counter_ = 0;
};

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

float maxComponent(glm::vec3 c) {
  return std::max(c.x, std::max(c.y, c.z));
}

bool finite(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

struct Discs {
  const worlds::DiscLight* light[2];
  int count = 0;
};

Discs activeDiscs(const worlds::SkyModel& sky) {
  Discs d{};
  for (const worlds::DiscLight* l : {&sky.sun, &sky.moon}) {
    if (maxComponent(l->irradianceNormal()) > 0.0f) d.light[d.count++] = l;
  }
  return d;
}

glm::vec3 hitAlbedo(const worlds::TriangleMesh& mesh, const worlds::Material& m, const RayHit& hit) {
  glm::vec3 a = m.albedo;
  if (m.albedoTexture >= 0 && !mesh.uvs.empty()) {
    const size_t t = hit.triangle;
    const glm::vec2 uv = (1.0f - hit.barycentric.x - hit.barycentric.y) * mesh.uvs[mesh.indices[t * 3]] +
                         hit.barycentric.x * mesh.uvs[mesh.indices[t * 3 + 1]] +
                         hit.barycentric.y * mesh.uvs[mesh.indices[t * 3 + 2]];
    a *= mesh.textures[size_t(m.albedoTexture)].sampleLinear(uv);
  }
  return a;
}

// The hit point from the triangle's vertices and barycentrics (more accurate than origin + t dir far from
// the origin).
glm::vec3 hitPoint(const worlds::TriangleMesh& mesh, const RayHit& hit) {
  const size_t t = hit.triangle;
  return (1.0f - hit.barycentric.x - hit.barycentric.y) * mesh.positions[mesh.indices[t * 3]] +
         hit.barycentric.x * mesh.positions[mesh.indices[t * 3 + 1]] +
         hit.barycentric.y * mesh.positions[mesh.indices[t * 3 + 2]];
}

// Secondary ray origin: p pushed off the surface along n by a fixed number of float ulps (256 per unit
// of n), or by 1/65536 m near the world origin (Waechter & Binder 2019, "A Fast and Robust Method for
// Avoiding Self-Intersection", Ray Tracing Gems ch. 6). An offset relative to |p| instead would grow to
// decimetres in a km-sized world and could push origins through thin walls and out of corners.
glm::vec3 offsetRayOrigin(glm::vec3 p, glm::vec3 n) {
  constexpr float kOriginRegion = 1.0f / 32.0f;
  constexpr float kFloatScale = 1.0f / 65536.0f;
  constexpr float kIntScale = 256.0f;
  glm::vec3 out;
  for (int k = 0; k < 3; ++k) {
    const int32_t ulps = int32_t(kIntScale * n[k]);
    const int32_t bits = std::bit_cast<int32_t>(p[k]);
    const float moved = std::bit_cast<float>(bits + (p[k] < 0.0f ? -ulps : ulps));
    out[k] = std::abs(p[k]) < kOriginRegion ? p[k] + kFloatScale * n[k] : moved;
  }
  return out;
}

struct FirstHit {
  float r = 0.0f;
  glm::vec3 normal{0.0f};
  glm::vec3 albedo{0.0f};
};

// One path from the probe along dir; returns its radiance estimate (discs excluded on the primary
// segment: the caller deposits them).
glm::vec3 tracePath(const EmbreeScene& scene, const worlds::SkyModel& sky, const Discs& discs,
                    const CaptureOptions& o, glm::vec3 origin, glm::vec3 dir, PathRng& rng, FirstHit& first,
                    uint64_t& rays) {
  const worlds::TriangleMesh& mesh = scene.mesh();
  glm::vec3 radiance(0.0f);
  glm::vec3 throughput(1.0f);
  first = FirstHit{o.maxDistance, glm::vec3(0.0f), glm::vec3(0.0f)};
  for (int k = 0;; ++k) {
    const std::optional<RayHit> hit = scene.intersect(origin, dir, 0.0f, o.maxDistance);
    ++rays;
    if (!hit) {
      radiance += throughput * worlds::skyRadiance(sky, dir);
      break;
    }
    const worlds::Material& m = mesh.materials[mesh.triangleMaterial[hit->triangle]];
    const glm::vec3 albedo = hitAlbedo(mesh, m, *hit);
    const glm::vec3 n = hit->backface ? -hit->normal : hit->normal;  // faces the incoming ray
    if (k == 0) {
      first.r = hit->t;
      first.normal = m.doubleSided ? n : hit->normal;
      first.albedo = albedo;
    }
    if (hit->backface && !m.doubleSided) break;  // inside solid: black absorber
    radiance += throughput * m.emission;
    if (k >= o.maxBounces) break;
    const glm::vec3 po = offsetRayOrigin(hitPoint(mesh, *hit), n);
    const SurfaceBrdf brdf{albedo, m.roughness, m.metallic};
    const bool lambertian = brdf.isLambertian();
    const glm::vec3 wo = -dir;
    for (int d = 0; d < discs.count; ++d) {
      const worlds::DiscLight& l = *discs.light[d];
      if (glm::dot(n, l.direction) <= 0.0f) continue;
      const glm::vec3 f = lambertian ? albedo * kInvPi : evalBrdf(brdf, n, wo, l.direction);
      if (!(maxComponent(f) > 0.0f)) continue;
      ++rays;
      if (!scene.occluded(po, l.direction, 0.0f, o.maxDistance)) radiance += throughput * f * l.irradiance(n);
    }
    // Bounce. Lambertian with cosine sampling: f cos / pdf = albedo exactly; otherwise brdf.h's mixture.
    glm::vec3 weight;
    if (lambertian) {
      weight = albedo;
      const float u1 = rng.nextFloat();
      const float u2 = rng.nextFloat();
      dir = cosineSampleHemisphere(n, u1, u2);
    } else {
      const float u0 = rng.nextFloat();
      const float u1 = rng.nextFloat();
      const float u2 = rng.nextFloat();
      const BrdfSample bs = sampleBrdf(brdf, n, wo, u0, u1, u2);
      if (!bs.valid) break;
      weight = bs.weight;
      dir = bs.wi;
    }
    if (!(maxComponent(weight) > 0.0f)) break;
    if (k >= o.rouletteAfter) {
      // Survival by this bounce's weight (the albedo for Lambertian), not by the path throughput: the
      // path weight then never grows through roulette (weight / q <= 1 per bounce while weight <= 0.95),
      // which keeps single samples bounded and the standard error estimate trustworthy.
      // Throughput-based survival (as in pbrt-v4) gave 1/q factors of 16 and more in a furnace of albedo
      // 0.5 and a heavy-tailed, underestimated noise.
      const float q = std::min(0.95f, maxComponent(weight));
      if (rng.nextFloat() >= q) break;
      weight /= q;
    }
    throughput *= weight;
    origin = po;
  }
  return radiance;
}

void validatePosition(glm::vec3 p, size_t index) {
  if (!finite(p)) fail("probe {}: position ({}, {}, {}) is not finite", index, p.x, p.y, p.z);
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
  const Discs discs = activeDiscs(sky);
  std::atomic<uint64_t> rays{0};

  tbb::parallel_for(tbb::blocked_range<int>(0, n, 1), [&](const tbb::blocked_range<int>& rows) {
    uint64_t localRays = 0;
    for (int j = rows.begin(); j < rows.end(); ++j) {
      for (int i = 0; i < n; ++i) {
        const int texel = j * n + i;
        // Weighted sums in double: sum w, sum w^2, and per channel (RGB, luminance) sum w f, sum w^2 f,
        // sum w^2 f^2 for the delta-method standard error of the ratio estimate.
        double sw = 0, sw2 = 0, swf[4] = {}, sw2f[4] = {}, sw2f2[4] = {};
        double sr = 0, sr2 = 0, sn[3] = {}, sa[3] = {};
        for (int s = 0; s < S; ++s) {
          PathRng rng(key, texel, s);
          const TexelSample ts = primarySample(i, j, n, s, S, rng);
          FirstHit first;
          const glm::vec3 L = tracePath(scene, sky, discs, o, position, ts.direction, rng, first, localRays);
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
    }
    rays.fetch_add(localRays, std::memory_order_relaxed);
  });

  // Discs on the primary segment: energy / Omega into the texel holding the disc centre; irradiance
  // gets them analytically instead (see the header).
  std::vector<float> withoutDiscs = c.radiance;
  std::vector<const worlds::DiscLight*> visible;
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

  double relSum = 0.0;
  size_t relCount = 0;
  for (size_t t = 0; t < texels; ++t) {
    const float y = luminance(glm::vec3(c.radiance[t * 3], c.radiance[t * 3 + 1], c.radiance[t * 3 + 2]));
    if (y > 0.0f) {
      relSum += double(luminanceStdError[t]) / double(y);
      ++relCount;
    }
  }
  c.meanRelativeStdError = relCount ? relSum / double(relCount) : 0.0;

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
  c.rays = rays.load() + discRays;
  return c;
}

}  // namespace

uint64_t ProbeCapture::contentHash() const {
  uint64_t h = 0xcbf29ce484222325ULL;
  auto bytes = [&h](const void* data, size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i) h = (h ^ p[i]) * 0x100000001b3ULL;
  };
  auto floats = [&bytes](const std::vector<float>& v) {
    const uint64_t count = v.size();
    bytes(&count, sizeof count);
    bytes(v.data(), v.size() * sizeof(float));
  };
  bytes(&resolution, sizeof resolution);
  bytes(&irradianceResolution, sizeof irradianceResolution);
  bytes(&position, sizeof position);
  for (const std::vector<float>* v : {&radiance, &radianceStdError, &distance, &normal, &albedo, &irradiance})
    floats(*v);
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
  std::atomic<size_t> finished{0};
  std::atomic<bool> stopped{false};
  std::mutex progressMutex;
  std::optional<Progress> progress;
  if (showProgress) progress.emplace("capture", positions.size(), "probes");

  tbb::parallel_for(tbb::blocked_range<size_t>(0, positions.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p < r.end(); ++p) {
      if (InterruptGuard::interrupted()) {
        stopped.store(true);
        return;
      }
      result.probes[p] = captureOne(scene, sky, positions[p], options, solidAngles);
      result.done[p] = 1;
      finished.fetch_add(1);
      if (progress) {  // Progress is single-threaded: whoever holds the lock reports the current count
        std::unique_lock lock(progressMutex, std::try_to_lock);
        if (lock.owns_lock()) progress->update(finished.load());
      }
    }
  });

  if (progress) {
    progress->update(finished.load());
    progress->finish();
  }
  result.probesDone = finished.load();
  result.interrupted = stopped.load() && result.probesDone < positions.size();
  for (size_t p = 0; p < positions.size(); ++p) {
    if (result.done[p]) result.rays += result.probes[p].rays;
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace lfgi::bake
