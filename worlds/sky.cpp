#include "worlds/sky.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/error.h"
#include "core/octahedral.h"
#include "shared/octahedral.h"

namespace lfgi::worlds {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

// Spectral grid of the sun model: 380, 390, ..., 750 nm.
constexpr int kSpectralSamples = 38;
constexpr double kFirstWavelengthNm = 380.0;
constexpr double kWavelengthStepNm = 10.0;

// Extraterrestrial solar spectral radiance, 380..750 nm by 10 nm (Preetham et al. 1999, Table 2, from
// Iqbal 1983). Only the shape is used; the scale comes from the luminous solar constant.
constexpr double kSolarSpectrum[kSpectralSamples] = {
    16559.0, 16233.7, 21127.5, 25888.2, 25829.1, 24232.3, 26760.5, 29658.3, 30545.4, 30057.5,
    30663.7, 28830.4, 28712.1, 27825.0, 27100.6, 27233.6, 26361.3, 25503.8, 25060.2, 25311.6,
    25355.9, 25134.2, 24631.5, 24173.2, 23685.3, 23212.1, 22827.7, 22339.8, 21970.2, 21526.7,
    21097.9, 20728.3, 20240.4, 19870.8, 19427.2, 19072.4, 18628.9, 18259.2};

// Ozone absorption coefficient k_o (1/cm), 380..750 nm by 10 nm (Vigroux's values via Iqbal 1983 and
// Preetham's appendix; 0 below 445 nm within our range).
constexpr double kOzoneK[kSpectralSamples] = {
    0.0,   0.0,   0.0,   0.0,   0.0,   0.0,   0.0,   0.003, 0.006, 0.009, 0.014, 0.021, 0.030,
    0.040, 0.048, 0.063, 0.075, 0.085, 0.103, 0.120, 0.120, 0.115, 0.125, 0.120, 0.105, 0.090,
    0.079, 0.067, 0.057, 0.048, 0.036, 0.028, 0.023, 0.018, 0.014, 0.011, 0.010, 0.009};
constexpr double kOzoneColumnCm = 0.35;

// CIE 1931 2-degree colour-matching functions, multi-lobe piecewise-Gaussian fit of Wyman, Sloan &
// Shirley 2013, "Simple Analytic Approximations to the CIE XYZ Color Matching Functions" (JCGT 2(2)).
double lobe(double l, double mu, double sigmaLow, double sigmaHigh) {
  double t = (l - mu) / (l < mu ? sigmaLow : sigmaHigh);
  return std::exp(-0.5 * t * t);
}
glm::dvec3 cieCmf(double l) {
  double x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) -
             0.065 * lobe(l, 501.1, 20.4, 26.2);
  double y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
  double z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
  return {x, y, z};
}

// XYZ of the spectrum after transmittance through air mass m at turbidity T, normalised so that the
// extraterrestrial spectrum (m = 0) has Y = 1. Preetham 1999 appendix A.1 transmittances.
glm::dvec3 attenuatedSolarXyz(double airMass, double turbidity) {
  double beta = 0.04608365822050 * turbidity - 0.04586025928522;  // Angstrom turbidity coefficient
  constexpr double kAlpha = 1.3;                                  // Angstrom wavelength exponent
  glm::dvec3 xyz(0.0);
  double yTop = 0.0;
  for (int i = 0; i < kSpectralSamples; ++i) {
    double nm = kFirstWavelengthNm + kWavelengthStepNm * i;
    double um = nm * 1e-3;
    double tau = 0.008735 * std::pow(um, -4.08) + beta * std::pow(um, -kAlpha) + kOzoneK[i] * kOzoneColumnCm;
    glm::dvec3 cmf = cieCmf(nm);
    xyz += cmf * (kSolarSpectrum[i] * std::exp(-airMass * tau));
    yTop += cmf.y * kSolarSpectrum[i];
  }
  return xyz / yTop;
}

glm::vec3 xyzToRec709(glm::dvec3 xyz) {
  return glm::max(shared::skyXyzToRec709(glm::vec3(xyz)), glm::vec3(0.0f));
}

// Fraction of a disc of angular radius r whose centre is at elevation h that lies above the horizon
// (flat circular segment; exact to O(r^2) for the 0.27 deg discs here).
double visibleDiscFraction(double elevationRad, double radiusRad) {
  double x = elevationRad / radiusRad;
  if (x >= 1.0) return 1.0;
  if (x <= -1.0) return 0.0;
  // Area below the horizon line at distance x (in radii) below the centre: acos(x) - x sqrt(1 - x^2).
  return 1.0 - (std::acos(x) - x * std::sqrt(1.0 - x * x)) / kPi;
}

// Sky brightness factor for a source at elevation h (degrees): 1 above the horizon, 10^(-0.4 depression)
// below it, depression capped at 30 deg (1e-12, far under the night floor).
double twilightFactor(double elevationDeg) {
  if (elevationDeg >= 0.0) return 1.0;
  return std::pow(10.0, -0.4 * std::min(-elevationDeg, 30.0));
}

// Perez coefficients (A, B, C, D) and E for Y, x, y at turbidity T (Preetham 1999, appendix A.2).
struct PerezCoefficients {
  glm::vec4 y, cx, cy, e;
};
PerezCoefficients perezCoefficients(float t) {
  PerezCoefficients p;
  p.y =
      glm::vec4(0.1787f * t - 1.4630f, -0.3554f * t + 0.4275f, -0.0227f * t + 5.3251f, 0.1206f * t - 2.5771f);
  p.cx = glm::vec4(-0.0193f * t - 0.2592f, -0.0665f * t + 0.0008f, -0.0004f * t + 0.2125f,
                   -0.0641f * t - 0.8989f);
  p.cy = glm::vec4(-0.0167f * t - 0.2608f, -0.0950f * t + 0.0092f, -0.0079f * t + 0.2102f,
                   -0.0441f * t - 1.6537f);
  p.e = glm::vec4(-0.0670f * t + 0.3703f, -0.0033f * t + 0.0452f, -0.0109f * t + 0.0529f, 0.0f);
  return p;
}

// Direction the sky's Perez gamma is measured from: the source with its elevation clamped to >= 0.
glm::vec3 skySourceDirection(const glm::vec3& d) {
  if (d.y >= 0.0f) return d;
  glm::vec3 h(d.x, 0.0f, d.z);
  float l = glm::length(h);
  return l > 1e-6f ? h / l : glm::vec3(1.0f, 0.0f, 0.0f);
}

// Zenith-normalised Preetham term for a source: (weight * Yz / F_Y(0, ts), xz / F_x(0, ts), yz / F_y(0, ts)).
glm::vec4 preethamZenithTerm(const PerezCoefficients& p, const PreethamZenith& z, float thetaS,
                             double weight) {
  float cosT = std::cos(thetaS);
  auto f0 = [&](const glm::vec4& abcd, float e) { return shared::skyPerez(abcd, e, 1.0f, thetaS, cosT); };
  return glm::vec4(static_cast<float>(weight * z.luminance / f0(p.y, p.e.x)), z.x / f0(p.cx, p.e.y),
                   z.y / f0(p.cy, p.e.z), 0.0f);
}

DiscLight makeDisc(const glm::vec3& direction, double elevationDeg, double radiusDeg, double luminanceTop,
                   double turbidity, double dim) {
  DiscLight d;
  d.direction = direction;
  d.elevationDeg = static_cast<float>(elevationDeg);
  double r = radiusDeg * kDeg;
  d.angularRadiusRad = static_cast<float>(r);
  d.solidAngle = static_cast<float>(2.0 * kPi * (1.0 - std::cos(r)));
  d.visibleFraction = static_cast<float>(visibleDiscFraction(elevationDeg * kDeg, r));
  if (d.visibleFraction > 0.0f && dim > 0.0) {
    glm::dvec3 xyz = attenuatedSolarXyz(kastenYoungAirMass(static_cast<float>(elevationDeg)), turbidity);
    d.radiance = xyzToRec709(xyz * (luminanceTop * dim));
  }
  return d;
}

// owner: "SkyState" or the function whose argument is checked; the message names owner.field.
void checkRange(const char* owner, const char* field, double v, double lo, double hi) {
  if (!std::isfinite(v)) fail("{}.{} = {} is not a finite number", owner, field, v);
  if (v < lo || v > hi) fail("{}.{} = {} outside [{}, {}]", owner, field, v, lo, hi);
}

void checkDay(const char* owner, int dayOfYear) {
  if (dayOfYear < 1 || dayOfYear > 366) fail("{}.dayOfYear = {} outside [1, 366]", owner, dayOfYear);
}

}  // namespace

float solarDeclinationDeg(int dayOfYear) {
  checkDay("solarDeclinationDeg", dayOfYear);
  return static_cast<float>(23.45 * std::sin(2.0 * kPi * (284.0 + dayOfYear) / 365.0));
}

glm::vec3 directionFromElevationAzimuth(float elevationDeg, float azimuthDeg) {
  double h = elevationDeg * kDeg, a = azimuthDeg * kDeg;
  double east = std::cos(h) * std::sin(a), north = std::cos(h) * std::cos(a);
  return glm::normalize(glm::vec3(glm::dvec3(east, std::sin(h), -north)));
}

SunPosition sunPosition(float timeOfDayHours, float latitudeDeg, int dayOfYear) {
  checkRange("sunPosition", "timeOfDayHours", timeOfDayHours, 0.0, 24.0);
  checkRange("sunPosition", "latitudeDeg", latitudeDeg, -90.0, 90.0);
  checkDay("sunPosition", dayOfYear);
  SunPosition s;
  s.declinationDeg = solarDeclinationDeg(dayOfYear);
  s.hourAngleDeg = 15.0f * (timeOfDayHours - 12.0f);
  double phi = latitudeDeg * kDeg, delta = s.declinationDeg * kDeg, omega = s.hourAngleDeg * kDeg;
  // Sun in the local east/north/up frame (rotate the equatorial direction by the hour angle and the
  // colatitude); up = sin(phi) sin(delta) + cos(phi) cos(delta) cos(omega) is the usual altitude formula.
  double east = -std::cos(delta) * std::sin(omega);
  double north = std::sin(delta) * std::cos(phi) - std::cos(delta) * std::cos(omega) * std::sin(phi);
  double up = std::sin(delta) * std::sin(phi) + std::cos(delta) * std::cos(omega) * std::cos(phi);
  glm::dvec3 d = glm::normalize(glm::dvec3(east, up, -north));
  s.direction = glm::vec3(d);
  s.elevationDeg = static_cast<float>(std::asin(std::clamp(d.y, -1.0, 1.0)) / kDeg);
  double az = std::atan2(east, north) / kDeg;
  if (az < 0.0) az += 360.0;
  s.azimuthDeg = static_cast<float>(az >= 360.0 ? az - 360.0 : az);
  return s;
}

float kastenYoungAirMass(float elevationDeg) {
  double z = 90.0 - std::clamp(static_cast<double>(elevationDeg), 0.0, 90.0);
  return static_cast<float>(1.0 / (std::cos(z * kDeg) + 0.50572 * std::pow(96.07995 - z, -1.6364)));
}

glm::vec3 sunDiscRadianceAtGround(float elevationDeg, float turbidity) {
  double r = kSunAngularRadiusDeg * kDeg;
  double luminanceTop = kSolarIlluminanceKlx / (2.0 * kPi * (1.0 - std::cos(r)));
  return xyzToRec709(attenuatedSolarXyz(kastenYoungAirMass(elevationDeg), turbidity) * luminanceTop);
}

PreethamZenith preethamZenith(float turbidity, float sunZenithRad) {
  double t = turbidity;
  double ts = std::clamp(static_cast<double>(sunZenithRad), 0.0, kPi / 2.0);
  double chi = (4.0 / 9.0 - t / 120.0) * (kPi - 2.0 * ts);
  PreethamZenith z;
  z.luminance = static_cast<float>((4.0453 * t - 4.9710) * std::tan(chi) - 0.2155 * t + 2.4192);
  double ts2 = ts * ts, ts3 = ts2 * ts;
  z.x = static_cast<float>(t * t * (0.00166 * ts3 - 0.00375 * ts2 + 0.00209 * ts) +
                           t * (-0.02903 * ts3 + 0.06377 * ts2 - 0.03202 * ts + 0.00394) +
                           (0.11693 * ts3 - 0.21196 * ts2 + 0.06052 * ts + 0.25886));
  z.y = static_cast<float>(t * t * (0.00275 * ts3 - 0.00610 * ts2 + 0.00317 * ts) +
                           t * (-0.04214 * ts3 + 0.08970 * ts2 - 0.04153 * ts + 0.00516) +
                           (0.15346 * ts3 - 0.26756 * ts2 + 0.06670 * ts + 0.26688));
  return z;
}

void validateSkyState(const SkyState& s) {
  checkRange("SkyState", "timeOfDayHours", s.timeOfDayHours, 0.0, 24.0);
  checkRange("SkyState", "latitudeDeg", s.latitudeDeg, -90.0, 90.0);
  checkDay("SkyState", s.dayOfYear);
  checkRange("SkyState", "turbidity", s.turbidity, kMinTurbidity, kMaxTurbidity);
  checkRange("SkyState", "overcast", s.overcast, 0.0, 1.0);
}

SkyModel makeSky(const SkyState& state) {
  validateSkyState(state);
  SkyModel m;
  m.state = state;
  m.sunPosition = sunPosition(state.timeOfDayHours, state.latitudeDeg, state.dayOfYear);
  const double overcast = state.overcast;
  m.effectiveTurbidity = static_cast<float>(state.turbidity + (kMaxTurbidity - state.turbidity) * overcast);
  const float t = m.effectiveTurbidity;

  const glm::vec3 sunDir = m.sunPosition.direction;
  const glm::vec3 moonDir = -sunDir;
  const double sunElev = m.sunPosition.elevationDeg;
  const double moonElev = -sunElev;
  m.sunTwilight = static_cast<float>(twilightFactor(sunElev));
  m.moonTwilight = static_cast<float>(twilightFactor(moonElev));

  // Discs. The moon's top-of-atmosphere radiance uses the solar spectrum scaled to its luminance.
  const double dim = 1.0 - overcast;
  const double sunSolid = 2.0 * kPi * (1.0 - std::cos(kSunAngularRadiusDeg * kDeg));
  const double moonSolid = 2.0 * kPi * (1.0 - std::cos(kMoonAngularRadiusDeg * kDeg));
  m.sun = makeDisc(sunDir, sunElev, kSunAngularRadiusDeg, kSolarIlluminanceKlx / sunSolid, t, dim);
  m.moon = makeDisc(moonDir, moonElev, kMoonAngularRadiusDeg, kMoonLuminanceKcd, t, dim);
  // The moonlit sky is the daylight sky scaled by the ratio of top-of-atmosphere irradiances.
  const double moonSkyScale = kMoonLuminanceKcd * moonSolid / kSolarIlluminanceKlx;

  // Clear (Preetham) part, one term per source, with the source elevation clamped to >= 0.
  const PerezCoefficients perez = perezCoefficients(t);
  const float sunThetaS = static_cast<float>(kPi / 2.0 - std::max(sunElev, 0.0) * kDeg);
  const float moonThetaS = static_cast<float>(kPi / 2.0 - std::max(moonElev, 0.0) * kDeg);
  m.sunZenith = preethamZenith(t, sunThetaS);
  const PreethamZenith moonZenith = preethamZenith(t, moonThetaS);

  // Terms too faint to matter are switched off (weight 0, skipped by shared::skyRadiance): their largest
  // possible value, weight * Yz * max F / F(0, ts) (F / F0 < 50 over the fitted range), is under 1e-3 of
  // the night floor. The sun-lit term goes off below ~-29 deg, the moon-lit one by day above ~14 deg.
  const double sunWeight = (1.0 - overcast) * m.sunTwilight;
  const double moonWeight = (1.0 - overcast) * moonSkyScale * m.moonTwilight;
  auto significant = [](double weight, const PreethamZenith& z) {
    return weight * z.luminance * 50.0 >= 1e-3 * kNightSkyLuminanceKcd;
  };

  shared::SkyParams& p = m.params;
  p.perezY = perez.y;
  p.perezX = perez.cx;
  p.perezCy = perez.cy;
  p.perezE = perez.e;
  p.sunSkyDir = glm::vec4(skySourceDirection(sunDir), 0.0f);
  p.sunSkyZenith = significant(sunWeight, m.sunZenith)
                       ? preethamZenithTerm(perez, m.sunZenith, sunThetaS, sunWeight)
                       : glm::vec4(0.0f);
  p.moonSkyDir = glm::vec4(skySourceDirection(moonDir), 0.0f);
  p.moonSkyZenith = significant(moonWeight, moonZenith)
                        ? preethamZenithTerm(perez, moonZenith, moonThetaS, moonWeight)
                        : glm::vec4(0.0f);

  // CIE overcast part: Krochmann's zenith luminance per source.
  auto overcastLz = [](double elevDeg) { return 8.6 * std::sin(std::max(elevDeg, 0.0) * kDeg) + 0.123; };
  const double lz =
      overcast * (m.sunTwilight * overcastLz(sunElev) + moonSkyScale * m.moonTwilight * overcastLz(moonElev));
  p.overcastZenith = glm::vec4(glm::vec3(static_cast<float>(lz)), 0.0f);
  p.floorRadiance = glm::vec4(glm::vec3(kNightSkyLuminanceKcd), 0.0f);

  auto packDisc = [](const DiscLight& d, glm::vec4& dir, glm::vec4& rad, glm::vec4& irr) {
    dir = glm::vec4(d.direction, std::cos(d.angularRadiusRad));
    rad = glm::vec4(d.radiance, d.solidAngle);
    irr = glm::vec4(d.irradianceNormal(), d.visibleFraction);
  };
  packDisc(m.sun, p.sunDirection, p.sunRadiance, p.sunIrradiance);
  packDisc(m.moon, p.moonDirection, p.moonRadiance, p.moonIrradiance);
  return m;
}

glm::vec3 skyRadiance(const SkyModel& sky, glm::vec3 dir) {
  return shared::skyRadiance(sky.params, dir);
}

glm::vec3 discRadiance(const SkyModel& sky, glm::vec3 dir) {
  return shared::sunDiscRadiance(sky.params, dir) + shared::moonDiscRadiance(sky.params, dir);
}

std::vector<float> skyOctahedralMap(const SkyModel& sky, int n, bool includeSun) {
  if (n < 1 || n > 4096) fail("skyOctahedralMap: map size n = {} outside [1, 4096]", n);
  const auto un = static_cast<shared::uint>(n);
  std::vector<float> map(octInteriorFloats(n, 3));
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      glm::vec3 d = shared::octTexelDirection(
          glm::uvec2(static_cast<shared::uint>(i), static_cast<shared::uint>(j)), un);
      glm::vec3 l = shared::skyRadiance(sky.params, d);
      float* t = &map[(static_cast<size_t>(j) * static_cast<size_t>(n) + static_cast<size_t>(i)) * 3];
      t[0] = l.x;
      t[1] = l.y;
      t[2] = l.z;
    }
  }
  if (!includeSun) return map;

  const std::vector<double> omega = octTexelSolidAngles(n);
  auto splat = [&](const DiscLight& disc) {
    glm::dvec3 energy(disc.irradianceNormal());
    if (energy.x <= 0.0 && energy.y <= 0.0 && energy.z <= 0.0) return;
    const glm::dvec3 target(disc.direction);
    // Candidate texels: the 3 x 3 neighbourhood of the texel containing the disc centre, folded across the
    // map edge (octBorderSource) and deduplicated.
    const glm::uvec2 home = shared::octDirectionTexel(disc.direction, un);
    size_t index[9];
    glm::dvec3 dir[9];
    int count = 0;
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        glm::uvec2 b(static_cast<shared::uint>(static_cast<int>(home.x) + di + 1),
                     static_cast<shared::uint>(static_cast<int>(home.y) + dj + 1));
        glm::uvec2 src = shared::octBorderSource(b, un);
        size_t k = static_cast<size_t>(src.y) * static_cast<size_t>(n) + static_cast<size_t>(src.x);
        if (std::find(index, index + count, k) != index + count) continue;
        index[count] = k;
        dir[count] = glm::dvec3(shared::octTexelDirection(src, un));
        ++count;
      }
    }
    // The tightest spherical triangle of candidate centres containing the disc centre: target =
    // sum x_i w_i with x_i >= 0 and the smallest sum x_i (the normalised weights' mean direction then has
    // the largest length 1 / sum x_i, i.e. the least spread).
    size_t best[3] = {index[0], index[0], index[0]};
    double bestWeight[3] = {1.0, 0.0, 0.0};
    double bestSum = std::numeric_limits<double>::infinity();
    for (int a = 0; a < count; ++a) {
      for (int b = a + 1; b < count; ++b) {
        for (int c = b + 1; c < count; ++c) {
          glm::dmat3 m(dir[a], dir[b], dir[c]);
          double det = glm::determinant(m);
          if (std::abs(det) < 1e-12) continue;
          glm::dvec3 x = glm::inverse(m) * target;
          double sum = x.x + x.y + x.z;
          if (x.x < 0.0 || x.y < 0.0 || x.z < 0.0 || sum >= bestSum) continue;
          bestSum = sum;
          best[0] = index[a], best[1] = index[b], best[2] = index[c];
          bestWeight[0] = x.x / sum, bestWeight[1] = x.y / sum, bestWeight[2] = x.z / sum;
        }
      }
    }
    if (!std::isfinite(bestSum)) {  // tiny maps: no triangle contains it; the home texel takes it all
      best[0] = static_cast<size_t>(home.y) * static_cast<size_t>(n) + static_cast<size_t>(home.x);
    }
    for (int v = 0; v < 3; ++v) {
      if (bestWeight[v] <= 0.0) continue;
      size_t k = best[v];
      glm::dvec3 add = energy * (bestWeight[v] / omega[k]);
      map[k * 3 + 0] += static_cast<float>(add.x);
      map[k * 3 + 1] += static_cast<float>(add.y);
      map[k * 3 + 2] += static_cast<float>(add.z);
    }
  };
  splat(sky.sun);
  splat(sky.moon);
  return map;
}

}  // namespace lfgi::worlds
