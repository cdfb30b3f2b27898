#include "core/octahedral.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <random>

#include "core/error.h"

namespace lfgi {
namespace {

constexpr double kFourPi = 4.0 * std::numbers::pi;

glm::vec3 randomDirection(std::mt19937& rng) {
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  for (;;) {
    const glm::vec3 d(gauss(rng), gauss(rng), gauss(rng));
    const float len = glm::length(d);
    if (len > 1e-3f) return d / len;
  }
}

double angleBetween(glm::dvec3 a, glm::dvec3 b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

TEST(Octahedral, RoundTripRandomDirections) {
  std::mt19937 rng(20240611);
  double worst = 0.0;
  for (int k = 0; k < 100000; ++k) {
    const glm::vec3 d = randomDirection(rng);
    const glm::vec2 p = octEncode(d);
    ASSERT_LE(std::abs(p.x), 1.0f);
    ASSERT_LE(std::abs(p.y), 1.0f);
    worst = std::max(worst, angleBetween(d, octDecode(p)));
  }
  std::printf("  max round-trip angular error over 1e5 directions: %.3g rad\n", worst);
  EXPECT_LT(worst, 1e-6);  // float: a few ulp of the unit vector
}

TEST(Octahedral, AxesAndHemispheres) {
  // +Y (up) at the centre, -Y at the corners, +X towards +u, +Z towards +v.
  EXPECT_NEAR(octEncode({0, 1, 0}).x, 0.0f, 1e-7f);
  EXPECT_NEAR(octEncode({0, 1, 0}).y, 0.0f, 1e-7f);
  EXPECT_NEAR(std::abs(octEncode({0, -1, 0}).x), 1.0f, 1e-7f);
  EXPECT_NEAR(std::abs(octEncode({0, -1, 0}).y), 1.0f, 1e-7f);
  EXPECT_NEAR(octEncode({1, 0, 0}).x, 1.0f, 1e-7f);
  EXPECT_NEAR(octEncode({0, 0, 1}).y, 1.0f, 1e-7f);
  EXPECT_NEAR(octEncode({-1, 0, 0}).x, -1.0f, 1e-7f);
  EXPECT_NEAR(octEncode({0, 0, -1}).y, -1.0f, 1e-7f);
}

TEST(Octahedral, EveryTexelCentreMapsToItsTexel) {
  for (int n = 1; n <= 128; ++n) {
    int wrong = 0;
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const glm::ivec2 t = octDirectionTexel(octTexelDirection(i, j, n), n);
        if (t != glm::ivec2(i, j)) ++wrong;
      }
    }
    EXPECT_EQ(wrong, 0) << "n = " << n;
  }
}

// A smooth test function on the sphere (no symmetry the border could hide behind).
float smoothFunction(glm::vec3 d) {
  return 1.0f + 0.6f * d.x - 0.4f * d.y + 0.5f * d.z + 0.3f * d.x * d.z + 0.2f * d.y * d.y;
}
// Linear in x and z only: no y, whose crease across the fold edges is the largest.
float foldProbeFunction(glm::vec3 d) {
  return 1.0f + d.x + d.z;
}

std::vector<float> interiorOf(int n, const std::function<float(glm::vec3)>& f) {
  std::vector<float> map(octInteriorFloats(n, 1));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) map[static_cast<std::size_t>(j * n + i)] = f(octTexelDirection(i, j, n));
  return map;
}

// Directions whose encode lies within 1.5 texels of the map edge (where the border taps are used).
std::vector<glm::vec3> edgeDirections(int n, int count, std::mt19937& rng) {
  std::uniform_real_distribution<float> along(-1.0f, 1.0f);
  std::uniform_real_distribution<float> depth(0.0f, 3.0f / float(n));
  std::vector<glm::vec3> dirs;
  for (int k = 0; k < count; ++k) {
    const float a = along(rng);
    const float e = 1.0f - depth(rng);
    glm::vec2 p;
    switch (k % 5) {
      case 0:
        p = {a, -e};
        break;
      case 1:
        p = {a, e};
        break;
      case 2:
        p = {-e, a};
        break;
      case 3:
        p = {e, a};
        break;
      default:
        p = {(k & 8) ? e : -e, (k & 16) ? 1.0f - depth(rng) : -1.0f + depth(rng)};
        break;  // corners
    }
    dirs.push_back(octDecode(p));
  }
  return dirs;
}

double maxSampleError(const std::vector<float>& bordered, int n, const std::vector<glm::vec3>& dirs,
                      const std::function<float(glm::vec3)>& f) {
  double worst = 0.0;
  for (const glm::vec3& d : dirs) {
    float v = 0.0f;
    octSampleBilinear(bordered.data(), n, 1, d, &v);
    worst = std::max(worst, double(std::abs(v - f(d))));
  }
  return worst;
}

TEST(Octahedral, BilinearAcrossBorderStaysCloseToSmoothFunction) {
  std::mt19937 rng(7);
  for (int n : {8, 16, 32}) {
    const std::vector<float> bordered = makeBordered(interiorOf(n, smoothFunction), n, 1);
    const std::vector<glm::vec3> edge = edgeDirections(n, 5000, rng);
    std::vector<glm::vec3> anywhere;
    for (int k = 0; k < 5000; ++k) anywhere.push_back(randomDirection(rng));
    const double edgeErr = maxSampleError(bordered, n, edge, smoothFunction);
    const double anyErr = maxSampleError(bordered, n, anywhere, smoothFunction);
    std::printf("  n=%d: max |bilinear - f| near edges %.4f, anywhere %.4f\n", n, edgeErr, anyErr);
    // The crease of the fold makes the error first order in the texel size h = 2/n; bound it by 0.6 h
    // (the function's gradient is about 1).
    EXPECT_LT(edgeErr, 1.2 / n) << "n = " << n;
    EXPECT_LT(anyErr, 1.2 / n) << "n = " << n;
  }
}

TEST(Octahedral, WrongBorderMirrorIsCaught) {
  const int n = 16;
  std::mt19937 rng(11);
  const std::vector<glm::vec3> edge = edgeDirections(n, 5000, rng);
  const std::vector<float> interior = interiorOf(n, foldProbeFunction);
  const std::vector<float> good = makeBordered(interior, n, 1);

  // Same border filled without the mirror (edge texels copy the adjacent interior texel, corners the
  // nearest corner): what a clamp-to-edge sampler would see.
  std::vector<float> clamped = good;
  for (int y = 0; y < n + 2; ++y)
    for (int x = 0; x < n + 2; ++x) {
      const int sx = std::clamp(x, 1, n), sy = std::clamp(y, 1, n);
      clamped[static_cast<std::size_t>(y * (n + 2) + x)] =
          clamped[static_cast<std::size_t>(sy * (n + 2) + sx)];
    }
  // Mirrored about the wrong centre (off by one texel along the edge): interior index n - 1 - i + 1.
  std::vector<float> offByOne = good;
  for (int y = 0; y < n + 2; ++y)
    for (int x = 0; x < n + 2; ++x) {
      const bool outX = x == 0 || x == n + 1, outY = y == 0 || y == n + 1;
      if (outX == outY) continue;  // interior or corner
      // Bordered (x, y) on the top/bottom edge: correct source column is n + 1 - x; use n + 2 - x.
      const int sx = outY ? std::clamp(n + 2 - x, 1, n) : (x == 0 ? 1 : n);
      const int sy = outX ? std::clamp(n + 2 - y, 1, n) : (y == 0 ? 1 : n);
      offByOne[static_cast<std::size_t>(y * (n + 2) + x)] =
          offByOne[static_cast<std::size_t>(sy * (n + 2) + sx)];
    }

  const double goodErr = maxSampleError(good, n, edge, foldProbeFunction);
  const double clampErr = maxSampleError(clamped, n, edge, foldProbeFunction);
  const double swapErr = maxSampleError(offByOne, n, edge, foldProbeFunction);
  std::printf("  n=%d, f = 1 + x + z near edges: correct border %.5f, clamped %.5f, off-by-one mirror %.5f\n",
              n, goodErr, clampErr, swapErr);
  // Measured 0.039 / 0.133 / 0.131: the mapping's creases (normalisation) leave the correct border a
  // first-order error too, but a wrong border is 3x worse.
  EXPECT_LT(goodErr, 0.05);
  EXPECT_GT(clampErr, 0.1);
  EXPECT_GT(swapErr, 0.1);
}

// The octahedral map tiles the plane by mirroring across its edges: (u, -1 - e) is the direction of
// (-u, -1 + e), (1 + e, v) that of (1 - e, -v), and a corner point that of the opposite corner. A border
// texel must therefore hold the interior texel at its wrapped centre, exactly.
glm::vec2 wrapOctahedral(glm::vec2 p) {
  if (p.y < -1.0f) p = {-p.x, -2.0f - p.y};
  if (p.y > 1.0f) p = {-p.x, 2.0f - p.y};
  if (p.x < -1.0f) p = {-2.0f - p.x, -p.y};
  if (p.x > 1.0f) p = {2.0f - p.x, -p.y};
  return p;
}

TEST(Octahedral, BorderTexelsHoldTheirWrappedNeighbour) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int n : {1, 2, 3, 4, 7, 8, 16, 33}) {
    std::vector<float> interior(octInteriorFloats(n, 1));
    for (float& v : interior) v = u(rng);  // distinct values: any wrong source shows
    const std::vector<float> bordered = makeBordered(interior, n, 1);
    for (int by = 0; by < n + 2; ++by)
      for (int bx = 0; bx < n + 2; ++bx) {
        const glm::vec2 centre = (glm::vec2(float(bx - 1), float(by - 1)) + 0.5f) * (2.0f / float(n)) - 1.0f;
        const glm::ivec2 t = octDirectionTexel(octDecode(wrapOctahedral(centre)), n);
        EXPECT_EQ(bordered[static_cast<std::size_t>(by * (n + 2) + bx)],
                  interior[static_cast<std::size_t>(t.y * n + t.x)])
            << "n = " << n << ", bordered texel (" << bx << ", " << by << ")";
      }
  }
}

TEST(Octahedral, FillBorderMatchesSharedConvention) {
  // Corners take the opposite corner; the top edge mirrors x.
  const int n = 4;
  std::vector<float> interior(octInteriorFloats(n, 2));
  for (std::size_t k = 0; k < interior.size(); ++k) interior[k] = float(k);
  const OctahedralMap map = OctahedralMap::fromInterior(interior, n, 2);
  auto at = [&](int x, int y, int c) {
    return map.texels[static_cast<std::size_t>((y * (n + 2) + x) * 2 + c)];
  };
  EXPECT_EQ(at(0, 0, 0), map.texel(n - 1, n - 1)[0]);
  EXPECT_EQ(at(n + 1, n + 1, 1), map.texel(0, 0)[1]);
  EXPECT_EQ(at(1, 0, 0), map.texel(n - 1, 0)[0]);
  EXPECT_EQ(at(0, 1, 1), map.texel(0, n - 1)[1]);
  EXPECT_EQ(at(2, 2, 0), map.texel(1, 1)[0]);
  EXPECT_THROW(makeBordered(interior, n + 1, 2), Error);
  EXPECT_THROW(fillBorder(nullptr, 0, 1), Error);
}

TEST(OctahedralSolidAngle, SumsToFourPi) {
  double worst = 0.0;
  for (int n = 1; n <= 128; ++n) {
    const std::vector<double> omega = octTexelSolidAngles(n);
    double sum = 0.0;
    for (double w : omega) {
      ASSERT_GT(w, 0.0) << "n = " << n;
      sum += w;
    }
    worst = std::max(worst, std::abs(sum - kFourPi));
    EXPECT_NEAR(sum, kFourPi, 1e-4) << "n = " << n;
  }
  std::printf("  max |sum - 4 pi| for n = 1..128: %.3g sr\n", worst);
  EXPECT_LT(worst, 1e-9);  // exact up to double rounding
}

TEST(OctahedralSolidAngle, SymmetricUnderMapSymmetries) {
  for (int n : {5, 16, 33}) {
    const std::vector<double> w = octTexelSolidAngles(n);
    auto at = [&](int i, int j) { return w[static_cast<std::size_t>(j * n + i)]; };
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        EXPECT_NEAR(at(i, j), at(n - 1 - i, j), 1e-14);
        EXPECT_NEAR(at(i, j), at(i, n - 1 - j), 1e-14);
        EXPECT_NEAR(at(i, j), at(j, i), 1e-14);
      }
  }
}

// Integrand of the solid angle in (u, v): for the unnormalised decode p on the octahedron |p|_1 = 1,
// d omega = du dv / |p|^3 (each face is the plane |x|+|y|+|z| = 1 at distance 1/sqrt(3) with area
// element sqrt(3) du dv). With the unit decode d = p / |p|, 1/|p| = |d|_1.
double jacobian(glm::vec2 uv) {
  const glm::dvec3 d = octDecode(uv);
  const double l1 = std::abs(d.x) + std::abs(d.y) + std::abs(d.z);
  return l1 * l1 * l1;
}

TEST(OctahedralSolidAngle, MatchesNumericalJacobianIntegral) {
  const int sub = 24;  // sub x sub midpoint samples per texel
  double worstRel = 0.0;
  for (int n : {1, 2, 3, 5, 8, 13, 16}) {
    const std::vector<double> omega = octTexelSolidAngles(n);
    const double h = 2.0 / n;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        double integral = 0.0;
        for (int b = 0; b < sub; ++b)
          for (int a = 0; a < sub; ++a) {
            const double u = -1.0 + h * (i + (a + 0.5) / sub);
            const double v = -1.0 + h * (j + (b + 0.5) / sub);
            integral += jacobian(glm::vec2(float(u), float(v)));
          }
        integral *= (h / sub) * (h / sub);
        const double exact = omega[static_cast<std::size_t>(j * n + i)];
        worstRel = std::max(worstRel, std::abs(integral - exact) / exact);
      }
  }
  std::printf("  max relative |numerical - exact| texel solid angle (24^2 samples/texel): %.3g\n", worstRel);
  EXPECT_LT(worstRel, 2e-3);
}

TEST(OctahedralSolidAngle, GaussIntegralsAgreeWithExactSolidAngles) {
  // Two independent routes to the same numbers: spherical-triangle areas vs. Gauss quadrature of the
  // Jacobian, and the quadrature integrates x, x^2 etc. to their analytic values over the sphere.
  double worstOmega = 0.0;
  for (int n : {1, 2, 3, 5, 8, 16, 64}) {
    const std::vector<double> omega = octTexelSolidAngles(n);
    double moments[4] = {};
    const std::vector<double> q = octTexelIntegrals(n, 4, [](const glm::dvec3& w, double* out) {
      out[0] = 1.0;
      out[1] = w.y;
      out[2] = w.x * w.x;
      out[3] = w.y * w.y * w.y * w.y;
    });
    for (std::size_t t = 0; t < omega.size(); ++t) {
      worstOmega = std::max(worstOmega, std::abs(q[4 * t] - omega[t]) / omega[t]);
      for (int k = 0; k < 4; ++k) moments[k] += q[4 * t + static_cast<std::size_t>(k)];
    }
    EXPECT_NEAR(moments[0], kFourPi, 1e-12) << "n = " << n;
    EXPECT_NEAR(moments[1], 0.0, 1e-12) << "n = " << n;
    EXPECT_NEAR(moments[2], kFourPi / 3.0, 1e-12) << "n = " << n;
    EXPECT_NEAR(moments[3], kFourPi / 5.0, 1e-12) << "n = " << n;
  }
  std::printf("  max relative |Gauss - exact| texel solid angle: %.3g\n", worstOmega);
  EXPECT_LT(worstOmega, 1e-12);
  EXPECT_THROW(octTexelIntegrals(4, 0, [](const glm::dvec3&, double*) {}), Error);
}

TEST(OctahedralSolidAngle, MinMaxRatio) {
  // The density du dv / |p|^3 ranges from 1 (octahedron vertices) to 3 sqrt(3) (face centres).
  const double bound = 3.0 * std::sqrt(3.0);
  for (int n : {2, 8, 16, 64, 128}) {
    const std::vector<double> w = octTexelSolidAngles(n);
    const auto [lo, hi] = std::minmax_element(w.begin(), w.end());
    const double ratio = *hi / *lo;
    EXPECT_GE(ratio, 1.0);
    EXPECT_LE(ratio, bound) << "n = " << n;
    if (n >= 64) {
      EXPECT_GT(ratio, 4.5) << "n = " << n;
    }
    if (n == 128)
      std::printf("  n=128 texel solid angle max/min: %.4f (limit 3 sqrt 3 = %.4f)\n", ratio, bound);
  }
  // n = 1: one texel is the whole sphere; n = 2: four quadrant texels of pi each.
  EXPECT_NEAR(octTexelSolidAngles(1)[0], kFourPi, 1e-12);
  for (double w : octTexelSolidAngles(2)) EXPECT_NEAR(w, std::numbers::pi, 1e-12);
}

}  // namespace
}  // namespace lfgi
