#include "core/sh.h"

#include <cmath>
#include <map>
#include <mutex>
#include <numbers>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi {

namespace {

// Normalisation constants of the real orthonormal basis (see sh.h).
constexpr float kY00 = 0.28209479177387814f;  // 1 / (2 sqrt(pi))
constexpr float kY1 = 0.48860251190291992f;   // sqrt(3 / (4 pi))
constexpr float kY2a = 1.0925484305920792f;   // sqrt(15 / pi) / 2
constexpr float kY20 = 0.31539156525252005f;  // sqrt(5 / pi) / 4
constexpr float kY22 = 0.54627421529603959f;  // sqrt(15 / pi) / 4
constexpr double kY00d = 0.28209479177387814;
constexpr double kY1d = 0.48860251190291992;
constexpr double kY2ad = 1.0925484305920792;
constexpr double kY20d = 0.31539156525252005;
constexpr double kY22d = 0.54627421529603959;

// Band of coefficient k in l*(l+1)+m order.
constexpr int bandOf(int k) {
  return k == 0 ? 0 : (k < 4 ? 1 : 2);
}

// Ramamoorthi & Hanrahan 2001, eq. 8.
constexpr float kA[3] = {std::numbers::pi_v<float>, 2.0f * std::numbers::pi_v<float> / 3.0f,
                         std::numbers::pi_v<float> / 4.0f};

template <int N>
std::array<float, N> basis(glm::vec3 d) {
  if constexpr (N == 4) {
    return shBasisL1(d);
  } else {
    return shBasisL2(d);
  }
}

void checkMap(const char* what, std::span<const float> rgb, int n, std::span<const double> solidAngles) {
  if (n < 1 || n > 4096) fail("{}: octahedral map size n = {} outside [1, 4096]", what, n);
  const std::size_t texels = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
  if (rgb.size() != texels * 3)
    fail("{}: RGB map has {} floats, expected {} for n = {}", what, rgb.size(), texels * 3, n);
  if (solidAngles.size() != texels)
    fail("{}: {} solid angles given, expected {} for n = {}", what, solidAngles.size(), texels, n);
}

}  // namespace

std::array<float, 4> shBasisL1(glm::vec3 d) {
  return {kY00, kY1 * d.y, kY1 * d.z, kY1 * d.x};
}

std::array<float, 9> shBasisL2(glm::vec3 d) {
  return {kY00,
          kY1 * d.y,
          kY1 * d.z,
          kY1 * d.x,
          kY2a * d.x * d.y,
          kY2a * d.y * d.z,
          kY20 * (3.0f * d.z * d.z - 1.0f),
          kY2a * d.x * d.z,
          kY22 * (d.x * d.x - d.y * d.y)};
}

std::shared_ptr<const std::vector<double>> shTexelWeights(int n) {
  if (n < 1 || n > 4096) fail("shTexelWeights: octahedral map size n = {} outside [1, 4096]", n);
  static std::mutex mutex;
  static std::map<int, std::shared_ptr<const std::vector<double>>> cache;
  {
    const std::lock_guard lock(mutex);
    if (auto it = cache.find(n); it != cache.end()) return it->second;
  }
  // Computed outside the lock: two threads may both compute the same n; the first insert wins.
  auto weights =
      std::make_shared<const std::vector<double>>(octTexelIntegrals(n, 9, [](const glm::dvec3& w, double* y) {
        // shBasisL2 in double: the float basis would cap the weights at ~1e-7 relative.
        y[0] = kY00d;
        y[1] = kY1d * w.y;
        y[2] = kY1d * w.z;
        y[3] = kY1d * w.x;
        y[4] = kY2ad * w.x * w.y;
        y[5] = kY2ad * w.y * w.z;
        y[6] = kY20d * (3.0 * w.z * w.z - 1.0);
        y[7] = kY2ad * w.x * w.z;
        y[8] = kY22d * (w.x * w.x - w.y * w.y);
      }));
  const std::lock_guard lock(mutex);
  return cache.emplace(n, std::move(weights)).first->second;
}

template <int N>
ShRgb<N> shProject(std::span<const float> rgb, int n, std::span<const double> weights) {
  if (n < 1 || n > 4096) fail("shProject: octahedral map size n = {} outside [1, 4096]", n);
  const std::size_t texels = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
  if (rgb.size() != texels * 3)
    fail("shProject: RGB map has {} floats, expected {} for n = {}", rgb.size(), texels * 3, n);
  if (weights.size() != texels * 9)
    fail("shProject: {} weights given, expected {} (shTexelWeights) for n = {}", weights.size(), texels * 9,
         n);
  // Accumulate in double: a 128^2 map sums 16k terms of very different size (sun vs. sky).
  std::array<glm::dvec3, N> acc{};
  for (std::size_t t = 0; t < texels; ++t) {
    const glm::dvec3 radiance(rgb[3 * t], rgb[3 * t + 1], rgb[3 * t + 2]);
    for (int k = 0; k < N; ++k) acc[k] += radiance * weights[9 * t + static_cast<std::size_t>(k)];
  }
  ShRgb<N> out;
  for (int k = 0; k < N; ++k) out.c[k] = glm::vec3(acc[k]);
  return out;
}

template <int N>
ShRgb<N> shProject(std::span<const float> rgb, int n) {
  const std::shared_ptr<const std::vector<double>> weights = shTexelWeights(n);
  return shProject<N>(rgb, n, *weights);
}

template <int N>
ShRgb<N> shConvolveIrradiance(const ShRgb<N>& radiance) {
  ShRgb<N> out;
  for (int k = 0; k < N; ++k) out.c[k] = radiance.c[k] * kA[bandOf(k)];
  return out;
}

template <int N>
glm::vec3 shEvaluate(const ShRgb<N>& sh, glm::vec3 d) {
  const std::array<float, N> y = basis<N>(d);
  glm::vec3 sum(0.0f);
  for (int k = 0; k < N; ++k) sum += sh.c[k] * y[k];
  return sum;
}

template <int N>
glm::vec3 shIrradiance(const ShRgb<N>& radiance, glm::vec3 normal) {
  return shEvaluate(shConvolveIrradiance(radiance), normal);
}

glm::vec3 bruteForceIrradiance(std::span<const float> rgb, int n, glm::vec3 normal,
                               std::span<const double> solidAngles) {
  checkMap("bruteForceIrradiance", rgb, n, solidAngles);
  glm::dvec3 sum(0.0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double cosine = glm::dot(normal, octTexelDirection(i, j, n));
      if (cosine <= 0.0) continue;
      const std::size_t t =
          static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i);
      sum += glm::dvec3(rgb[3 * t], rgb[3 * t + 1], rgb[3 * t + 2]) * (cosine * solidAngles[t]);
    }
  }
  return glm::vec3(sum);
}

glm::vec3 bruteForceIrradiance(std::span<const float> rgb, int n, glm::vec3 normal) {
  if (n < 1 || n > 4096) fail("bruteForceIrradiance: octahedral map size n = {} outside [1, 4096]", n);
  const std::vector<double> omega = octTexelSolidAngles(n);
  return bruteForceIrradiance(rgb, n, normal, omega);
}

double clampedCosineZonal(int l) {
  const double pi = std::numbers::pi;
  switch (l) {
    case 0:
      return std::sqrt(pi) / 2.0;
    case 1:
      return std::sqrt(pi / 3.0);
    case 2:
      return std::sqrt(5.0 * pi) / 8.0;
    default:
      fail("clampedCosineZonal: band l = {} not provided (0, 1, 2 only)", l);
  }
}

template ShRgb<4> shProject<4>(std::span<const float>, int);
template ShRgb<9> shProject<9>(std::span<const float>, int);
template ShRgb<4> shProject<4>(std::span<const float>, int, std::span<const double>);
template ShRgb<9> shProject<9>(std::span<const float>, int, std::span<const double>);
template ShRgb<4> shConvolveIrradiance<4>(const ShRgb<4>&);
template ShRgb<9> shConvolveIrradiance<9>(const ShRgb<9>&);
template glm::vec3 shEvaluate<4>(const ShRgb<4>&, glm::vec3);
template glm::vec3 shEvaluate<9>(const ShRgb<9>&, glm::vec3);
template glm::vec3 shIrradiance<4>(const ShRgb<4>&, glm::vec3);
template glm::vec3 shIrradiance<9>(const ShRgb<9>&, glm::vec3);

}  // namespace lfgi
