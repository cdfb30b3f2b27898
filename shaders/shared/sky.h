// Sky, sun and moon radiance shared by GLSL and C++: the CPU (worlds/sky.h, makeSky) precomputes every
// per-state quantity into SkyParams; the per-direction evaluation below is the one implementation that
// both the CPU reference and the GPU relight pass run.
//
// Conventions: +Y up, +X east, +Z south (-Z north); right-handed. Radiance is linear Rec.709 RGB in
// kcd/m^2 of luminance: the Rec.709 luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of a value is its
// photometric luminance in kilocandela per m^2, so irradiance (radiance x solid angle x cos) is in
// kilolux. The clear midday sky is ~2..15, the sun disc ~1.4e6 (above FP16's 65504: never store the
// disc itself in FP16), the night floor 2e-7.
//
// Model (see worlds/sky.h for the full contract):
//   clear part     Preetham, Shirley & Smits 1999, "A Practical Analytic Model for Daylight": Perez et al.
//                  1993 distribution F(theta, gamma) = (1 + A e^(B / cos theta)) (1 + C e^(D gamma)
//                  + E cos^2 gamma) for Y, x and y; value = zenith value * F(theta, gamma) / F(0, theta_s).
//                  Evaluated once for the sun and once for the moon (the moonlit sky is the same model
//                  scaled by the moon/sun irradiance ratio); xyY -> XYZ -> linear Rec.709, negative
//                  (out-of-gamut) components clamped to 0.
//   overcast part  CIE standard overcast sky (Moon & Spencer 1942): L(theta) = Lz (1 + 2 cos theta) / 3,
//                  D65 white (rgb = L).
//   floor          constant night-sky radiance (airglow + starlight), keeps the sky strictly positive.
// Below the horizon (dir.y < 0) every term returns its horizon value at the same azimuth (the direction
// with y clamped to 0); straight down uses the +X horizon. No ground bounce is modelled: geometry is the
// ground.
#ifndef LFGI_SHARED_SKY_H
#define LFGI_SHARED_SKY_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

#ifdef __cplusplus
using glm::acos;
using glm::exp;
#endif

// Everything the per-direction evaluation needs, precomputed by makeSky. std430: vec4 members only.
struct SkyParams {
  vec4 perezY;          // Perez A, B, C, D for luminance Y at the effective turbidity (Preetham app. A.2)
  vec4 perezX;          // Perez A, B, C, D for chromaticity x
  vec4 perezCy;         // Perez A, B, C, D for chromaticity y
  vec4 perezE;          // Perez E for (Y, x, y); w = 0
  vec4 sunSkyDir;       // xyz: sun direction used for gamma (elevation clamped to >= 0); w = 0
  vec4 sunSkyZenith;    // (weight * Yz / F_Y(0, ts), xz / F_x(0, ts), yz / F_y(0, ts), 0); Yz in kcd/m^2;
                        // x = 0: term off
  vec4 moonSkyDir;      // as sunSkyDir, for the moon
  vec4 moonSkyZenith;   // as sunSkyZenith, weight includes the moon/sun irradiance ratio
  vec4 overcastZenith;  // rgb: CIE overcast zenith radiance (sum over sun and moon); w = 0
  vec4 floorRadiance;   // rgb: night-sky floor radiance (> 0); w = 0
  vec4 sunDirection;    // xyz: unit direction towards the sun; w: cos(angular radius)
  vec4 sunRadiance;     // rgb: disc radiance after atmosphere and clouds; w: disc solid angle (sr)
  vec4 sunIrradiance;   // rgb: irradiance on a surface facing the sun = radiance * solid angle *
                        // visible fraction (kilolux); w: visible fraction of the disc above the horizon
  vec4 moonDirection;   // as sunDirection, for the moon
  vec4 moonRadiance;    // as sunRadiance, for the moon
  vec4 moonIrradiance;  // as sunIrradiance, for the moon
};
LFGI_CHECK_SIZE(SkyParams, 256)
LFGI_CHECK_OFFSET(SkyParams, overcastZenith, 128)
LFGI_CHECK_OFFSET(SkyParams, sunDirection, 160)
LFGI_CHECK_OFFSET(SkyParams, moonIrradiance, 240)

// Perez et al. 1993 all-weather distribution with coefficients (A, B, C, D) in abcd and E in e.
// Preconditions: cosTheta > 0; B < 0 (true for Y, x, y over turbidity [1.7, 10]) so nothing overflows.
LFGI_INLINE float skyPerez(vec4 abcd, float e, float cosTheta, float gamma, float cosGamma) {
  return (1.0f + abcd.x * exp(abcd.y / cosTheta)) *
         (1.0f + abcd.z * exp(abcd.w * gamma) + e * cosGamma * cosGamma);
}

// CIE XYZ -> linear Rec.709 / sRGB primaries, D65 white (IEC 61966-2-1 matrix, Lindbloom's digits).
LFGI_INLINE vec3 skyXyzToRec709(vec3 c) {
  return vec3(3.2404542f * c.x - 1.5371385f * c.y - 0.4985314f * c.z,
              -0.9692660f * c.x + 1.8760108f * c.y + 0.0415560f * c.z,
              0.0556434f * c.x - 0.2040259f * c.y + 1.0572252f * c.z);
}

// Rec.709 luminance of linear RGB (the Y row of the inverse of skyXyzToRec709).
LFGI_INLINE float skyLuminance(vec3 rgb) {
  return 0.2126729f * rgb.x + 0.7151522f * rgb.y + 0.0721750f * rgb.z;
}

// Direction actually evaluated by the sky: dir with y clamped to >= 0, renormalised (the horizon value
// below the horizon); (1, 0, 0) when dir is (nearly) straight down. dir need not be unit length.
LFGI_INLINE vec3 skyEvalDirection(vec3 dir) {
  vec3 v = vec3(dir.x, max(dir.y, 0.0f), dir.z);
  float l = length(v);
  return l > 1e-6f * length(dir) ? v * (1.0f / l) : vec3(1.0f, 0.0f, 0.0f);
}

// The Perez gradation factors (1 + A e^(B / cos theta)) for (Y, x, y); shared by the sun and moon terms.
// cos(theta) is floored at 1e-3: e^(B / 1e-3) underflows to 0 for every B < -0.09, i.e. exactly the
// horizon value, and no division by zero reaches the GPU.
LFGI_INLINE vec3 skyGradation(SkyParams p, float cosTheta) {
  float c = max(cosTheta, 0.001f);
  return vec3(1.0f + p.perezY.x * exp(p.perezY.y / c), 1.0f + p.perezX.x * exp(p.perezX.y / c),
              1.0f + p.perezCy.x * exp(p.perezCy.y / c));
}

// One Preetham term (sun-lit or moon-lit) in linear Rec.709, >= 0. v: unit, v.y >= 0; gradation from
// skyGradation(p, v.y).
LFGI_INLINE vec3 skyPreethamTerm(SkyParams p, vec3 v, vec3 gradation, vec4 sourceDir, vec4 zenith) {
  float cosGamma = clamp(v.x * sourceDir.x + v.y * sourceDir.y + v.z * sourceDir.z, -1.0f, 1.0f);
  float gamma = acos(cosGamma);
  float c2 = cosGamma * cosGamma;
  float lum = zenith.x * gradation.x * (1.0f + p.perezY.z * exp(p.perezY.w * gamma) + p.perezE.x * c2);
  float cx = zenith.y * gradation.y * (1.0f + p.perezX.z * exp(p.perezX.w * gamma) + p.perezE.y * c2);
  float cy = zenith.z * gradation.z * (1.0f + p.perezCy.z * exp(p.perezCy.w * gamma) + p.perezE.z * c2);
  vec3 xyz = vec3(cx / cy * lum, lum, (1.0f - cx - cy) / cy * lum);
  return max(skyXyzToRec709(xyz), vec3(0.0f));
}

// Sky radiance (no sun or moon disc) arriving from direction dir (towards the sky; finite, non-zero,
// need not be unit). Finite and >= floorRadiance > 0 for every direction, including below the horizon
// (horizon value at the same azimuth).
LFGI_INLINE vec3 skyRadiance(SkyParams p, vec3 dir) {
  vec3 v = skyEvalDirection(dir);
  vec3 l = vec3(p.floorRadiance) + vec3(p.overcastZenith) * ((1.0f + 2.0f * v.y) * (1.0f / 3.0f));
  // A Preetham term whose weight makeSky set to 0 (overcast 1, or the source so far below the horizon
  // that it adds < 1e-3 of the floor) is skipped: a uniform branch, it halves the cost by day.
  if (p.sunSkyZenith.x > 0.0f || p.moonSkyZenith.x > 0.0f) {
    vec3 g = skyGradation(p, v.y);
    if (p.sunSkyZenith.x > 0.0f) l = l + skyPreethamTerm(p, v, g, p.sunSkyDir, p.sunSkyZenith);
    if (p.moonSkyZenith.x > 0.0f) l = l + skyPreethamTerm(p, v, g, p.moonSkyDir, p.moonSkyZenith);
  }
  return l;
}

// Radiance of a disc (direction.w = cos angular radius) in direction dir: the disc radiance inside the
// disc and above the horizon, else 0. dir: finite, non-zero.
LFGI_INLINE vec3 skyDiscRadiance(vec4 discDirection, vec4 discRadiance, vec3 dir) {
  vec3 d = normalize(dir);
  bool inside = d.y >= 0.0f && dot(d, vec3(discDirection)) >= discDirection.w;
  return inside ? vec3(discRadiance) : vec3(0.0f);
}

LFGI_INLINE vec3 sunDiscRadiance(SkyParams p, vec3 dir) {
  return skyDiscRadiance(p.sunDirection, p.sunRadiance, dir);
}

LFGI_INLINE vec3 moonDiscRadiance(SkyParams p, vec3 dir) {
  return skyDiscRadiance(p.moonDirection, p.moonRadiance, dir);
}

// Irradiance (kilolux per channel) from the sun disc on a surface with unit normal n, unshadowed:
// radiance * solid angle * visible fraction * max(0, n . sun). The disc is treated as a point for the
// cosine (its 0.27 deg radius changes cos by < 1e-5).
LFGI_INLINE vec3 sunIrradianceOn(SkyParams p, vec3 n) {
  return vec3(p.sunIrradiance) * max(dot(n, vec3(p.sunDirection)), 0.0f);
}

LFGI_INLINE vec3 moonIrradianceOn(SkyParams p, vec3 n) {
  return vec3(p.moonIrradiance) * max(dot(n, vec3(p.moonDirection)), 0.0f);
}

LFGI_SHARED_END

#endif  // LFGI_SHARED_SKY_H
