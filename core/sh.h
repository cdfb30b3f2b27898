// Real spherical harmonics, L1 (4 coefficients) and L2 (9 coefficients) per RGB channel: the baseline
// representation and the always-resident fallback (docs/DESIGN.md §1, §4).
//
// Basis: the standard orthonormal real SH (integral of Y_lm^2 over the sphere = 1) written in the
// Cartesian components (x, y, z) of a unit world direction, as in Ramamoorthi & Hanrahan 2001, "An
// Efficient Representation for Irradiance Environment Maps", eq. 3, and Sloan 2008, "Stupid Spherical
// Harmonics (SH) Tricks". No Condon-Shortley phase: every constant below is positive. The zonal axis is
// world +Z (not the +Y up axis); nothing in the maths depends on which axis is zonal. Order:
//   0: Y00 = 0.282095                      (1 / (2 sqrt(pi)))
//   1: Y1-1 = 0.488603 y   2: Y10 = 0.488603 z   3: Y11 = 0.488603 x      (sqrt(3 / (4 pi)))
//   4: Y2-2 = 1.092548 xy  5: Y2-1 = 1.092548 yz  6: Y20 = 0.315392 (3z^2 - 1)
//   7: Y21 = 1.092548 xz   8: Y22 = 0.546274 (x^2 - y^2)
// This is the l*(l+1)+m index order, so an L1 set is the first 4 entries of an L2 set.
//
// Octahedral maps passed here are interior maps (octahedral.h layout), n x n texels of 3 floats (linear
// RGB radiance, W/(sr m^2) or any consistent unit). A texel's value is taken to hold over the texel's
// exact footprint on the sphere (the reconstruction a nearest-texel lookup sees).
#pragma once

#include <array>
#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace lfgi {

// Coefficients of an RGB function in the first N real SH basis functions (N = 4: L1, N = 9: L2).
template <int N>
struct ShRgb {
  static_assert(N == 4 || N == 9, "only L1 (4) and L2 (9) are provided");
  static constexpr int kCount = N;
  std::array<glm::vec3, N> c{};
};
using ShL1 = ShRgb<4>;
using ShL2 = ShRgb<9>;

// Basis values at a unit direction d (not normalised here; pass a unit vector).
std::array<float, 4> shBasisL1(glm::vec3 d);
std::array<float, 9> shBasisL2(glm::vec3 d);

// Per-texel projection weights of an n x n map: weights[(j * n + i) * 9 + k] = integral over texel
// (i, j) of Y_k(w) dw (octTexelIntegrals, exact to ~1e-12). Band 0 is Y00 times the exact texel solid
// angle; summed over the texels every weight but k = 0 vanishes, so a constant map projects exactly. An
// L1 projection uses k < 4. Computed once per n and cached (thread-safe); n in [1, 4096].
std::shared_ptr<const std::vector<double>> shTexelWeights(int n);

// Projection of an interior octahedral RGB radiance map: c_k = sum_texels L_texel * weight_{texel,k}
// (shTexelWeights). Exact for a map that is constant per texel; for radiance sampled at texel centres
// from a smooth function the error is O(1/n^2). Throws lfgi::Error if rgb.size() != n*n*3, n is outside
// [1, 4096], or (second form) weights.size() != n*n*9.
template <int N>
ShRgb<N> shProject(std::span<const float> rgb, int n);
template <int N>
ShRgb<N> shProject(std::span<const float> rgb, int n, std::span<const double> weights);

// Radiance SH -> irradiance SH by convolution with the clamped cosine: multiplies band l by A_l
// (Ramamoorthi & Hanrahan 2001, eq. 8: A0 = pi, A1 = 2 pi / 3, A2 = pi / 4).
template <int N>
ShRgb<N> shConvolveIrradiance(const ShRgb<N>& radiance);

// Evaluates an SH expansion at unit direction d: sum_k c_k * Y_k(d).
template <int N>
glm::vec3 shEvaluate(const ShRgb<N>& sh, glm::vec3 d);

// Irradiance E(n) (W/m^2 for radiance in W/(sr m^2)) at unit normal n from radiance SH: the convolution
// and the evaluation in one call.
template <int N>
glm::vec3 shIrradiance(const ShRgb<N>& radiance, glm::vec3 normal);

// Ground truth: E(n) = sum_texels L(w) * max(0, n . w) * omega_texel over an interior octahedral RGB map
// (texel-centre directions, exact solid angles). O(n^2) per normal. Same size checks as shProject.
glm::vec3 bruteForceIrradiance(std::span<const float> rgb, int n, glm::vec3 normal);
glm::vec3 bruteForceIrradiance(std::span<const float> rgb, int n, glm::vec3 normal,
                               std::span<const double> solidAngles);

// Analytic zonal coefficient of the clamped cosine max(0, z . w) in band l (l = 0, 1, 2): sqrt(pi)/2,
// sqrt(pi/3), sqrt(5 pi)/8. A_l = sqrt(4 pi / (2l + 1)) times this.
double clampedCosineZonal(int l);

}  // namespace lfgi
