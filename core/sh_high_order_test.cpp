#include "core/sh_high_order.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "core/error.h"
#include "core/octahedral.h"
#include "core/sh.h"

namespace lfgi {
namespace {

glm::dvec3 randomDirection(std::mt19937& rng) {
  std::normal_distribution<double> g;
  glm::dvec3 d(g(rng), g(rng), g(rng));
  return glm::normalize(d);
}

TEST(ShHighOrder, FirstNineMatchShL2) {
  std::mt19937 rng(7);
  std::vector<double> y(64);
  for (int t = 0; t < 100; ++t) {
    const glm::dvec3 d = randomDirection(rng);
    shBasis(7, d, y);
    const std::array<float, 9> l2 = shBasisL2(glm::vec3(d));
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(y[size_t(k)], l2[size_t(k)], 2e-6) << "k = " << k;
  }
}

// Orthonormality over the sphere, every product integrated exactly over the octahedral texels (the same
// quadrature the projection weights use), so this also checks the texel weights' premise.
TEST(ShHighOrder, OrthonormalWithExactTexelIntegrals) {
  constexpr int K = 64;
  const int n = 8;
  const std::vector<double> products = octTexelIntegrals(
      n, K * K,
      [](const glm::dvec3& w, double* v) {
        double y[K];
        shBasis(7, w, std::span<double>(y, K));
        for (int a = 0; a < K; ++a)
          for (int b = 0; b < K; ++b) v[a * K + b] = y[a] * y[b];
      },
      /*order=*/12);  // products reach degree 14: order 8 leaves ~5e-10
  double worst = 0.0;
  for (int a = 0; a < K; ++a)
    for (int b = 0; b < K; ++b) {
      double g = 0.0;
      for (int t = 0; t < n * n; ++t) g += products[size_t(t) * K * K + size_t(a * K + b)];
      worst = std::max(worst, std::abs(g - (a == b ? 1.0 : 0.0)));
    }
  std::printf("max |<Y_a, Y_b> - delta_ab| over 64x64 pairs: %.3g\n", worst);
  EXPECT_LT(worst, 1e-10);
}

TEST(ShHighOrder, ConstantMapProjectsExactly) {
  const int n = 16;
  const auto w = shTexelWeightsHigh(7, n);
  ASSERT_EQ(w->size(), size_t(n * n * 64));
  // A constant map of value 1: c_0 = sqrt(4 pi), every other coefficient 0.
  for (int k = 0; k < 64; ++k) {
    double c = 0.0;
    for (int t = 0; t < n * n; ++t) c += (*w)[size_t(t) * 64 + size_t(k)];
    EXPECT_NEAR(c, k == 0 ? std::sqrt(4.0 * std::numbers::pi) : 0.0, 1e-11) << "k = " << k;
  }
  // The first 9 weights are core/sh.h's.
  const auto w2 = shTexelWeights(n);
  for (int t = 0; t < n * n; ++t)
    for (int k = 0; k < 9; ++k)
      EXPECT_NEAR((*w)[size_t(t) * 64 + size_t(k)], (*w2)[size_t(t) * 9 + size_t(k)], 1e-14);
}

// The clamped cosine about +Z has only zonal coefficients; they match the closed form of the header and,
// for l <= 2, core/sh.h's analytic values; integrated exactly over the octahedral texels.
TEST(ShHighOrder, CosineLobeProjectsExactly) {
  const int n = 16;
  // The lobe's kink z = 0 is the line v = 0 of the map (and its fold), a texel edge for even n, so each
  // texel's integrand is smooth and the quadrature stays spectrally accurate.
  const std::vector<double> c = octTexelIntegrals(n, 64, [](const glm::dvec3& w, double* v) {
    double y[64];
    shBasis(7, w, std::span<double>(y, 64));
    for (int k = 0; k < 64; ++k) v[k] = std::max(0.0, w.z) * y[k];
  });
  double worst = 0.0;
  for (int k = 0; k < 64; ++k) {
    double sum = 0.0;
    for (int t = 0; t < n * n; ++t) sum += c[size_t(t) * 64 + size_t(k)];
    const int l = shBandOf(k);
    const bool zonal = k == l * (l + 1);
    worst = std::max(worst, std::abs(sum - (zonal ? clampedCosineZonalHigh(l) : 0.0)));
  }
  std::printf("clamped cosine: max coefficient error %.3g over 64 coefficients\n", worst);
  EXPECT_LT(worst, 1e-10);
  for (int l = 0; l <= 2; ++l) EXPECT_NEAR(clampedCosineZonalHigh(l), clampedCosineZonal(l), 1e-14);
  const double pi = std::numbers::pi;
  EXPECT_NEAR(shIrradianceFactor(0), pi, 1e-14);
  EXPECT_NEAR(shIrradianceFactor(1), 2.0 * pi / 3.0, 1e-14);
  EXPECT_NEAR(shIrradianceFactor(2), pi / 4.0, 1e-14);
  EXPECT_EQ(shIrradianceFactor(3), 0.0);
  EXPECT_NEAR(shIrradianceFactor(4), -pi / 24.0, 1e-14);  // Ramamoorthi & Hanrahan 2001, eq. 8
  EXPECT_NEAR(shIrradianceFactor(6), pi / 64.0, 1e-14);
  EXPECT_EQ(shIrradianceFactor(7), 0.0);
}

TEST(ShHighOrder, RejectsBadArguments) {
  std::vector<double> y(64);
  EXPECT_THROW(shBasis(8, {0, 0, 1}, y), Error);
  EXPECT_THROW(shBasis(7, {0, 0, 1}, std::span<double>(y.data(), 63)), Error);
  EXPECT_THROW(shTexelWeightsHigh(7, 0), Error);
  EXPECT_THROW(shIrradianceFactor(-1), Error);
}

}  // namespace
}  // namespace lfgi
