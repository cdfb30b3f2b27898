#include "bake/path_trace.h"

#include <algorithm>
#include <bit>
#include <numbers>
#include <optional>

#include "bake/brdf.h"

namespace lfgi::bake::detail {

namespace {
constexpr float kInvPi = float(1.0 / std::numbers::pi);
}  // namespace

float maxComponent(glm::vec3 c) {
  return std::max(c.x, std::max(c.y, c.z));
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

Discs activeDiscs(const worlds::SkyModel& sky) {
  Discs d{};
  for (const worlds::DiscLight* l : {&sky.sun, &sky.moon}) {
    if (maxComponent(l->irradianceNormal()) > 0.0f) d.light[d.count++] = l;
  }
  return d;
}

namespace {

// Light L emitted towards hit k - 1 (by the sky after a miss, or by the surface hit k).
inline void addEmitted(glm::vec3& radiance, glm::vec3& beyond, glm::vec3 throughput, glm::vec3 rest,
                       PathSplit* split, int k, glm::vec3 L) {
  radiance += throughput * L;
  if (split) {
    if (k <= 1) {
      split->direct += throughput * L;
    } else {
      beyond += rest * L;
    }
  }
}

// Bounce at hit k: the next direction into dir and the bounce's weight into the throughput; false ends the
// path. Lambertian with cosine sampling: f cos / pdf = albedo exactly; otherwise brdf.h's mixture.
inline bool bounce(const SurfaceBrdf& brdf, bool lambertian, glm::vec3 albedo, glm::vec3 n, glm::vec3 wo,
                   int k, const PathOptions& o, PathRng& rng, PathSplit* split, glm::vec3& throughput,
                   glm::vec3& rest, glm::vec3& w0Diffuse, glm::vec3& w0Specular, glm::vec3& dir) {
  glm::vec3 weight;
  if (lambertian) {
    weight = albedo;
    const float u1 = rng.nextFloat();
    const float u2 = rng.nextFloat();
    dir = cosineSampleHemisphere(n, u1, u2);
    if (split && k == 0) w0Diffuse = albedo;
  } else {
    const float u0 = rng.nextFloat();
    const float u1 = rng.nextFloat();
    const float u2 = rng.nextFloat();
    const BrdfSample bs = sampleBrdf(brdf, n, wo, u0, u1, u2);
    if (!bs.valid) return false;
    weight = bs.weight;
    dir = bs.wi;
    if (split && k == 0) {
      // f = f_diffuse + f_specular, both over the same mixture pdf: each part is an unbiased estimate of
      // its own lobe's share whichever lobe was sampled.
      w0Diffuse = diffuseBrdf(brdf) * (glm::dot(n, bs.wi) / bs.pdf);
      w0Specular = bs.weight - w0Diffuse;
    }
  }
  if (!(maxComponent(weight) > 0.0f)) return false;
  if (k >= o.rouletteAfter) {
    // Survival by this bounce's weight (the albedo for Lambertian), not by the path throughput: the
    // path weight then never grows through roulette (weight / q <= 1 per bounce while weight <= 0.95),
    // which keeps single samples bounded and the standard error estimate trustworthy.
    // Throughput-based survival (as in pbrt-v4) gave 1/q factors of 16 and more in a furnace of albedo
    // 0.5 and a heavy-tailed, underestimated noise.
    const float q = std::min(0.95f, maxComponent(weight));
    if (rng.nextFloat() >= q) return false;
    weight /= q;
  }
  throughput *= weight;
  if (k >= 1) rest *= weight;
  return true;
}

}  // namespace

// The split (when asked for) rides along without touching the total's arithmetic: contributions at hit 0
// and those arriving at hit 0 straight from an emitter or the sky are `direct`; everything else is
// accumulated in `beyond` per unit of the first bounce's weight w0 (rest = the throughput after it) and
// multiplied at the end by w0's diffuse and specular parts.
glm::vec3 tracePath(const EmbreeScene& scene, const worlds::SkyModel& sky, const Discs& discs,
                    const PathOptions& o, glm::vec3 origin, glm::vec3 dir, PathRng& rng, FirstHit& first,
                    uint64_t& rays, PathSplit* split) {
  const worlds::TriangleMesh& mesh = scene.mesh();
  glm::vec3 radiance(0.0f);
  glm::vec3 throughput(1.0f);
  glm::vec3 beyond(0.0f), rest(1.0f), w0Diffuse(0.0f), w0Specular(0.0f);
  first = FirstHit{o.maxDistance, glm::vec3(0.0f), glm::vec3(0.0f)};
  for (int k = 0;; ++k) {
    const std::optional<RayHit> hit = scene.intersect(origin, dir, 0.0f, o.maxDistance);
    ++rays;
    if (!hit) {
      glm::vec3 L = worlds::skyRadiance(sky, dir);
      if (k == 0 && o.discsOnPrimaryMiss) L += worlds::discRadiance(sky, dir);
      addEmitted(radiance, beyond, throughput, rest, split, k, L);
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
    addEmitted(radiance, beyond, throughput, rest, split, k, m.emission);
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
      if (!scene.occluded(po, l.direction, 0.0f, o.maxDistance)) {
        radiance += throughput * f * l.irradiance(n);
        if (split) {
          if (k == 0) {
            split->direct += f * l.irradiance(n);
          } else {
            beyond += rest * f * l.irradiance(n);
          }
        }
      }
    }
    if (!bounce(brdf, lambertian, albedo, n, wo, k, o, rng, split, throughput, rest, w0Diffuse, w0Specular,
                dir))
      break;
    origin = po;
  }
  if (split) {
    split->indirectDiffuse = w0Diffuse * beyond;
    split->indirectSpecular = w0Specular * beyond;
  }
  return radiance;
}

}  // namespace lfgi::bake::detail
