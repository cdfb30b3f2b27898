// Real spherical harmonics of any band up to l = 7 (64 coefficients): the SH L7 probe baseline
// (docs/docs/DESIGN.md §4). Same basis conventions as core/sh.h, of which this is the extension:
// orthonormal real SH in world (x, y, z), no Condon-Shortley phase, zonal axis +Z, index l(l+1)+m, so the
// first 9 values equal shBasisL2 exactly (up to float rounding).
//
// Recurrence (Cartesian, no trigonometry, no pole singularity): with z = cos(theta) and
// (x + i y)^m = sin^m(theta) (cos m phi + i sin m phi),
//   Y_l^0  = K_l^0 Q_l^0(z)
//   Y_l^m  = sqrt(2) K_l^m Q_l^m(z) Re (x + i y)^m      m > 0
//   Y_l^-m = sqrt(2) K_l^m Q_l^m(z) Im (x + i y)^m
// where K_l^m = sqrt((2l + 1) / (4 pi) (l - m)! / (l + m)!) and Q_l^m = P_l^m / sin^m(theta) is the
// polynomial part of the associated Legendre function (no Condon-Shortley phase), from the standard
// three-term recurrence in l (Press et al., Numerical Recipes 3rd ed., §6.7):
//   Q_m^m = (2m - 1)!!,  Q_{m+1}^m = (2m + 1) z Q_m^m,
//   Q_l^m = ((2l - 1) z Q_{l-1}^m - (l + m - 1) Q_{l-2}^m) / (l - m).
#pragma once

#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace lfgi {

inline constexpr int kShMaxBand = 7;

// Number of coefficients of bands 0..lmax: (lmax + 1)^2.
constexpr int shCoefficientCount(int lmax) {
  return (lmax + 1) * (lmax + 1);
}

// Writes the (lmax + 1)^2 basis values at unit direction d (not normalised here) to out.
// Throws lfgi::Error if lmax is outside [0, 7] or out is too small.
void shBasis(int lmax, const glm::dvec3& d, std::span<double> out);

// Exact per-texel projection weights of an n x n interior octahedral map for bands 0..lmax:
// weights[(j * n + i) * K + k] = integral over texel (i, j) of Y_k (octTexelIntegrals, Gauss order 8, exact
// to ~1e-13 for these polynomials of degree <= 7). Cached per (lmax, n), thread-safe. Same checks as
// shBasis, plus n in [1, 4096].
std::shared_ptr<const std::vector<double>> shTexelWeightsHigh(int lmax, int n);

// Zonal coefficient of the clamped cosine max(0, z . w) in band l: 2 pi K_l^0 integral_0^1 t P_l(t) dt,
// the integral by 8-point Gauss-Legendre (exact: the integrand has degree <= 8). Zero for odd l > 1.
double clampedCosineZonalHigh(int l);

// Irradiance convolution factor of band l: A_l = sqrt(4 pi / (2l + 1)) * clampedCosineZonalHigh(l)
// (Ramamoorthi & Hanrahan 2001, eq. 8 generalised; A0 = pi, A1 = 2 pi / 3, A2 = pi / 4).
double shIrradianceFactor(int l);

// Band of coefficient index k (l(l+1)+m order).
int shBandOf(int k);

}  // namespace lfgi
