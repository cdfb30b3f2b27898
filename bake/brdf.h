// The surface model of the ground truth: Lambertian, plus a "simple GGX" specular lobe for materials with
// metallic > 0 or roughness < 1 (glTF metallic-roughness parameters, worlds::Material).
//
// f(wo, wi) = (1 - metallic) (1 - 0.04) albedo / pi                            diffuse
//           + D(h) V(wo, wi) F(wo . h)                                          specular
//   D: GGX / Trowbridge-Reitz (Walter et al. 2007, "Microfacet Models for Refraction through Rough
//      Surfaces"), alpha = max(roughness^2, 1e-3) (Burley 2012 remapping);
//   V: height-correlated Smith visibility G2 / (4 NL NV) (Heitz 2014, "Understanding the Masking-Shadowing
//      Function in Microfacet-Based BRDFs", eq. 99; the form of Filament's V_SmithGGXCorrelated);
//   F: Schlick, F0 = mix(0.04, albedo, metallic).
// Limits, stated: single scattering only (rough metals lose energy as in every single-scatter GGX: a
// white metal of roughness 1 reflects 1 - c ln((1 + c) / c) at c = NV, 0.335 at 30 deg; no Kulla-Conty
// compensation), and the constant diffuse weight does not subtract the specular reflectance, so a
// bright rough dielectric can reflect slightly more than 1 at grazing angles.
// Roughness 1 and metallic 0 (the worlds/ default) is exactly Lambertian: isLambertian() and the path
// tracer take the cosine-sampled branch, bit-identical to a pure diffuse tracer.
//
// Sampling: one-sample mixture of cosine-weighted hemisphere sampling and GGX half-vector sampling
// (h ~ D(h) (n . h), Walter et al. 2007 eq. 35/36), lobe chosen with probability specularProbability();
// the returned pdf is the full mixture pdf, so weight = f cos / pdf is unbiased for any choice.
// All vectors are unit and in world space; n is the shading normal on the side of wo.
#pragma once

#include <glm/glm.hpp>

namespace lfgi::bake {

struct SurfaceBrdf {
  glm::vec3 albedo{0.5f};
  float roughness = 1.0f;
  float metallic = 0.0f;

  bool isLambertian() const { return metallic <= 0.0f && roughness >= 1.0f; }
  float alpha() const;
  glm::vec3 f0() const;
  // Probability of sampling the specular lobe: 1 for pure metals, else specular/(specular + diffuse)
  // weight by luminance, at least 0.1; 0 when isLambertian().
  float specularProbability() const;
};

// f(wo, wi) without the cosine; 0 when either direction is below the surface (n . w <= 0).
glm::vec3 evalBrdf(const SurfaceBrdf& b, glm::vec3 n, glm::vec3 wo, glm::vec3 wi);
// The diffuse part of f (a constant: (1 - metallic) (1 - 0.04) albedo / pi, or albedo / pi when
// isLambertian()); f - diffuseBrdf is the specular lobe. Used to split a path's first bounce by lobe.
glm::vec3 diffuseBrdf(const SurfaceBrdf& b);
// Solid-angle density of sampleBrdf producing wi.
float brdfPdf(const SurfaceBrdf& b, glm::vec3 n, glm::vec3 wo, glm::vec3 wi);

struct BrdfSample {
  glm::vec3 wi{0.0f};
  glm::vec3 weight{0.0f};  // f(wo, wi) (n . wi) / pdf
  float pdf = 0.0f;
  bool valid = false;  // false if the sampled direction is below the surface (path ends)
};
// u0 picks the lobe, (u1, u2) the direction; all in [0, 1).
BrdfSample sampleBrdf(const SurfaceBrdf& b, glm::vec3 n, glm::vec3 wo, float u0, float u1, float u2);

// Cosine-distributed direction about unit n (Malley's method, branchless ONB of Duff et al. 2017).
glm::vec3 cosineSampleHemisphere(glm::vec3 n, float u1, float u2);

}  // namespace lfgi::bake
