#include "core/sh_high_order.h"

#include <cmath>
#include <map>
#include <mutex>
#include <numbers>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi {

namespace {

void checkBand(const char* what, int lmax) {
  if (lmax < 0 || lmax > kShMaxBand) fail("{}: SH band lmax = {} outside [0, {}]", what, lmax, kShMaxBand);
}

double factorial(int k) {
  double f = 1.0;
  for (int i = 2; i <= k; ++i) f *= double(i);
  return f;
}

// K_l^m of the header, times sqrt(2) for m != 0, indexed [l][m].
struct Normalisation {
  double k[kShMaxBand + 1][kShMaxBand + 1] = {};
  Normalisation() {
    for (int l = 0; l <= kShMaxBand; ++l)
      for (int m = 0; m <= l; ++m) {
        const double v =
            std::sqrt((2.0 * l + 1.0) / (4.0 * std::numbers::pi) * factorial(l - m) / factorial(l + m));
        k[l][m] = m == 0 ? v : std::sqrt(2.0) * v;
      }
  }
};
const Normalisation kNorm;

}  // namespace

int shBandOf(int k) {
  int l = 0;
  while ((l + 1) * (l + 1) <= k) ++l;
  return l;
}

void shBasis(int lmax, const glm::dvec3& d, std::span<double> out) {
  checkBand("shBasis", lmax);
  if (out.size() < size_t(shCoefficientCount(lmax)))
    fail("shBasis: output holds {} values, lmax = {} needs {}", out.size(), lmax, shCoefficientCount(lmax));
  const double x = d.x, y = d.y, z = d.z;
  double re = 1.0, im = 0.0;  // (x + i y)^m
  double qmm = 1.0;           // Q_m^m = (2m - 1)!!
  for (int m = 0; m <= lmax; ++m) {
    if (m > 0) {
      const double r = re * x - im * y;
      im = re * y + im * x;
      re = r;
      qmm *= double(2 * m - 1);
    }
    double q2 = 0.0, q1 = qmm;  // Q_{l-2}^m, Q_{l-1}^m walking up in l
    for (int l = m; l <= lmax; ++l) {
      double q;
      if (l == m) {
        q = qmm;
      } else if (l == m + 1) {
        q = double(2 * m + 1) * z * qmm;
      } else {
        q = (double(2 * l - 1) * z * q1 - double(l + m - 1) * q2) / double(l - m);
      }
      if (l > m) {
        q2 = q1;
        q1 = q;
      }
      const double base = kNorm.k[l][m] * q;
      const int centre = l * (l + 1);
      if (m == 0) {
        out[size_t(centre)] = base;
      } else {
        out[size_t(centre + m)] = base * re;
        out[size_t(centre - m)] = base * im;
      }
    }
  }
}

std::shared_ptr<const std::vector<double>> shTexelWeightsHigh(int lmax, int n) {
  checkBand("shTexelWeightsHigh", lmax);
  if (n < 1 || n > 4096) fail("shTexelWeightsHigh: octahedral map size n = {} outside [1, 4096]", n);
  static std::mutex mutex;
  static std::map<std::pair<int, int>, std::shared_ptr<const std::vector<double>>> cache;
  const std::pair key(lmax, n);
  {
    const std::lock_guard lock(mutex);
    if (auto it = cache.find(key); it != cache.end()) return it->second;
  }
  const int count = shCoefficientCount(lmax);
  auto weights = std::make_shared<const std::vector<double>>(octTexelIntegrals(
      n, count,
      [&](const glm::dvec3& w, double* y) { shBasis(lmax, w, std::span<double>(y, size_t(count))); }));
  const std::lock_guard lock(mutex);
  return cache.emplace(key, std::move(weights)).first->second;
}

double clampedCosineZonalHigh(int l) {
  checkBand("clampedCosineZonalHigh", l);
  if (l > 1 && l % 2 == 1)
    return 0.0;  // odd l: t P_l(t) is even, so the half-range integral is half of the full one, 0 by
                 // orthogonality to P_1
  // 8-point Gauss-Legendre on [-1, 1], mapped to [0, 1].
  static constexpr double kX[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                   -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                                   0.7966664774136267,  0.9602898564975363};
  static constexpr double kW[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                   0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                   0.2223810344533745, 0.1012285362903763};
  double sum = 0.0;
  for (int i = 0; i < 8; ++i) {
    const double t = 0.5 * (kX[i] + 1.0);
    // Legendre P_l(t) by Bonnet's recurrence.
    double p0 = 1.0, p1 = t, p = l == 0 ? 1.0 : t;
    for (int k = 2; k <= l; ++k) {
      p = (double(2 * k - 1) * t * p1 - double(k - 1) * p0) / double(k);
      p0 = p1;
      p1 = p;
    }
    sum += 0.5 * kW[i] * t * p;
  }
  return 2.0 * std::numbers::pi * kNorm.k[l][0] * sum;
}

double shIrradianceFactor(int l) {
  checkBand("shIrradianceFactor", l);
  return std::sqrt(4.0 * std::numbers::pi / (2.0 * l + 1.0)) * clampedCosineZonalHigh(l);
}

}  // namespace lfgi
