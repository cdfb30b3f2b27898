// Octahedral direction mapping shared by GLSL and C++.
// Cigolle et al. 2014, "A Survey of Efficient Representations for Independent Unit Vectors", with +Y
// (up) as the fold axis: the upper hemisphere (sky) fills the central diamond |u|+|v| <= 1 and the lower
// hemisphere folds into the four corners. u follows +X, v follows +Z.
//
// Texel convention for an N x N map: texel (i, j) covers [i, i+1) x [j, j+1) in texel units; its centre
// is at ((i + 0.5) / N) * 2 - 1 in [-1, 1]^2. A bordered map stores (N + 2)^2 texels: interior texel
// (i, j) sits at (i + 1, j + 1) and the one-texel border repeats the octahedrally adjacent interior texel
// (edge texels mirror across the edge midpoint, corners take the opposite corner), so bilinear taps
// across the map edge stay continuous on the sphere.
#ifndef LFGI_SHARED_OCTAHEDRAL_H
#define LFGI_SHARED_OCTAHEDRAL_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

LFGI_INLINE vec2 octSignNotZero(vec2 v) {
  return vec2(v.x >= 0.0f ? 1.0f : -1.0f, v.y >= 0.0f ? 1.0f : -1.0f);
}

// Unit direction -> point in [-1, 1]^2. Precondition: d is finite and non-zero (need not be unit).
LFGI_INLINE vec2 octEncode(vec3 d) {
  float l1 = abs(d.x) + abs(d.y) + abs(d.z);
  vec2 p = vec2(d.x, d.z) * (1.0f / l1);
  if (d.y < 0.0f) {
    p = (vec2(1.0f) - abs(vec2(p.y, p.x))) * octSignNotZero(p);
  }
  return p;
}

// Point in [-1, 1]^2 -> the direction on the octahedron |x| + |y| + |z| = 1 (not unit length: between
// 1 / sqrt(3) and 1), for callers that only need it up to scale.
LFGI_INLINE vec3 octDecodeL1(vec2 p) {
  vec3 d = vec3(p.x, 1.0f - abs(p.x) - abs(p.y), p.y);
  if (d.y < 0.0f) {
    vec2 q = (vec2(1.0f) - abs(vec2(p.y, p.x))) * octSignNotZero(p);
    d.x = q.x;
    d.z = q.y;
  }
  return d;
}

// Point in [-1, 1]^2 -> unit direction. Inverse of octEncode.
LFGI_INLINE vec3 octDecode(vec2 p) {
  return normalize(octDecodeL1(p));
}

// Centre of interior texel (i, j) of an N x N map -> [-1, 1]^2.
LFGI_INLINE vec2 octTexelCentre(uvec2 texel, uint n) {
  return (vec2(float(texel.x), float(texel.y)) + vec2(0.5f)) * (2.0f / float(n)) - vec2(1.0f);
}

// Centre of interior texel (i, j) of an N x N map -> unit direction.
LFGI_INLINE vec3 octTexelDirection(uvec2 texel, uint n) {
  return octDecode(octTexelCentre(texel, n));
}

// Unit direction -> interior texel of an N x N map that contains it (nearest-texel lookup).
LFGI_INLINE uvec2 octDirectionTexel(vec3 d, uint n) {
  vec2 t = (octEncode(d) * 0.5f + vec2(0.5f)) * float(n);
  ivec2 i = clamp(ivec2(int(floor(t.x)), int(floor(t.y))), ivec2(0), ivec2(int(n) - 1));
  return uvec2(uint(i.x), uint(i.y));
}

// Bordered texel coordinate b in [0, N+1]^2 -> the interior texel (in [0, N-1]^2) whose value it holds.
// Interior texels map to themselves (b - 1).
LFGI_INLINE uvec2 octBorderSource(uvec2 b, uint n) {
  int x = int(b.x) - 1;
  int y = int(b.y) - 1;
  int last = int(n) - 1;
  bool outX = x < 0 || x > last;
  bool outY = y < 0 || y > last;
  if (outX && outY) {  // corner: the diagonally opposite corner
    x = x < 0 ? last : 0;
    y = y < 0 ? last : 0;
  } else if (outY) {  // top/bottom edge: mirror x, clamp y
    x = last - x;
    y = y < 0 ? 0 : last;
  } else if (outX) {  // left/right edge: mirror y, clamp x
    y = last - y;
    x = x < 0 ? 0 : last;
  }
  return uvec2(uint(x), uint(y));
}

// Texel index t of an N x N map, possibly outside it (|t - [0, N)| < N), -> the interior texel it denotes
// across the fold: the map mirrors across each edge midpoint (as octBorderSource, generalised to several
// texels); used by splat windows that straddle the map's border.
LFGI_INLINE ivec2 octWrap(ivec2 t, int n) {
  if (t.x < 0) {
    t = ivec2(-1 - t.x, n - 1 - t.y);
  } else if (t.x >= n) {
    t = ivec2(2 * n - 1 - t.x, n - 1 - t.y);
  }
  if (t.y < 0) {
    t = ivec2(n - 1 - t.x, -1 - t.y);
  } else if (t.y >= n) {
    t = ivec2(n - 1 - t.x, 2 * n - 1 - t.y);
  }
  return clamp(t, ivec2(0), ivec2(n - 1));
}

LFGI_SHARED_END

#endif  // LFGI_SHARED_OCTAHEDRAL_H
