#include "worlds/sky.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/octahedral.h"
#include "shared/octahedral.h"

namespace lfgi::worlds {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
const glm::vec3 kUp(0.0f, 1.0f, 0.0f);

float lum(glm::vec3 rgb) {
  return shared::skyLuminance(rgb);
}

bool finiteNonNegative(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && v.x >= 0.0f && v.y >= 0.0f &&
         v.z >= 0.0f;
}
bool finitePositive(glm::vec3 v) {
  return finiteNonNegative(v) && v.x > 0.0f && v.y > 0.0f && v.z > 0.0f;
}

// Fibonacci sphere: count roughly uniform unit directions over both hemispheres, plus the poles and
// four horizon directions.
std::vector<glm::vec3> sphereDirections(int count) {
  std::vector<glm::vec3> d;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    double y = 1.0 - 2.0 * (i + 0.5) / count;
    double r = std::sqrt(1.0 - y * y);
    d.emplace_back(glm::dvec3(r * std::cos(golden * i), y, r * std::sin(golden * i)));
  }
  for (glm::vec3 e : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0),
                      glm::vec3(0, 0, 1), glm::vec3(0, 0, -1)})
    d.push_back(e);
  return d;
}

SkyState state(float hours, float lat, int day, float turbidity = 3.0f, float overcast = 0.0f) {
  SkyState s;
  s.timeOfDayHours = hours;
  s.latitudeDeg = lat;
  s.dayOfYear = day;
  s.turbidity = turbidity;
  s.overcast = overcast;
  return s;
}

// Time of the zero crossing of the sun's elevation in [a, b] (bisection; elevation(a), elevation(b) differ
// in sign).
double elevationZero(double a, double b, float lat, int day) {
  auto e = [&](double t) { return sunPosition(static_cast<float>(t), lat, day).elevationDeg; };
  double ea = e(a);
  for (int k = 0; k < 60; ++k) {
    double m = 0.5 * (a + b);
    double em = e(m);
    if ((em > 0.0) == (ea > 0.0)) {
      a = m;
      ea = em;
    } else {
      b = m;
    }
  }
  return 0.5 * (a + b);
}

// Reference sky irradiance on unit normal n: integral of skyRadiance max(0, n . w) over the hemisphere
// around n, midpoint rule in (s = cos^2 theta, phi) so that cos theta d omega = ds dphi / 2.
glm::dvec3 referenceSkyIrradiance(const SkyModel& sky, glm::vec3 n, int ns = 300, int nphi = 600) {
  glm::vec3 t = std::abs(n.y) < 0.9f ? glm::normalize(glm::cross(n, kUp)) : glm::vec3(1, 0, 0);
  glm::vec3 b = glm::cross(n, t);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < ns; ++i) {
    double s = (i + 0.5) / ns;
    double c = std::sqrt(s), sn = std::sqrt(1.0 - s);
    for (int k = 0; k < nphi; ++k) {
      double phi = 2.0 * kPi * (k + 0.5) / nphi;
      glm::vec3 w = glm::vec3(glm::dvec3(t) * (sn * std::cos(phi)) + glm::dvec3(b) * (sn * std::sin(phi)) +
                              glm::dvec3(n) * c);
      sum += glm::dvec3(skyRadiance(sky, w));
    }
  }
  return sum * (0.5 * 2.0 * kPi / (static_cast<double>(ns) * nphi));
}

// Brute-force irradiance of an interior RGB octahedral map: sum L max(0, n . w) Omega over texels.
glm::dvec3 mapIrradiance(const std::vector<float>& map, int n, glm::vec3 normal) {
  std::vector<double> omega = octTexelSolidAngles(n);
  glm::dvec3 sum(0.0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      glm::vec3 w = shared::octTexelDirection(glm::uvec2(i, j), static_cast<shared::uint>(n));
      double c = std::max(0.0, static_cast<double>(glm::dot(w, normal)));
      size_t k = static_cast<size_t>(j) * static_cast<size_t>(n) + static_cast<size_t>(i);
      sum += glm::dvec3(map[k * 3], map[k * 3 + 1], map[k * 3 + 2]) * (c * omega[k]);
    }
  }
  return sum;
}

double maxRelError(glm::dvec3 got, glm::dvec3 want) {
  glm::dvec3 e = glm::abs(got - want) / want;
  return std::max({e.x, e.y, e.z});
}

// ---------------------------------------------------------------------------------------------------
// Sun position

TEST(SunPosition, BelowHorizonAtMidnight) {
  for (float lat : {-60.0f, -45.0f, -20.0f, 0.0f, 30.0f, 45.0f, 60.0f}) {
    for (int day : {1, 80, 172, 266, 355}) {
      for (float t : {0.0f, 24.0f}) {
        SunPosition s = sunPosition(t, lat, day);
        EXPECT_LT(s.elevationDeg, 0.0f) << "lat " << lat << " day " << day << " t " << t;
        EXPECT_LT(s.direction.y, 0.0f);
      }
    }
  }
}

TEST(SunPosition, NoonElevationMatchesLatitudeMinusDeclination) {
  SunPosition s = sunPosition(12.0f, 45.0f, 172);
  EXPECT_GT(s.elevationDeg, 0.0f);
  // 21 June: declination 23.44 deg (almanac), so 90 - |45 - 23.44| = 68.56 deg.
  EXPECT_NEAR(s.elevationDeg, 68.56f, 0.5f);
  EXPECT_NEAR(s.azimuthDeg, 180.0f, 1e-3f) << "northern summer noon sun is due south";
  EXPECT_NEAR(s.direction.z, std::cos(s.elevationDeg * kDeg), 1e-5) << "+Z is south";
  EXPECT_NEAR(solarDeclinationDeg(172), 23.44f, 0.5f);
  EXPECT_NEAR(solarDeclinationDeg(355), -23.44f, 0.5f);
  EXPECT_NEAR(solarDeclinationDeg(80), 0.0f, 1.0f);
  double worst = 0.0;
  for (float lat : {-70.0f, -45.0f, 0.0f, 23.0f, 45.0f, 70.0f}) {
    for (int day : {1, 80, 172, 266, 355}) {
      SunPosition n = sunPosition(12.0f, lat, day);
      double want = 90.0 - std::abs(lat - solarDeclinationDeg(day));
      worst = std::max(worst, std::abs(n.elevationDeg - want));
      EXPECT_NEAR(n.elevationDeg, want, 0.5) << "lat " << lat << " day " << day;
    }
  }
  std::printf("[ measured ] noon elevation vs 90 - |lat - decl|: max error %.2e deg\n", worst);
}

TEST(SunPosition, MorningEastEveningWestAndUnitDirection) {
  SunPosition am = sunPosition(8.0f, 45.0f, 172), pm = sunPosition(16.0f, 45.0f, 172);
  EXPECT_GT(am.direction.x, 0.0f) << "+X is east";
  EXPECT_LT(pm.direction.x, 0.0f);
  EXPECT_GT(am.azimuthDeg, 0.0f);
  EXPECT_LT(am.azimuthDeg, 180.0f);
  EXPECT_GT(pm.azimuthDeg, 180.0f);
  EXPECT_NEAR(am.azimuthDeg + pm.azimuthDeg, 360.0f, 1e-3f);
  for (float t = 0.0f; t <= 24.0f; t += 0.5f) {
    SunPosition s = sunPosition(t, -33.0f, 20);
    EXPECT_NEAR(glm::length(s.direction), 1.0f, 1e-6f);
    glm::vec3 back = directionFromElevationAzimuth(s.elevationDeg, s.azimuthDeg);
    EXPECT_NEAR(glm::length(back - s.direction), 0.0f, 1e-5f) << "t " << t;
  }
}

TEST(SunPosition, SunriseAndSunsetSymmetricAboutNoon) {
  for (float lat : {-50.0f, 0.0f, 45.0f, 60.0f}) {
    for (int day : {20, 80, 172, 300}) {
      double rise = elevationZero(0.0, 12.0, lat, day);
      double set = elevationZero(12.0, 24.0, lat, day);
      EXPECT_NEAR(0.5 * (rise + set), 12.0, 1e-4) << "lat " << lat << " day " << day;
      // Day length from the sunset hour angle cos(w0) = -tan(phi) tan(delta).
      double w0 = std::acos(-std::tan(lat * kDeg) * std::tan(solarDeclinationDeg(day) * kDeg)) / kDeg;
      EXPECT_NEAR(set - rise, 2.0 * w0 / 15.0, 1e-3) << "lat " << lat << " day " << day;
    }
  }
}

TEST(SunPosition, BadArgumentsThrowNamingThem) {
  auto message = [](auto call) -> std::string {
    try {
      call();
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(message([] { sunPosition(-0.1f, 45.0f, 172); }).find("timeOfDayHours"), std::string::npos);
  EXPECT_NE(message([] { sunPosition(12.0f, 91.0f, 172); }).find("latitudeDeg"), std::string::npos);
  EXPECT_NE(message([] { sunPosition(12.0f, 45.0f, 0); }).find("dayOfYear"), std::string::npos);
  EXPECT_NE(message([] {
              sunPosition(std::numeric_limits<float>::quiet_NaN(), 45.0f, 172);
            }).find("timeOfDayHours"),
            std::string::npos);
  EXPECT_NE(message([] { solarDeclinationDeg(367); }).find("dayOfYear"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------------
// Sun disc

TEST(SunDisc, NoonIlluminanceAndSunsetReddening) {
  SkyModel noon = makeSky(state(12.0f, 45.0f, 172));
  float e = lum(noon.sun.irradianceNormal());
  std::printf("[ measured ] sun normal illuminance at 68.6 deg, T=3: %.1f klx, disc luminance %.3g kcd/m^2\n",
              e, lum(noon.sun.radiance));
  EXPECT_GT(e, 70.0f);  // clear-sky direct normal illuminance is ~80..110 klx at high sun
  EXPECT_LT(e, 120.0f);
  EXPECT_NEAR(noon.sun.solidAngle, 6.80e-5f, 0.02e-5f);
  EXPECT_FLOAT_EQ(noon.sun.visibleFraction, 1.0f);
  // Lower sun: dimmer and redder; hazier: dimmer.
  glm::vec3 high = sunDiscRadianceAtGround(60.0f, 3.0f), low = sunDiscRadianceAtGround(5.0f, 3.0f);
  EXPECT_LT(lum(low), 0.5f * lum(high));
  EXPECT_GT(low.x / low.z, 1.5f * high.x / high.z);
  EXPECT_LT(lum(sunDiscRadianceAtGround(60.0f, 8.0f)), lum(high));
  EXPECT_NEAR(kastenYoungAirMass(90.0f), 1.0f, 1e-3f);
  EXPECT_NEAR(kastenYoungAirMass(0.0f), 38.0f, 0.2f);
}

TEST(SunDisc, ZeroWhenOvercastOrBelowHorizon) {
  SkyModel sky = makeSky(state(12.0f, 45.0f, 172, 3.0f, 1.0f));
  EXPECT_EQ(sky.sun.radiance, glm::vec3(0.0f));
  EXPECT_EQ(sky.params.sunIrradiance, glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
  EXPECT_EQ(discRadiance(sky, sky.sun.direction), glm::vec3(0.0f));
  SkyModel night = makeSky(state(0.0f, 45.0f, 172));
  EXPECT_EQ(night.sun.irradianceNormal(), glm::vec3(0.0f));
  EXPECT_EQ(shared::sunDiscRadiance(night.params, night.sun.direction), glm::vec3(0.0f));
  // The full moon is up at midnight, ~1e-6 of the sun.
  EXPECT_GT(night.moon.elevationDeg, 0.0f);
  float moonE = lum(night.moon.irradianceNormal()) * 1e3f;  // lux
  EXPECT_GT(moonE, 0.02f);
  EXPECT_LT(moonE, 0.3f);
  float ratio = lum(night.moon.radiance) / lum(sunDiscRadianceAtGround(night.moon.elevationDeg, 3.0f));
  EXPECT_NEAR(ratio, 1.3e-6f, 0.2e-6f);
  EXPECT_GT(lum(discRadiance(night, night.moon.direction)), 0.0f);
}

TEST(SunDisc, DiscRadianceOnlyInsideTheDisc) {
  SkyModel sky = makeSky(state(10.0f, 45.0f, 172));
  glm::vec3 s = sky.sun.direction;
  glm::vec3 side = glm::normalize(glm::cross(s, kUp));
  auto at = [&](double deg) {
    return glm::normalize(s * float(std::cos(deg * kDeg)) + side * float(std::sin(deg * kDeg)));
  };
  EXPECT_EQ(discRadiance(sky, at(0.0)), sky.sun.radiance);
  EXPECT_EQ(discRadiance(sky, at(0.2)), sky.sun.radiance);
  EXPECT_EQ(discRadiance(sky, at(0.35)), glm::vec3(0.0f));
  EXPECT_EQ(discRadiance(sky, -s), glm::vec3(0.0f));
}

// ---------------------------------------------------------------------------------------------------
// Sky

TEST(SkyModel, FiniteAndPositiveEverywhereAndAlways) {
  const std::vector<glm::vec3> dirs = sphereDirections(2000);
  long evaluated = 0;
  for (float lat : {-60.0f, 0.0f, 45.0f, 70.0f}) {
    for (float turbidity : {2.0f, 5.0f, 9.0f}) {
      for (float overcast : {0.0f, 0.5f, 1.0f}) {
        for (int q = 0; q <= 96; ++q) {
          float t = 0.25f * static_cast<float>(q);
          SkyModel sky = makeSky(state(t, lat, q % 2 ? 172 : 355, turbidity, overcast));
          const shared::SkyParams& p = sky.params;
          bool ok = true;
          for (const glm::vec3& d : dirs) {
            glm::vec3 l = shared::skyRadiance(p, d);
            if (!finitePositive(l)) {
              ADD_FAILURE() << "sky " << l.x << "," << l.y << "," << l.z << " at t " << t << " lat " << lat
                            << " T " << turbidity << " overcast " << overcast << " dir " << d.x << "," << d.y
                            << "," << d.z;
              ok = false;
              break;
            }
          }
          ++evaluated;
          for (const DiscLight* disc : {&sky.sun, &sky.moon}) {
            ok = ok && finiteNonNegative(disc->radiance) && finiteNonNegative(disc->irradianceNormal()) &&
                 finiteNonNegative(discRadiance(sky, disc->direction)) &&
                 finiteNonNegative(shared::sunIrradianceOn(p, kUp)) &&
                 finiteNonNegative(shared::moonIrradianceOn(p, kUp));
          }
          ASSERT_TRUE(ok) << "t " << t << " lat " << lat << " T " << turbidity << " overcast " << overcast;
        }
      }
    }
  }
  EXPECT_EQ(evaluated, 4 * 3 * 3 * 97);
}

TEST(SkyModel, ZenithEqualsPreethamZenithLuminance) {
  for (SkyState s :
       {state(12.0f, 45.0f, 172, 3.0f), state(9.0f, 10.0f, 80, 2.0f), state(17.0f, -30.0f, 20, 7.5f),
        state(7.0f, 60.0f, 172, 1.7f), state(15.0f, 0.0f, 300, 10.0f)}) {
    SkyModel sky = makeSky(s);
    ASSERT_GT(sky.sunPosition.elevationDeg, 0.0f);
    // Preetham eq. for Yz written out again here, with the paper's numbers.
    double t = s.turbidity, ts = (90.0 - sky.sunPosition.elevationDeg) * kDeg;
    double chi = (4.0 / 9.0 - t / 120.0) * (kPi - 2.0 * ts);
    double yz = (4.0453 * t - 4.9710) * std::tan(chi) - 0.2155 * t + 2.4192;
    EXPECT_NEAR(sky.sunZenith.luminance, yz, 1e-5 * yz);
    double got = lum(skyRadiance(sky, kUp));
    EXPECT_NEAR(got, yz, 1e-4 * yz) << "T " << t << " sun zenith angle " << ts / kDeg;
  }
}

TEST(SkyModel, BrighterNearTheSunThanNinetyDegreesAway) {
  // Sun elevations 20..70 deg: with the sun near the zenith the only directions 90 deg away are on the
  // horizon, which Preetham's gradation term brightens (x6 at T = 2), so the comparison says nothing there.
  for (SkyState s : {state(12.0f, 45.0f, 172), state(9.0f, 45.0f, 172, 6.0f), state(16.5f, 0.0f, 80, 2.0f),
                     state(12.0f, 45.0f, 355, 2.0f), state(14.0f, -30.0f, 20, 9.0f)}) {
    SkyModel sky = makeSky(s);
    glm::vec3 sun = sky.sun.direction;
    // far: the highest direction 90 deg of arc from the sun; near: 10 deg from the sun towards far.
    glm::vec3 w = kUp - sun * sun.y;
    w = glm::length(w) > 1e-3f ? glm::normalize(w) : glm::vec3(1, 0, 0);
    glm::vec3 near = glm::normalize(sun * float(std::cos(10.0 * kDeg)) + w * float(std::sin(10.0 * kDeg)));
    float ln = lum(skyRadiance(sky, near)), lf = lum(skyRadiance(sky, w));
    EXPECT_GT(ln, 1.5f * lf) << "t " << s.timeOfDayHours << " lat " << s.latitudeDeg;
    std::printf("[ measured ] sky 10 deg / 90 deg from the sun (elev %.1f, T %.1f): %.2f\n",
                sky.sunPosition.elevationDeg, s.turbidity, ln / lf);
  }
}

TEST(SkyModel, OvercastFollowsCieRatioAndHasNoSun) {
  double worst = 0.0;
  for (SkyState s : {state(12.0f, 45.0f, 172, 3.0f, 1.0f), state(8.0f, 10.0f, 80, 9.0f, 1.0f),
                     state(15.0f, -40.0f, 355, 2.0f, 1.0f)}) {
    SkyModel sky = makeSky(s);
    ASSERT_GT(sky.sunPosition.elevationDeg, 5.0f);
    EXPECT_EQ(sky.sun.irradianceNormal(), glm::vec3(0.0f));
    float zenith = lum(skyRadiance(sky, kUp));
    for (glm::vec3 h :
         {glm::vec3(1, 0, 0), glm::vec3(0, 0, 1), glm::vec3(-0.6f, 0, 0.8f), sky.sun.direction}) {
      glm::vec3 hd = glm::normalize(glm::vec3(h.x, 0.0f, h.z));
      double ratio = zenith / lum(skyRadiance(sky, hd));
      worst = std::max(worst, std::abs(ratio / 3.0 - 1.0));
      EXPECT_NEAR(ratio, 3.0, 0.03);
    }
    // Krochmann: Lz = 8.6 sin(elevation) + 0.123 kcd/m^2.
    EXPECT_NEAR(zenith, 8.6 * std::sin(sky.sunPosition.elevationDeg * kDeg) + 0.123, 1e-3 * zenith);
    // Uniform in azimuth and neutral (D65).
    glm::vec3 a = skyRadiance(sky, directionFromElevationAzimuth(30.0f, 10.0f));
    glm::vec3 b = skyRadiance(sky, directionFromElevationAzimuth(30.0f, 200.0f));
    EXPECT_NEAR(lum(a), lum(b), 1e-5f * lum(a));
    EXPECT_NEAR(a.x, a.z, 1e-5f * a.x);
  }
  std::printf("[ measured ] overcast zenith/horizon ratio: max deviation from 3 = %.2e (relative)\n", worst);
  // Intermediate cloud: the sun dims monotonically, the sky in between.
  float prev = std::numeric_limits<float>::infinity();
  for (float o = 0.0f; o <= 1.0f; o += 0.25f) {
    float e = lum(makeSky(state(12.0f, 45.0f, 172, 3.0f, o)).sun.irradianceNormal());
    EXPECT_LT(e, prev);
    prev = e;
  }
  EXPECT_EQ(prev, 0.0f);
}

TEST(SkyModel, BelowHorizonReturnsHorizonValue) {
  SkyModel sky = makeSky(state(10.0f, 45.0f, 172, 3.0f, 0.3f));
  for (float az : {0.0f, 77.0f, 180.0f, 300.0f}) {
    glm::vec3 h = skyRadiance(sky, directionFromElevationAzimuth(0.0f, az));
    glm::vec3 below = skyRadiance(sky, directionFromElevationAzimuth(-40.0f, az));
    EXPECT_NEAR(glm::length(below - h), 0.0f, 1e-5f * glm::length(h));
  }
  EXPECT_TRUE(finitePositive(skyRadiance(sky, glm::vec3(0, -1, 0))));
  EXPECT_TRUE(finitePositive(skyRadiance(sky, glm::vec3(0, -3, 0))));  // non-unit straight down
}

TEST(SkyModel, NightIsDarkButPositiveWithAMoonlitSky) {
  SkyModel night = makeSky(state(0.0f, 45.0f, 172));
  SkyModel noon = makeSky(state(12.0f, 45.0f, 172));
  float nightZenith = lum(skyRadiance(night, kUp)), noonZenith = lum(skyRadiance(noon, kUp));
  EXPECT_GT(nightZenith, kNightSkyLuminanceKcd);
  EXPECT_LT(nightZenith, 1e-6f * noonZenith * 100.0f);
  EXPECT_GT(night.params.floorRadiance.x, 0.0f);
  std::printf("[ measured ] zenith luminance: noon %.3g kcd/m^2, midnight %.3g kcd/m^2 (moonlit)\n",
              noonZenith, nightZenith);
}

TEST(SkyModel, ContinuousThroughSunriseAndSunset) {
  const float lat = 45.0f;
  const int day = 172;
  std::vector<glm::vec3> dirs = {kUp};
  for (float az = 0.0f; az < 360.0f; az += 45.0f) {
    dirs.push_back(directionFromElevationAzimuth(0.0f, az));
    dirs.push_back(directionFromElevationAzimuth(30.0f, az + 20.0f));
  }
  const double rise = elevationZero(0.0, 12.0, lat, day), set = elevationZero(12.0, 24.0, lat, day);
  // Per-minute factor bound: the twilight factor changes by 10^(0.4 * 0.25 deg) = 1.26 at the fastest
  // possible solar motion (0.25 deg/min); the clear sky itself changes far less.
  constexpr double kMaxStepFactor = 1.3;
  double worstStep = 1.0;
  for (double centre : {rise, set}) {
    for (int minute = -150; minute < 150; ++minute) {
      float t0 = static_cast<float>(centre + minute / 60.0),
            t1 = static_cast<float>(centre + (minute + 1) / 60.0);
      SkyModel a = makeSky(state(t0, lat, day)), b = makeSky(state(t1, lat, day));
      for (glm::vec3 d : dirs) {
        double la = lum(skyRadiance(a, d)), lb = lum(skyRadiance(b, d));
        double f = std::max(la / lb, lb / la);
        worstStep = std::max(worstStep, f);
        ASSERT_LE(f, kMaxStepFactor) << "t " << t0 << " -> " << t1 << " dir " << d.x << "," << d.y << ","
                                     << d.z;
      }
      // The sun's irradiance starts from 0 and grows without jumps (relative to its noon value).
      double ea = lum(a.sun.irradianceNormal()), eb = lum(b.sun.irradianceNormal());
      EXPECT_LT(std::abs(ea - eb), 0.02 * 95.0) << "t " << t0;
    }
    // Across elevation 0 itself: +-0.36 s.
    SkyModel a = makeSky(state(static_cast<float>(centre - 1e-4), lat, day));
    SkyModel b = makeSky(state(static_cast<float>(centre + 1e-4), lat, day));
    ASSERT_NE(a.sunPosition.elevationDeg > 0.0f, b.sunPosition.elevationDeg > 0.0f);
    for (glm::vec3 d : dirs) {
      double la = lum(skyRadiance(a, d)), lb = lum(skyRadiance(b, d));
      EXPECT_NEAR(la / lb, 1.0, 0.01);
    }
    // Half a disc through 38 air masses: a few lux, not the ~1e5 lux of noon.
    EXPECT_LT(lum(a.sun.irradianceNormal()) + lum(b.sun.irradianceNormal()), 0.01f);
  }
  std::printf("[ measured ] largest sky change per minute through sunrise/sunset: x%.3f\n", worstStep);
}

TEST(SkyModel, TwilightFadesToTheNightFloor) {
  // Equator at the equinox: the sun sets vertically, so depression = 15 deg/h after 18:00.
  float prev = std::numeric_limits<float>::infinity();
  for (float t = 17.5f; t <= 19.0f; t += 0.25f) {  // until the rising moon's sky takes over
    float z = lum(skyRadiance(makeSky(state(t, 0.0f, 80)), kUp));
    EXPECT_LT(z, prev) << "t " << t;
    prev = z;
  }
  float civil = lum(skyRadiance(makeSky(state(18.4f, 0.0f, 80)), kUp));  // ~ -6 deg
  float sunset = lum(skyRadiance(makeSky(state(18.0f, 0.0f, 80)), kUp));
  EXPECT_LT(civil, 0.01f * sunset);
  EXPECT_GT(civil, 1e-4f * sunset);
}

// ---------------------------------------------------------------------------------------------------
// Octahedral map

TEST(SkyOctahedralMap, TexelsHoldSkyRadianceAtCentres) {
  SkyModel sky = makeSky(state(14.0f, 30.0f, 100, 4.0f, 0.2f));
  const int n = 8;
  std::vector<float> map = skyOctahedralMap(sky, n, false);
  ASSERT_EQ(map.size(), static_cast<size_t>(n * n * 3));
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      glm::vec3 l = skyRadiance(sky, octTexelDirection(i, j, n));
      size_t k = static_cast<size_t>(j * n + i) * 3;
      EXPECT_FLOAT_EQ(map[k], l.x);
      EXPECT_FLOAT_EQ(map[k + 2], l.z);
    }
  }
  EXPECT_THROW(skyOctahedralMap(sky, 0, true), Error);
  EXPECT_THROW(skyOctahedralMap(sky, 5000, true), Error);
}

TEST(SkyOctahedralMap, IrradianceIsEnergyCorrectWithTheSun) {
  struct Case {
    SkyState s;
    glm::vec3 normal;
  };
  const Case cases[] = {
      {state(12.0f, 45.0f, 172), kUp},
      {state(9.0f, 0.0f, 80, 2.0f), kUp},
      {state(16.0f, -35.0f, 20, 6.0f, 0.3f), kUp},
      {state(7.0f, 52.0f, 172, 3.0f), glm::normalize(glm::vec3(0.7f, 0.5f, 0.1f))},  // low sun, tilted
  };
  double worst16 = 0.0;
  for (const Case& c : cases) {
    SkyModel sky = makeSky(c.s);
    ASSERT_GT(sky.sunPosition.elevationDeg, 5.0f);
    glm::dvec3 sun = glm::dvec3(sky.sun.irradiance(c.normal)) + glm::dvec3(sky.moon.irradiance(c.normal));
    glm::dvec3 want = sun + referenceSkyIrradiance(sky, c.normal);
    for (int n : {16, 32, 64}) {
      glm::dvec3 got = mapIrradiance(skyOctahedralMap(sky, n, true), n, c.normal);
      double err = maxRelError(got, want);
      if (n == 16) worst16 = std::max(worst16, err);
      if (n >= 32) {
        EXPECT_LT(err, 0.01) << "n " << n << " t " << c.s.timeOfDayHours;
      }
      std::printf(
          "[ measured ] n=%d t=%.1f lat=%.0f: map irradiance %.3f klx (sun %.3f) vs analytic %.3f, "
          "rel err %.2e\n",
          n, c.s.timeOfDayHours, c.s.latitudeDeg, lum(glm::vec3(got)), lum(glm::vec3(sun)),
          lum(glm::vec3(want)), err);
    }
  }
  EXPECT_LT(worst16, 0.02);
}

TEST(SkyOctahedralMap, SunEnergyIsConservedExactly) {
  SkyModel sky = makeSky(state(11.0f, 45.0f, 172));
  for (int n : {1, 2, 7, 16}) {
    std::vector<float> with = skyOctahedralMap(sky, n, true), without = skyOctahedralMap(sky, n, false);
    std::vector<double> omega = octTexelSolidAngles(n);
    double e = 0.0;
    for (size_t k = 0; k < omega.size(); ++k) e += (with[k * 3 + 1] - without[k * 3 + 1]) * omega[k];
    double want = sky.sun.irradianceNormal().y + sky.moon.irradianceNormal().y;
    EXPECT_NEAR(e, want, 1e-5 * want) << "n " << n;
  }
}

// ---------------------------------------------------------------------------------------------------
// Validation

TEST(SkyState, BadFieldsThrowNamingTheField) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto expectNamed = [](SkyState s, const std::string& field) {
    try {
      makeSky(s);
      ADD_FAILURE() << "no error for bad " << field;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  auto with = [](auto set) {
    SkyState s;
    set(s);
    return s;
  };
  expectNamed(with([](SkyState& s) { s.timeOfDayHours = 24.5f; }), "timeOfDayHours");
  expectNamed(with([](SkyState& s) { s.timeOfDayHours = -1.0f; }), "timeOfDayHours");
  expectNamed(with([&](SkyState& s) { s.timeOfDayHours = nan; }), "timeOfDayHours");
  expectNamed(with([](SkyState& s) { s.latitudeDeg = -90.5f; }), "latitudeDeg");
  expectNamed(with([&](SkyState& s) { s.latitudeDeg = nan; }), "latitudeDeg");
  expectNamed(with([](SkyState& s) { s.dayOfYear = 0; }), "dayOfYear");
  expectNamed(with([](SkyState& s) { s.dayOfYear = 367; }), "dayOfYear");
  expectNamed(with([](SkyState& s) { s.turbidity = 1.5f; }), "turbidity");
  expectNamed(with([](SkyState& s) { s.turbidity = 10.5f; }), "turbidity");
  expectNamed(with([&](SkyState& s) { s.turbidity = nan; }), "turbidity");
  expectNamed(with([](SkyState& s) { s.overcast = -0.01f; }), "overcast");
  expectNamed(with([](SkyState& s) { s.overcast = 1.01f; }), "overcast");
  expectNamed(with([&](SkyState& s) { s.overcast = nan; }), "overcast");
  expectNamed(with([](SkyState& s) { s.overcast = std::numeric_limits<float>::infinity(); }), "overcast");
  // The limits themselves are fine.
  EXPECT_NO_THROW(makeSky(state(0.0f, -90.0f, 1, kMinTurbidity, 0.0f)));
  EXPECT_NO_THROW(makeSky(state(24.0f, 90.0f, 366, kMaxTurbidity, 1.0f)));
}

}  // namespace
}  // namespace lfgi::worlds
