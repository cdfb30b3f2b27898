// Sun, moon, sky and weather: the outdoor light that the bake captures and the relight pass re-applies.
//
// Conventions: metres, right-handed, +Y up, +X east, +Z south (-Z north). Azimuth is measured from north
// towards east (compass bearing: 0 = north, 90 = east, 180 = south). Directions point TOWARDS the light.
//
// Unit of radiance: linear Rec.709 RGB in kcd/m^2 of luminance ("kilonit"): the Rec.709 luminance
// Y = 0.2126 R + 0.7152 G + 0.0722 B of a value is its photometric luminance in 1000 cd/m^2, so
// irradiance (radiance x solid angle x cos) comes out in kilolux. Preetham's zenith luminance is already
// in kcd/m^2, so the clear sky needs no scale; everything else (sun, moon, overcast, night) is put on the
// same photometric scale. Typical values: clear midday sky 2..15, midday sun disc ~1.4e6 (irradiance
// ~95 klx), CIE overcast noon zenith ~8, full-moon disc ~2, night floor 2e-7.
//
// Model:
// - Sun position: Cooper 1969 declination, hour angle 15 deg/h from local solar noon (no equation of
//   time, no refraction), standard spherical-astronomy altitude/azimuth (e.g. Iqbal 1983, "An
//   Introduction to Solar Radiation", ch. 1).
// - Clear sky: Preetham, Shirley & Smits 1999, "A Practical Analytic Model for Daylight" (SIGGRAPH):
//   Perez distribution for Y, x, y with turbidity-linear coefficients, zenith luminance and chromaticity
//   fits, xyY -> XYZ -> linear Rec.709 (out-of-gamut negatives clamped to 0). Preetham is fitted for the
//   sun above the horizon only; below it the sun's position used by the sky is clamped to elevation 0
//   (shape and colour frozen at the sunset state) and the whole sun-lit sky is multiplied by a twilight
//   factor 10^(-0.4 * depression_deg) (depression capped at 30 deg), i.e. ~2.4 decades by civil
//   twilight's end (-6 deg) and ~7 by astronomical twilight's end (-18 deg), where it meets the night
//   floor — roughly the measured fall of twilight illuminance. Continuous (not smooth) at elevation 0.
//   Preetham is known to be too bright for a low sun (zenith ~1.8 kcd/m^2 at sunset, T = 3); kept as is.
// - Sun disc: angular radius 0.2665 deg; extraterrestrial luminance = luminous solar constant 133.8 klx
//   (Darula, Kittler & Gueymard 2005) / disc solid angle; spectrum = Preetham's Table 2 extraterrestrial
//   solar spectral radiance (380..750 nm, from Iqbal 1983), attenuated per wavelength as in Preetham's
//   appendix A.1: Rayleigh exp(-0.008735 l^-4.08 m), Angstrom aerosol exp(-beta l^-1.3 m) with
//   beta = 0.04608 T - 0.04586, ozone exp(-k_o(l) 0.35 cm m) (Vigroux k_o via Iqbal); water vapour and
//   O2 bands (>= 690 nm, < 0.3 % of Y) are left out. Air mass m: Kasten & Young 1989. Spectrum -> XYZ with
//   the CIE 1931 colour-matching functions in the analytic multi-lobe fit of Wyman, Sloan & Shirley 2013
//   (JCGT 2(2)), -> linear Rec.709. A disc partly below the horizon contributes its visible fraction
//   (circular segment), the air mass is taken at max(elevation, 0).
// - Moon: full moon opposite the sun (direction = -sun; phases and the real lunar orbit are not
//   modelled), angular radius 0.259 deg, extraterrestrial luminance 2.5 kcd/m^2 (~1.3e-6 of the sun's),
//   same spectrum and atmosphere as the sun. It also lights the sky: a second Preetham term with the moon
//   as the source, scaled by the moon/sun extraterrestrial irradiance ratio (~1.2e-6).
// - Weather: overcast in [0, 1]. Effective turbidity T' = T + (10 - T) * overcast (haze rises with the
//   cloud); discs are dimmed by (1 - overcast) (0 at 1); sky = (1 - overcast) * Preetham(T')
//   + overcast * CIE standard overcast sky (Moon & Spencer 1942, L = Lz (1 + 2 cos theta) / 3, D65
//   white) with Krochmann's zenith luminance Lz = 8.6 sin(elevation) + 0.123 kcd/m^2 (as in Radiance's
//   gensky), elevation clamped to >= 0 and the same twilight factor below the horizon (moon term scaled
//   like the Preetham moon term).
// - A Preetham term whose largest possible value is under 1e-3 of the night floor is switched off (weight
//   0) so the GPU skips it: the sun-lit one below ~-29 deg, the moon-lit one when the sun is above ~14 deg.
// - Night floor: 2e-7 kcd/m^2 D65 white everywhere (natural night sky ~22 mag/arcsec^2: airglow,
//   zodiacal light, starlight; Leinert et al. 1998), so radiance is always finite and > 0.
// - Below the horizon the sky returns its horizon value at the same azimuth (no ground, no ground bounce:
//   geometry supplies the ground). See shaders/shared/sky.h.
//
// Threading: every function here is pure (no global state); SkyModel is a value.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "shared/sky.h"

namespace lfgi::worlds {

inline constexpr float kSunAngularRadiusDeg = 0.2665f;
inline constexpr float kMoonAngularRadiusDeg = 0.259f;
inline constexpr float kSolarIlluminanceKlx = 133.8f;    // luminous solar constant, top of atmosphere
inline constexpr float kMoonLuminanceKcd = 2.5f;         // full moon, top of atmosphere, kcd/m^2
inline constexpr float kNightSkyLuminanceKcd = 2.0e-7f;  // night floor, kcd/m^2
inline constexpr float kMinTurbidity = 1.7f;             // Preetham's fitted range
inline constexpr float kMaxTurbidity = 10.0f;

struct SunPosition {
  glm::vec3 direction{0.0f, 1.0f, 0.0f};  // unit, towards the sun, world space (+X east, +Y up, +Z south)
  float elevationDeg = 90.0f;             // above the horizon, [-90, 90]
  float azimuthDeg = 0.0f;                // from north towards east, [0, 360)
  float declinationDeg = 0.0f;
  float hourAngleDeg = 0.0f;  // 15 deg per hour from local solar noon, negative in the morning
};

// Solar declination (degrees) on day 1..366 of the year, Cooper 1969: 23.45 sin(360 (284 + N) / 365).
// Differs from Spencer 1971's Fourier series by at most 1.4 deg (near the equinoxes), < 0.1 deg at the
// solstices. Throws lfgi::Error naming dayOfYear outside [1, 366].
float solarDeclinationDeg(int dayOfYear);

// Sun position at local solar time timeOfDayHours in [0, 24] (12 = solar noon), latitude in [-90, 90]
// degrees (north positive), dayOfYear in [1, 366]. Geometric (no refraction). Throws lfgi::Error naming
// the offending argument (NaN included).
SunPosition sunPosition(float timeOfDayHours, float latitudeDeg, int dayOfYear);

// Unit world direction for an elevation (deg above horizon) and azimuth (deg from north towards east).
glm::vec3 directionFromElevationAzimuth(float elevationDeg, float azimuthDeg);

// Kasten & Young 1989 relative optical air mass for a body at elevationDeg (clamped to [0, 90]):
// 1 at the zenith, ~38 at the horizon.
float kastenYoungAirMass(float elevationDeg);

// Radiance (kcd/m^2 RGB) of the unobstructed sun disc seen from the ground at elevationDeg (clamped to
// >= 0 for the air mass) through an atmosphere of turbidity T in [1.7, 10] (no clouds, no horizon cut).
glm::vec3 sunDiscRadianceAtGround(float elevationDeg, float turbidity);

// Preetham 1999 zenith luminance Yz (kcd/m^2) and chromaticity (x, y) for turbidity T and sun zenith
// angle thetaS (radians, clamped to [0, pi/2]).
struct PreethamZenith {
  float luminance = 0.0f;
  float x = 0.0f;
  float y = 0.0f;
};
PreethamZenith preethamZenith(float turbidity, float sunZenithRad);

struct SkyState {
  float timeOfDayHours = 12.0f;  // local solar time, [0, 24]
  float latitudeDeg = 45.0f;     // [-90, 90], north positive
  int dayOfYear = 172;           // [1, 366]; 172 = 21 June
  float turbidity = 3.0f;        // Preetham turbidity, [1.7, 10]; 2 = very clear, 3 = clear, 6+ = hazy
  float overcast = 0.0f;         // [0, 1]; 0 = clear, 1 = CIE standard overcast (no sun)
};

// Throws lfgi::Error naming the first bad field ("SkyState.turbidity = 12 outside [1.7, 10]"); NaN is
// bad everywhere.
void validateSkyState(const SkyState& state);

// A sun or moon disc as seen from the ground.
struct DiscLight {
  glm::vec3 direction{0.0f, 1.0f, 0.0f};  // unit, towards the disc
  float elevationDeg = 0.0f;
  float angularRadiusRad = 0.0f;
  float solidAngle = 0.0f;       // sr, 2 pi (1 - cos radius)
  glm::vec3 radiance{0.0f};      // kcd/m^2 RGB after atmosphere and clouds
  float visibleFraction = 0.0f;  // part of the disc above the horizon, [0, 1]

  // Irradiance (klx RGB) on a surface facing the disc: radiance * solidAngle * visibleFraction.
  glm::vec3 irradianceNormal() const { return radiance * (solidAngle * visibleFraction); }
  // Unshadowed irradiance on a surface with unit normal n: irradianceNormal() * max(0, n . direction).
  glm::vec3 irradiance(glm::vec3 n) const {
    return irradianceNormal() * glm::max(glm::dot(n, direction), 0.0f);
  }
};

// Everything about one sky state, precomputed. params is what the GPU gets (upload it as-is).
struct SkyModel {
  SkyState state;
  SunPosition sunPosition;
  float effectiveTurbidity = 3.0f;  // T' = T + (10 - T) * overcast
  float sunTwilight = 1.0f;         // factor on the sun-lit sky (1 above the horizon)
  float moonTwilight = 0.0f;        // same for the moon
  PreethamZenith sunZenith;         // Preetham zenith values for the sun at max(elevation, 0)
  DiscLight sun;
  DiscLight moon;
  shared::SkyParams params{};
};

// Validates state (validateSkyState) and precomputes the model. Cost: ~2 x 38 spectral samples.
SkyModel makeSky(const SkyState& state);

// Sky radiance without the discs (shared::skyRadiance): finite and > 0 for any finite non-zero dir.
glm::vec3 skyRadiance(const SkyModel& sky, glm::vec3 dir);
// Sun + moon disc radiance in dir (0 outside the discs and below the horizon).
glm::vec3 discRadiance(const SkyModel& sky, glm::vec3 dir);

// Interior n x n octahedral radiance map (core/octahedral.h layout: texel (i, j) at (j * n + i) * 3,
// RGB), n in [1, 4096] (else lfgi::Error). Each texel holds skyRadiance at its centre direction
// (shared::octTexelDirection). With includeSun, the sun's and the moon's energy (DiscLight::
// irradianceNormal() = radiance x disc solid angle x visible fraction) is added as radiance
// weight_k x energy / Omega_k over three texels k: among the 3 x 3 texels around the one containing the
// disc centre (folded across the map edge by octBorderSource), the three whose centre directions span the
// tightest spherical triangle containing the disc direction, weights = its barycentric coordinates
// normalised to sum 1. So sum_k L_k Omega_k gains exactly the disc's energy and the weighted mean
// direction is exactly the disc's, which keeps the irradiance sum_texels L max(0, n . w) Omega correct
// to second order in the texel size for any normal facing the three texels (measured: ~1 % at n = 16,
// 0.25 % at 32, 0.06 % at 64 for the sun part; a one-texel deposit is first order, ~7 % at 16, and
// bilinear splatting is first order across the octahedron's creases). Tiny maps (n <= 2) where no
// triangle contains it put everything in the containing texel. The disc is never drawn at its true size
// (at n >~ 430 texels are smaller than it; still energy-correct).
std::vector<float> skyOctahedralMap(const SkyModel& sky, int n, bool includeSun);

}  // namespace lfgi::worlds
