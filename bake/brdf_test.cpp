#include "bake/brdf.h"
#include "core/hash.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>

namespace lfgi::bake {
namespace {

// Small deterministic generator for the tests (splitmix64).
struct Rng {
  uint64_t s;
  float next() { return float(splitmix64Finalize(s += kGoldenGamma) >> 40) * 0x1.0p-24f; }
};

glm::vec3 viewDirection(float thetaDeg) {
  const float t = thetaDeg * std::numbers::pi_v<float> / 180.0f;
  return glm::vec3(std::sin(t), std::cos(t), 0.0f);
}

TEST(Brdf, DefaultMaterialIsExactlyLambertian) {
  const SurfaceBrdf b{glm::vec3(0.3f, 0.5f, 0.7f), 1.0f, 0.0f};
  ASSERT_TRUE(b.isLambertian());
  EXPECT_EQ(b.specularProbability(), 0.0f);
  const glm::vec3 n(0.0f, 1.0f, 0.0f);
  const glm::vec3 f = evalBrdf(b, n, viewDirection(30.0f), glm::normalize(glm::vec3(-0.3f, 0.8f, 0.2f)));
  EXPECT_FLOAT_EQ(f.y, 0.5f / std::numbers::pi_v<float>);
  EXPECT_EQ(evalBrdf(b, n, viewDirection(30.0f), glm::vec3(0.0f, -1.0f, 0.0f)), glm::vec3(0.0f));
}

// The sampler's weights must integrate f cos to the same value as uniform hemisphere sampling (a wrong
// pdf shows up as a bias), and the pdf it reports must be brdfPdf at the sampled direction.
TEST(Brdf, ImportanceSamplingAgreesWithUniformSamplingAndItsPdf) {
  const glm::vec3 n(0.0f, 1.0f, 0.0f);
  struct Case {
    float roughness, metallic, thetaDeg;
  };
  const Case cases[] = {{0.3f, 0.0f, 20.0f},
                        {0.5f, 1.0f, 45.0f},
                        {0.25f, 0.5f, 70.0f},
                        {0.8f, 0.0f, 80.0f},
                        {0.4f, 1.0f, 5.0f}};
  for (const Case& c : cases) {
    const SurfaceBrdf b{glm::vec3(0.9f, 0.6f, 0.3f), c.roughness, c.metallic};
    const glm::vec3 wo = viewDirection(c.thetaDeg);
    const int count = 200000;
    Rng rng{uint64_t(c.thetaDeg * 1000.0f)};
    double si = 0, si2 = 0, su = 0, su2 = 0, worstPdf = 0;
    for (int i = 0; i < count; ++i) {
      const float u0 = rng.next(), u1 = rng.next(), u2 = rng.next();
      const BrdfSample s = sampleBrdf(b, n, wo, u0, u1, u2);
      const double w = s.valid ? double(s.weight.y) : 0.0;
      si += w;
      si2 += w * w;
      if (s.valid) {
        const double p = brdfPdf(b, n, wo, s.wi);
        worstPdf = std::max(worstPdf, std::abs(p - s.pdf) / p);
      }
      // Uniform hemisphere: pdf 1 / (2 pi).
      const float z = u1, r = std::sqrt(std::max(0.0f, 1.0f - z * z)),
                  phi = 2.0f * std::numbers::pi_v<float> * u2;
      const glm::vec3 wi(r * std::cos(phi), z, r * std::sin(phi));
      const double v = double(evalBrdf(b, n, wo, wi).y) * z * 2.0 * std::numbers::pi;
      su += v;
      su2 += v * v;
    }
    const double mi = si / count, mu = su / count;
    const double ei = std::sqrt(std::max(0.0, si2 / count - mi * mi) / count);
    const double eu = std::sqrt(std::max(0.0, su2 / count - mu * mu) / count);
    EXPECT_LT(std::abs(mi - mu), 4.0 * std::sqrt(ei * ei + eu * eu))
        << "roughness " << c.roughness << " metallic " << c.metallic << " theta " << c.thetaDeg;
    EXPECT_LT(worstPdf, 1e-4);
    EXPECT_LE(mi, 1.0 + 4.0 * ei);  // green albedo 0.6: no energy gain
    std::printf(
        "brdf r=%.2f m=%.1f theta=%2.0f: directional albedo (G) importance %.4f +- %.4f, uniform %.4f +- "
        "%.4f\n",
        c.roughness, c.metallic, c.thetaDeg, mi, ei, mu, eu);
  }
}

// White metal (F = 1). At roughness 1 (alpha = 1) D = 1/pi and the height-correlated V = 1 / (2 (NL + NV)),
// so the directional albedo is analytic: integral of NL / (NL + NV) over mu = NL in [0, 1] =
// 1 - c ln((1 + c) / c), c = NV (0.335 at 30 deg: single-scatter GGX loses 2/3 of the energy there, Heitz
// et al. 2016). Smooth metal reflects ~everything; nothing ever reflects more than 1.
TEST(Brdf, WhiteMetalDirectionalAlbedo) {
  const glm::vec3 n(0.0f, 1.0f, 0.0f);
  for (float roughness : {0.05f, 0.5f, 1.0f}) {
    const SurfaceBrdf b{glm::vec3(1.0f), roughness, 1.0f};
    ASSERT_EQ(b.specularProbability(), 1.0f);
    Rng rng{7};
    double sum = 0.0, sum2 = 0.0;
    const int count = 100000;
    for (int i = 0; i < count; ++i) {
      const float u0 = rng.next(), u1 = rng.next(), u2 = rng.next();
      const BrdfSample s = sampleBrdf(b, n, viewDirection(30.0f), u0, u1, u2);
      const double w = s.valid ? double(s.weight.x) : 0.0;
      sum += w;
      sum2 += w * w;
    }
    const double albedo = sum / count;
    const double se = std::sqrt(std::max(0.0, sum2 / count - albedo * albedo) / count);
    EXPECT_LE(albedo, 1.0 + 4.0 * se) << roughness;
    if (roughness == 1.0f) {
      const double c = std::cos(30.0 * std::numbers::pi / 180.0);
      const double exact = 1.0 - c * std::log((1.0 + c) / c);
      EXPECT_NEAR(albedo, exact, 4.0 * se + 1e-4);
      std::printf("white metal, roughness 1, 30 deg: albedo %.5f +- %.5f, analytic %.5f\n", albedo, se,
                  exact);
    } else {
      EXPECT_GT(albedo, roughness < 0.1f ? 0.98 : 0.75) << roughness;
      std::printf("white metal, roughness %.2f, 30 deg: albedo %.5f +- %.5f\n", roughness, albedo, se);
    }
  }
}

}  // namespace
}  // namespace lfgi::bake
