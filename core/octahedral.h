// OctahedralMap helpers: the CPU side of the probe direction parameterisation.
//
// Mapping: Cigolle et al. 2014, "A Survey of Efficient Representations for Independent Unit Vectors",
// +Y (up) as the fold axis, u follows +X, v follows +Z. The math itself lives in
// shaders/shared/octahedral.h (one definition for GLSL and C++); these functions wrap it with int
// texel indices and add what only the CPU needs: border filling, bilinear lookup, exact solid angles.
//
// Layouts (all interleaved, `channels` floats per texel):
//   interior map: n x n texels, texel (i, j) at index (j * n + i) * channels; i runs along u, j along v.
//   bordered map: (n + 2) x (n + 2) texels, interior texel (i, j) at bordered (i + 1, j + 1); the
//                 one-texel ring repeats the octahedrally adjacent interior texel (octBorderSource).
// Limits: 1 <= n <= 4096 everywhere below (the GPU maps use 8..128).
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace lfgi {

// Unit (or any finite non-zero) direction -> point in [-1, 1]^2.
glm::vec2 octEncode(glm::vec3 direction);
// Point in [-1, 1]^2 -> unit direction. Inverse of octEncode.
glm::vec3 octDecode(glm::vec2 p);

// Centre of interior texel (i, j), 0 <= i, j < n -> unit direction.
glm::vec3 octTexelDirection(int i, int j, int n);
// Unit direction -> the interior texel (i, j) containing it (nearest-texel lookup), clamped to [0, n-1].
glm::ivec2 octDirectionTexel(glm::vec3 direction, int n);

// Side length of the bordered map that stores an n x n interior: n + 2.
constexpr int octBorderedSize(int n) {
  return n + 2;
}
// Floats in an interior / bordered map.
constexpr std::size_t octInteriorFloats(int n, int channels) {
  return static_cast<std::size_t>(n) * static_cast<std::size_t>(n) * static_cast<std::size_t>(channels);
}
constexpr std::size_t octBorderedFloats(int n, int channels) {
  return octInteriorFloats(octBorderedSize(n), channels);
}

// Fills the one-texel border ring of a bordered map in place from its interior (octBorderSource: edges
// mirror across the edge midpoint, corners take the opposite corner). data holds octBorderedFloats(n,
// channels) floats. Needed before bilinear sampling so taps across the map edge land on the texels that
// are adjacent on the sphere.
void fillBorder(float* data, int n, int channels);

// Copies an interior map into a new bordered map and fills its border. Throws lfgi::Error if
// interior.size() != octInteriorFloats(n, channels).
std::vector<float> makeBordered(std::span<const float> interior, int n, int channels);

// Bilinear lookup of a bordered map (border filled) in direction `direction` (finite, non-zero).
// Writes `channels` floats to out. The interpolation is in octahedral (u, v) space, so it is exact for
// functions linear in (u, v) within the four taps; across the fold (map edge) the error is first order
// in the texel size because the mapping has a crease there.
void octSampleBilinear(const float* bordered, int n, int channels, glm::vec3 direction, float* out);

// Exact solid angle (steradians) of every interior texel of an n x n map, indexed j * n + i; sums to 4*pi
// up to double rounding. Within each of the 8 octahedron faces the decode before normalisation is affine,
// so a texel's straight edges map to great-circle arcs: the texel square is clipped against u = 0,
// v = 0 and |u| + |v| = 1 (Sutherland-Hodgman), each convex piece is mapped onto the octahedron,
// projected to the sphere and its area summed as a fan of spherical triangles (Van Oosterom & Strackee
// 1983, "The Solid Angle of a Plane Triangle"). Any n >= 1 (odd n too). Cost O(n^2).
std::vector<double> octTexelSolidAngles(int n);

// Integrals of `count` functions over every texel's exact footprint on the sphere:
// result[(j * n + i) * count + k] = integral over texel (i, j) of f_k(w) dw, where f(w, values) writes
// f_0..f_{count-1} at unit direction w. The texel is cut into the same face pieces as above; on each
// piece d omega = du dv / |p|^3 (p the octahedron point, |p|_1 = 1), integrated with an order x order
// Gauss-Legendre rule (Duffy collapse) on triangles at most 0.2 across in (u, v). Smooth f converges
// spectrally: order 8 matches octTexelSolidAngles to ~2e-14 relative and integrates low-degree
// polynomials over the sphere to ~1e-13.
// Cost O(n^2 order^2 count). Throws lfgi::Error for n outside [1, 4096], count < 1 or order < 1.
std::vector<double> octTexelIntegrals(int n, int count,
                                      const std::function<void(const glm::dvec3& w, double* values)>& f,
                                      int order = 8);

// An owned bordered octahedral map: the convenient form for CPU code that samples by direction.
struct OctahedralMap {
  int n = 0;
  int channels = 0;
  std::vector<float> texels;  // bordered layout, octBorderedFloats(n, channels) floats

  // Builds the bordered map from an interior map (see makeBordered).
  static OctahedralMap fromInterior(std::span<const float> interior, int n, int channels);

  // Interior texel (i, j), 0 <= i, j < n: `channels` floats.
  const float* texel(int i, int j) const {
    return texels.data() + (static_cast<std::size_t>(j + 1) * static_cast<std::size_t>(n + 2) +
                            static_cast<std::size_t>(i + 1)) *
                               static_cast<std::size_t>(channels);
  }
  // Bilinear lookup; out.size() must be >= channels.
  void sample(glm::vec3 direction, std::span<float> out) const;
};

}  // namespace lfgi
