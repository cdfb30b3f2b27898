#include "core/sh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <random>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi {
namespace {

constexpr double kPi = std::numbers::pi;

std::vector<float> rgbMapOf(int n, const std::function<glm::vec3(glm::vec3)>& f) {
  std::vector<float> map(octInteriorFloats(n, 3));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const glm::vec3 v = f(octTexelDirection(i, j, n));
      const std::size_t t = static_cast<std::size_t>(j * n + i) * 3;
      map[t] = v.x;
      map[t + 1] = v.y;
      map[t + 2] = v.z;
    }
  return map;
}

std::vector<glm::vec3> testNormals(int count) {
  std::mt19937 rng(99);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<glm::vec3> normals = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  while (int(normals.size()) < count) {
    const glm::vec3 d(g(rng), g(rng), g(rng));
    if (glm::length(d) > 1e-3f) normals.push_back(glm::normalize(d));
  }
  return normals;
}

TEST(Sh, BasisIsOrthonormal) {
  // Gram matrix integrated over the texel footprints (Gauss quadrature, not texel centres).
  const std::vector<double> gram = octTexelIntegrals(8, 81, [](const glm::dvec3& w, double* out) {
    const auto y = shBasisL2(glm::vec3(w));
    for (int a = 0; a < 9; ++a)
      for (int b = 0; b < 9; ++b) out[a * 9 + b] = double(y[a]) * y[b];
  });
  double worst = 0.0;
  for (int a = 0; a < 9; ++a)
    for (int b = 0; b < 9; ++b) {
      double sum = 0.0;
      for (std::size_t t = 0; t < 64; ++t) sum += gram[t * 81 + static_cast<std::size_t>(a * 9 + b)];
      worst = std::max(worst, std::abs(sum - (a == b ? 1.0 : 0.0)));
    }
  EXPECT_LT(worst, 1e-6);  // the float basis constants
}

TEST(Sh, TexelWeightsIntegrateTheBasis) {
  for (int n : {1, 2, 3, 8, 16, 31}) {
    const auto weights = shTexelWeights(n);
    const std::vector<double> omega = octTexelSolidAngles(n);
    ASSERT_EQ(weights->size(), omega.size() * 9);
    double sums[9] = {};
    for (std::size_t t = 0; t < omega.size(); ++t) {
      for (int k = 0; k < 9; ++k) sums[k] += (*weights)[t * 9 + static_cast<std::size_t>(k)];
      EXPECT_NEAR((*weights)[t * 9], 0.28209479177387814 * omega[t], 1e-13) << "n = " << n << " texel " << t;
    }
    EXPECT_NEAR(sums[0], 2.0 * std::sqrt(kPi), 1e-12) << "n = " << n;  // integral of Y00 = sqrt(4 pi)
    for (int k = 1; k < 9; ++k) EXPECT_NEAR(sums[k], 0.0, 1e-12) << "n = " << n << " k = " << k;
  }
  EXPECT_EQ(shTexelWeights(16).get(), shTexelWeights(16).get());  // cached
}

TEST(Sh, ConstantEnvironmentGivesPiTimesRadiance) {
  const glm::vec3 radiance(0.5f, 1.0f, 2.0f);
  double worst = 0.0;
  for (int n : {1, 4, 8, 16, 32}) {
    const std::vector<float> map = rgbMapOf(n, [&](glm::vec3) { return radiance; });
    const ShL2 l2 = shProject<9>(map, n);
    const ShL1 l1 = shProject<4>(map, n);
    for (const glm::vec3& normal : testNormals(200)) {
      for (const glm::vec3 e : {shIrradiance(l2, normal), shIrradiance(l1, normal)})
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(e[c] / (kPi * radiance[c]) - 1.0));
    }
  }
  std::printf("  constant environment, n = 1..32: max relative irradiance error %.3g\n", worst);
  EXPECT_LT(worst, 1e-6);  // float coefficients and evaluation; the projection is exact for a constant map
}

TEST(Sh, CentreSampledBasisProjectsToIdentity) {
  // Each basis function sampled at texel centres projects to (nearly) a unit vector: the O(1/n^2) error
  // of treating centre samples as texel averages.
  const int n = 64;
  double worst = 0.0;
  for (int a = 0; a < 9; ++a) {
    const std::vector<float> map = rgbMapOf(n, [&](glm::vec3 w) { return glm::vec3(shBasisL2(w)[a]); });
    const ShL2 sh = shProject<9>(map, n);
    for (int b = 0; b < 9; ++b) worst = std::max(worst, std::abs(double(sh.c[b].x) - (a == b ? 1.0 : 0.0)));
  }
  std::printf("  n=64 centre-sampled basis: max |projection - identity| %.3g\n", worst);
  EXPECT_LT(worst, 1.5 * (2.0 / n) * (2.0 / n));
}

TEST(Sh, ClampedCosineProjectsToAnalyticZonalCoefficients) {
  // Zonal axis is +Z in this basis: max(0, z . w) has coefficients only at k = 0, 2 (Y10), 6 (Y20).
  const int n = 128;
  const std::vector<float> map = rgbMapOf(n, [](glm::vec3 w) { return glm::vec3(std::max(0.0f, w.z)); });
  const ShL2 sh = shProject<9>(map, n);
  const double expected[9] = {
      clampedCosineZonal(0), 0, clampedCosineZonal(1), 0, 0, 0, clampedCosineZonal(2), 0, 0};
  EXPECT_NEAR(clampedCosineZonal(0), 0.886227, 1e-6);
  EXPECT_NEAR(clampedCosineZonal(1), 1.023327, 1e-6);
  EXPECT_NEAR(clampedCosineZonal(2), 0.495416, 1e-6);
  double worst = 0.0;
  for (int k = 0; k < 9; ++k) worst = std::max(worst, std::abs(double(sh.c[k].x) - expected[k]));
  std::printf("  clamped cosine, n=128: max |coefficient - analytic| %.3g\n", worst);
  // The lobe is sampled at texel centres; its kink at the horizon limits the accuracy (measured 1.1e-4).
  EXPECT_LT(worst, 2e-4);
}

TEST(Sh, RotatedClampedCosineMatchesConvolutionConstants) {
  // For the lobe max(0, a . w) the coefficients are A_l * Y_lm(a) (Funk-Hecke); A_l as in R&H 2001.
  const int n = 128;
  const double A[3] = {kPi, 2.0 * kPi / 3.0, kPi / 4.0};
  const auto weights = shTexelWeights(n);
  double worst = 0.0;
  for (const glm::vec3& axis : testNormals(10)) {
    const std::vector<float> map =
        rgbMapOf(n, [&](glm::vec3 w) { return glm::vec3(std::max(0.0f, glm::dot(axis, w))); });
    const ShL2 sh = shProject<9>(map, n, *weights);
    const auto y = shBasisL2(axis);
    for (int k = 0; k < 9; ++k) {
      const int l = k == 0 ? 0 : (k < 4 ? 1 : 2);
      worst = std::max(worst, std::abs(double(sh.c[k].y) - A[l] * y[k]));
    }
  }
  EXPECT_LT(worst, 3e-4);
}

// A clear-sky-like environment without a sun: zenith blue, brighter towards the horizon, a slight
// east-west gradient, and a darker (albedo-lit, 30 % of the horizon) ground, joined by a smooth blend a
// few degrees wide at the horizon. Smooth, so L2 irradiance should represent it.
glm::vec3 sky(glm::vec3 w) {
  const glm::vec3 zenith(0.25f, 0.45f, 1.0f);
  const glm::vec3 horizon(0.9f, 0.95f, 1.1f);
  const glm::vec3 ground = 0.3f * glm::vec3(0.6f, 0.5f, 0.4f);
  const float up = std::max(w.y, 0.0f);
  const glm::vec3 skyColour = glm::mix(horizon, zenith, std::pow(up, 0.6f)) * (1.0f + 0.3f * w.x);
  return glm::mix(ground, skyColour, glm::smoothstep(-0.15f, 0.05f, w.y));
}

TEST(Sh, L2IrradianceOfSkyMatchesBruteForce) {
  const int n = 64;
  const std::vector<float> map = rgbMapOf(n, sky);
  const std::vector<double> omega = octTexelSolidAngles(n);
  const ShL2 l2 = shProject<9>(map, n);
  const ShL1 l1 = shProject<4>(map, n);
  // Per-normal relative error |E_sh / E_true - 1| (max over RGB), split by where the normal faces, and
  // the project's relative RMS over all normals and channels.
  double maxAll = 0.0, maxUpper = 0.0, maxL1 = 0.0, errSq = 0.0, truthSq = 0.0;
  float worstNormalY = 0.0f;
  for (const glm::vec3& normal : testNormals(300)) {
    const glm::vec3 truth = bruteForceIrradiance(map, n, normal, omega);
    const glm::vec3 e2 = shIrradiance(l2, normal);
    const glm::vec3 e1 = shIrradiance(l1, normal);
    for (int c = 0; c < 3; ++c) {
      const double rel = std::abs(double(e2[c]) / truth[c] - 1.0);
      if (rel > maxAll) worstNormalY = normal.y;
      maxAll = std::max(maxAll, rel);
      if (normal.y >= -0.5f) maxUpper = std::max(maxUpper, rel);
      maxL1 = std::max(maxL1, std::abs(double(e1[c]) / truth[c] - 1.0));
      errSq += (double(e2[c]) - truth[c]) * (double(e2[c]) - truth[c]);
      truthSq += double(truth[c]) * truth[c];
    }
  }
  const double relRms = std::sqrt(errSq / truthSq);
  std::printf(
      "  sky irradiance, L2, 300 normals: relative RMS %.4f; max relative %.4f for normals with "
      "n.y >= -0.5, %.4f over all (worst at n.y = %.2f); L1 max relative %.4f\n",
      relRms, maxUpper, maxAll, worstNormalY, maxL1);
  // Measured (n = 64): relative RMS 0.0039, max 0.0262 for n.y >= -0.5 (the horizontal axis normals),
  // 0.0678 over all. The worst normal faces straight down at the dark ground, where E is small and the
  // L2 truncation of the bright sky (its ringing) is a larger fraction of it: that one exceeds 3 %, and
  // is asserted at its measured value rather than hidden.
  EXPECT_LE(relRms, 0.005);
  EXPECT_LE(maxUpper, 0.03);
  EXPECT_LE(maxAll, 0.07);
}

TEST(Sh, BruteForceConstantAndSizeChecks) {
  const int n = 32;
  const std::vector<float> map = rgbMapOf(n, [](glm::vec3) { return glm::vec3(1.0f); });
  // Texel-centre quadrature of the clamped cosine: the kink at the horizon costs O(1/n^2).
  double worst = 0.0;
  for (const glm::vec3& normal : testNormals(20))
    worst = std::max(worst, std::abs(bruteForceIrradiance(map, n, normal).x / kPi - 1.0));
  std::printf("  n=32 brute-force irradiance of a constant map: max relative error %.3g\n", worst);
  EXPECT_LT(worst, 3e-3);
  EXPECT_THROW(shProject<9>(std::vector<float>(10), n), Error);
  EXPECT_THROW(bruteForceIrradiance(map, n + 1, {0, 1, 0}), Error);
  EXPECT_THROW(clampedCosineZonal(3), Error);
}

}  // namespace
}  // namespace lfgi
