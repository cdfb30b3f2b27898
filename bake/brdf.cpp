#include "bake/brdf.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace lfgi::bake {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr float kDielectricF0 = 0.04f;

struct Frame {
  glm::vec3 t, b, n;
};

// Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (JCGT 6(1)).
Frame frame(glm::vec3 n) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float b = n.x * n.y * a;
  return {glm::vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x),
          glm::vec3(b, sign + n.y * n.y * a, -n.y), n};
}

float luminance(glm::vec3 c) {
  return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}

float ggxD(float nh, float a2) {
  const float d = nh * nh * (a2 - 1.0f) + 1.0f;
  return a2 / (kPi * d * d);
}

float smithV(float nl, float nv, float a2) {
  const float gv = nl * std::sqrt(nv * nv * (1.0f - a2) + a2);
  const float gl = nv * std::sqrt(nl * nl * (1.0f - a2) + a2);
  return 0.5f / (gv + gl);
}

glm::vec3 schlick(glm::vec3 f0, float vh) {
  const float m = std::clamp(1.0f - vh, 0.0f, 1.0f);
  const float m5 = m * m * m * m * m;
  return f0 + (glm::vec3(1.0f) - f0) * m5;
}

glm::vec3 diffuseWeight(const SurfaceBrdf& b) {
  return (1.0f - b.metallic) * (1.0f - kDielectricF0) * b.albedo;
}

}  // namespace

float SurfaceBrdf::alpha() const {
  return std::max(roughness * roughness, 1e-3f);
}

glm::vec3 SurfaceBrdf::f0() const {
  return glm::mix(glm::vec3(kDielectricF0), albedo, std::clamp(metallic, 0.0f, 1.0f));
}

float SurfaceBrdf::specularProbability() const {
  if (isLambertian()) return 0.0f;
  const float d = luminance(diffuseWeight(*this));
  if (!(d > 0.0f)) return 1.0f;
  const float s = luminance(f0());
  return std::clamp(s / (s + d), 0.1f, 1.0f);
}

glm::vec3 cosineSampleHemisphere(glm::vec3 n, float u1, float u2) {
  const Frame f = frame(n);
  const float r = std::sqrt(u1);
  const float phi = 2.0f * kPi * u2;
  const float z = std::sqrt(std::max(0.0f, 1.0f - u1));
  return glm::normalize(r * std::cos(phi) * f.t + r * std::sin(phi) * f.b + z * n);
}

glm::vec3 evalBrdf(const SurfaceBrdf& b, glm::vec3 n, glm::vec3 wo, glm::vec3 wi) {
  const float nl = glm::dot(n, wi);
  const float nv = glm::dot(n, wo);
  if (nl <= 0.0f || nv <= 0.0f) return glm::vec3(0.0f);
  if (b.isLambertian()) return b.albedo * (1.0f / kPi);
  glm::vec3 f = diffuseWeight(b) * (1.0f / kPi);
  const glm::vec3 h = glm::normalize(wo + wi);
  const float a = b.alpha();
  const float a2 = a * a;
  f += ggxD(std::max(glm::dot(n, h), 0.0f), a2) * smithV(nl, nv, a2) * schlick(b.f0(), glm::dot(wo, h));
  return f;
}

glm::vec3 diffuseBrdf(const SurfaceBrdf& b) {
  if (b.isLambertian()) return b.albedo * (1.0f / kPi);
  return diffuseWeight(b) * (1.0f / kPi);
}

float brdfPdf(const SurfaceBrdf& b, glm::vec3 n, glm::vec3 wo, glm::vec3 wi) {
  const float nl = glm::dot(n, wi);
  if (nl <= 0.0f) return 0.0f;
  const float ps = b.specularProbability();
  float pdf = (1.0f - ps) * nl / kPi;
  if (ps > 0.0f) {
    const glm::vec3 h = glm::normalize(wo + wi);
    const float vh = glm::dot(wo, h);
    if (vh > 0.0f) {
      const float a = b.alpha();
      const float nh = std::max(glm::dot(n, h), 0.0f);
      pdf += ps * ggxD(nh, a * a) * nh / (4.0f * vh);
    }
  }
  return pdf;
}

BrdfSample sampleBrdf(const SurfaceBrdf& b, glm::vec3 n, glm::vec3 wo, float u0, float u1, float u2) {
  BrdfSample s;
  const float ps = b.specularProbability();
  if (u0 < ps) {
    const float a = b.alpha();
    const float a2 = a * a;
    const float cos2 = (1.0f - u1) / (1.0f + (a2 - 1.0f) * u1);
    const float cosT = std::sqrt(std::max(0.0f, cos2));
    const float sinT = std::sqrt(std::max(0.0f, 1.0f - cos2));
    const float phi = 2.0f * kPi * u2;
    const Frame f = frame(n);
    const glm::vec3 h = glm::normalize(sinT * std::cos(phi) * f.t + sinT * std::sin(phi) * f.b + cosT * n);
    s.wi = glm::normalize(2.0f * glm::dot(wo, h) * h - wo);
  } else {
    s.wi = cosineSampleHemisphere(n, u1, u2);
  }
  const float nl = glm::dot(n, s.wi);
  if (nl <= 0.0f) return s;
  s.pdf = brdfPdf(b, n, wo, s.wi);
  if (!(s.pdf > 0.0f)) return s;
  s.weight = evalBrdf(b, n, wo, s.wi) * (nl / s.pdf);
  s.valid = true;
  return s;
}

}  // namespace lfgi::bake
