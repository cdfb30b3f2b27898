#include "core/octahedral.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "core/error.h"
#include "shared/octahedral.h"

namespace lfgi {

namespace {

constexpr int kMaxN = 4096;

void checkSize(const char* what, int n, int channels) {
  if (n < 1 || n > kMaxN) fail("{}: octahedral map size n = {} outside [1, {}]", what, n, kMaxN);
  if (channels < 1) fail("{}: channel count {} must be >= 1", what, channels);
}

std::size_t borderedIndex(int x, int y, int n) {
  return static_cast<std::size_t>(y) * static_cast<std::size_t>(n + 2) + static_cast<std::size_t>(x);
}

// A convex polygon in the (u, v) square; at most 4 + 3 vertices after three clips of a quad.
struct Polygon {
  glm::dvec2 v[8];
  int count = 0;
};

// Sutherland-Hodgman against the half-plane a*u + b*v <= c.
Polygon clip(const Polygon& in, double a, double b, double c) {
  Polygon out;
  for (int k = 0; k < in.count; ++k) {
    const glm::dvec2 p = in.v[k];
    const glm::dvec2 q = in.v[(k + 1) % in.count];
    const double dp = a * p.x + b * p.y - c;
    const double dq = a * q.x + b * q.y - c;
    if (dp <= 0.0) out.v[out.count++] = p;
    if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) {
      const double t = dp / (dp - dq);
      out.v[out.count++] = p + t * (q - p);
    }
  }
  return out;
}

// The octahedron point (before normalisation) of (u, v) inside the face with quadrant signs (su, sv);
// `lower` selects the folded corner triangle. Using the face's signs rather than sign(u) keeps the map
// affine on the face, including on its boundary.
glm::dvec3 facePoint(glm::dvec2 p, double su, double sv, bool lower) {
  const double au = su * p.x;
  const double av = sv * p.y;
  const double y = 1.0 - au - av;
  if (!lower) return {p.x, y, p.y};
  return {su * (1.0 - av), y, sv * (1.0 - au)};
}

// Solid angle of the spherical triangle with unit vertices a, b, c (Van Oosterom & Strackee 1983):
// tan(omega / 2) = |a . (b x c)| / (1 + a.b + b.c + c.a). atan2 keeps it accurate for tiny triangles.
double triangleSolidAngle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  const double num = std::abs(glm::dot(a, glm::cross(b, c)));
  const double den = 1.0 + glm::dot(a, b) + glm::dot(b, c) + glm::dot(c, a);
  return 2.0 * std::atan2(num, den);
}

}  // namespace

glm::vec2 octEncode(glm::vec3 direction) {
  return shared::octEncode(direction);
}

glm::vec3 octDecode(glm::vec2 p) {
  return shared::octDecode(p);
}

glm::vec3 octTexelDirection(int i, int j, int n) {
  return shared::octTexelDirection(glm::uvec2(static_cast<unsigned>(i), static_cast<unsigned>(j)),
                                   static_cast<unsigned>(n));
}

glm::ivec2 octDirectionTexel(glm::vec3 direction, int n) {
  return glm::ivec2(shared::octDirectionTexel(direction, static_cast<unsigned>(n)));
}

void fillBorder(float* data, int n, int channels) {
  checkSize("fillBorder", n, channels);
  const int side = n + 2;
  const std::size_t texelBytes = static_cast<std::size_t>(channels) * sizeof(float);
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      if (x > 0 && x <= n && y > 0 && y <= n) continue;
      const glm::uvec2 src = shared::octBorderSource(glm::uvec2(unsigned(x), unsigned(y)), unsigned(n));
      std::memcpy(
          data + borderedIndex(x, y, n) * static_cast<std::size_t>(channels),
          data + borderedIndex(int(src.x) + 1, int(src.y) + 1, n) * static_cast<std::size_t>(channels),
          texelBytes);
    }
  }
}

std::vector<float> makeBordered(std::span<const float> interior, int n, int channels) {
  checkSize("makeBordered", n, channels);
  if (interior.size() != octInteriorFloats(n, channels))
    fail("makeBordered: interior map has {} floats, expected {} for n = {} and {} channels", interior.size(),
         octInteriorFloats(n, channels), n, channels);
  std::vector<float> bordered(octBorderedFloats(n, channels));
  const std::size_t rowFloats = static_cast<std::size_t>(n) * static_cast<std::size_t>(channels);
  for (int j = 0; j < n; ++j) {
    std::memcpy(bordered.data() + borderedIndex(1, j + 1, n) * static_cast<std::size_t>(channels),
                interior.data() + static_cast<std::size_t>(j) * rowFloats, rowFloats * sizeof(float));
  }
  fillBorder(bordered.data(), n, channels);
  return bordered;
}

void octSampleBilinear(const float* bordered, int n, int channels, glm::vec3 direction, float* out) {
  // Continuous bordered texel coordinate whose integer + 0.5 points are texel centres. The encode lies
  // in [-1, 1]^2, so the taps stay within [0, n + 1]; the clamp only guards rounding.
  const glm::vec2 p = shared::octEncode(direction);
  const glm::vec2 t = (p * 0.5f + 0.5f) * float(n) + 0.5f;
  const glm::vec2 base = glm::floor(t);
  const glm::vec2 f = t - base;
  const int x0 = std::clamp(int(base.x), 0, n);
  const int y0 = std::clamp(int(base.y), 0, n);
  const float* t00 = bordered + borderedIndex(x0, y0, n) * static_cast<std::size_t>(channels);
  const float* t10 = bordered + borderedIndex(x0 + 1, y0, n) * static_cast<std::size_t>(channels);
  const float* t01 = bordered + borderedIndex(x0, y0 + 1, n) * static_cast<std::size_t>(channels);
  const float* t11 = bordered + borderedIndex(x0 + 1, y0 + 1, n) * static_cast<std::size_t>(channels);
  const float w00 = (1.0f - f.x) * (1.0f - f.y);
  const float w10 = f.x * (1.0f - f.y);
  const float w01 = (1.0f - f.x) * f.y;
  const float w11 = f.x * f.y;
  for (int c = 0; c < channels; ++c) out[c] = w00 * t00[c] + w10 * t10[c] + w01 * t01[c] + w11 * t11[c];
}

namespace {

// Calls piece(polygon, su, sv, lower) for each non-degenerate intersection of texel (i, j) with one of
// the 8 octahedron faces (quadrant su * u >= 0, sv * v >= 0; lower: |u| + |v| >= 1).
template <typename Piece>
void forEachTexelPiece(int i, int j, int n, Piece&& piece) {
  const double h = 2.0 / n;
  const double u0 = -1.0 + i * h, u1 = -1.0 + (i + 1) * h;
  const double v0 = -1.0 + j * h, v1 = -1.0 + (j + 1) * h;
  Polygon square;
  square.count = 4;
  square.v[0] = {u0, v0};
  square.v[1] = {u1, v0};
  square.v[2] = {u1, v1};
  square.v[3] = {u0, v1};
  for (int face = 0; face < 8; ++face) {
    const double su = (face & 1) ? -1.0 : 1.0;
    const double sv = (face & 2) ? -1.0 : 1.0;
    const bool lower = (face & 4) != 0;
    if ((su > 0 && u1 <= 0.0) || (su < 0 && u0 >= 0.0) || (sv > 0 && v1 <= 0.0) || (sv < 0 && v0 >= 0.0))
      continue;
    Polygon p = clip(square, -su, 0.0, 0.0);  // su * u >= 0
    p = clip(p, 0.0, -sv, 0.0);               // sv * v >= 0
    p = lower ? clip(p, -su, -sv, -1.0)       // |u| + |v| >= 1
              : clip(p, su, sv, 1.0);         // |u| + |v| <= 1
    if (p.count >= 3) piece(p, su, sv, lower);
  }
}

// Gauss-Legendre nodes and weights on [0, 1] (Newton on the Legendre recurrence).
void gaussLegendre01(int order, std::vector<double>& nodes, std::vector<double>& weights) {
  nodes.assign(static_cast<std::size_t>(order), 0.0);
  weights.assign(static_cast<std::size_t>(order), 0.0);
  for (int k = 0; k < order; ++k) {
    double x = std::cos(std::numbers::pi * (k + 0.75) / (order + 0.5));
    double dp = 1.0;
    for (int iter = 0; iter < 100; ++iter) {
      double p0 = 1.0, p1 = x;
      for (int m = 2; m <= order; ++m) {
        const double p2 = ((2.0 * m - 1.0) * x * p1 - (m - 1.0) * p0) / m;
        p0 = p1;
        p1 = p2;
      }
      dp = order * (x * p1 - p0) / (x * x - 1.0);
      const double dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    nodes[static_cast<std::size_t>(k)] = 0.5 * (1.0 - x);
    weights[static_cast<std::size_t>(k)] = 1.0 / ((1.0 - x * x) * dp * dp);  // 2 / (...) scaled by 1/2
  }
}

}  // namespace

std::vector<double> octTexelSolidAngles(int n) {
  checkSize("octTexelSolidAngles", n, 1);
  std::vector<double> omega(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), 0.0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      double sum = 0.0;
      forEachTexelPiece(i, j, n, [&](const Polygon& piece, double su, double sv, bool lower) {
        glm::dvec3 s[8];
        for (int k = 0; k < piece.count; ++k) s[k] = glm::normalize(facePoint(piece.v[k], su, sv, lower));
        for (int k = 1; k + 1 < piece.count; ++k) sum += triangleSolidAngle(s[0], s[k], s[k + 1]);
      });
      omega[static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i)] = sum;
    }
  }
  return omega;
}

std::vector<double> octTexelIntegrals(int n, int count,
                                      const std::function<void(const glm::dvec3& w, double* values)>& f,
                                      int order) {
  checkSize("octTexelIntegrals", n, count);
  if (order < 1 || order > 64) fail("octTexelIntegrals: quadrature order {} outside [1, 64]", order);
  std::vector<double> nodes, weights;
  gaussLegendre01(order, nodes, weights);
  const std::size_t stride = static_cast<std::size_t>(count);
  std::vector<double> result(static_cast<std::size_t>(n) * static_cast<std::size_t>(n) * stride, 0.0);
  std::vector<double> values(stride);
  constexpr double kMaxEdge = 0.2;
  // Duffy collapse of triangle (a, b, c): x(s, t) = a + s (b - a) + s t (c - b), dx = s |det| ds dt, with
  // the Gauss rule in s and t; the integrand picks up d omega = du dv / |p|^3.
  auto integrateTriangle = [&](glm::dvec2 a, glm::dvec2 b, glm::dvec2 c, double su, double sv, bool lower,
                               double* out) {
    const glm::dvec2 ab = b - a;
    const glm::dvec2 bc = c - b;
    const double det = std::abs(ab.x * bc.y - ab.y * bc.x);
    if (det == 0.0) return;
    for (int qs = 0; qs < order; ++qs) {
      const double s = nodes[static_cast<std::size_t>(qs)];
      for (int qt = 0; qt < order; ++qt) {
        const double t = nodes[static_cast<std::size_t>(qt)];
        const glm::dvec3 p = facePoint(a + s * ab + (s * t) * bc, su, sv, lower);
        const double len = glm::length(p);
        const double w = weights[static_cast<std::size_t>(qs)] * weights[static_cast<std::size_t>(qt)] * s *
                         det / (len * len * len);
        f(p / len, values.data());
        for (std::size_t k = 0; k < stride; ++k) out[k] += w * values[k];
      }
    }
  };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      double* out =
          result.data() +
          (static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i)) * stride;
      forEachTexelPiece(i, j, n, [&](const Polygon& piece, double su, double sv, bool lower) {
        for (int k = 1; k + 1 < piece.count; ++k) {
          // Split the fan triangle (a, b, c) into m^2 similar ones so that each is at most kMaxEdge
          // across: 1/|p|^3 varies by up to 5x over a whole face, and a fixed-order rule on small
          // triangles converges far faster than on large ones.
          const glm::dvec2 a = piece.v[0], b = piece.v[k], c = piece.v[k + 1];
          const double longest = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
          const int m = std::max(1, static_cast<int>(std::ceil(longest / kMaxEdge)));
          const glm::dvec2 eb = (b - a) / double(m), ec = (c - a) / double(m);
          for (int r = 0; r < m; ++r) {
            for (int q = 0; q + r < m; ++q) {
              const glm::dvec2 o = a + double(q) * eb + double(r) * ec;
              integrateTriangle(o, o + eb, o + ec, su, sv, lower, out);
              if (q + r + 1 < m) integrateTriangle(o + eb, o + eb + ec, o + ec, su, sv, lower, out);
            }
          }
        }
      });
    }
  }
  return result;
}

OctahedralMap OctahedralMap::fromInterior(std::span<const float> interior, int n, int channels) {
  OctahedralMap map;
  map.texels = makeBordered(interior, n, channels);
  map.n = n;
  map.channels = channels;
  return map;
}

void OctahedralMap::sample(glm::vec3 direction, std::span<float> out) const {
  if (out.size() < static_cast<std::size_t>(channels))
    fail("OctahedralMap::sample: output has {} floats, map has {} channels", out.size(), channels);
  octSampleBilinear(texels.data(), n, channels, direction, out.data());
}

}  // namespace lfgi
