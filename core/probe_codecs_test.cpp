#include "core/probe_codecs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "core/error.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/sh.h"
#include "core/sh_high_order.h"

namespace lfgi {
namespace {

ProbeField emptyField(int probes, int n, int m = 8) {
  ProbeField f;
  f.grid.dims = glm::ivec3(probes, 1, 1);
  f.resolution = n;
  f.irradianceResolution = m;
  f.radiance.assign(size_t(probes) * size_t(n * n * 3), 0.0f);
  return f;
}

// A smooth sky-like field: a per-probe gradient towards a per-probe direction, plus (optionally) one
// bright "sun" texel per probe, 10^3 above the rest (the HDR case every codec must survive).
ProbeField skyField(int probes, int n, bool sun, uint32_t seed = 3) {
  ProbeField f = emptyField(probes, n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int p = 0; p < probes; ++p) {
    const glm::vec3 a = glm::normalize(glm::vec3(u(rng), 1.5f, u(rng)));
    const glm::vec3 tint(0.5f + 0.4f * u(rng), 0.6f, 0.8f + 0.1f * u(rng));
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const glm::vec3 d = octTexelDirection(i, j, n);
        const glm::vec3 L = tint * (1.2f + glm::dot(d, a)) * (1.0f + 0.3f * d.x * d.z);
        float* o = f.radiance.data() + (size_t(p) * size_t(n * n) + size_t(j * n + i)) * 3;
        o[0] = L.x;
        o[1] = L.y;
        o[2] = L.z;
      }
    if (sun) {
      const int i = int(rng() % uint32_t(n)), j = int(rng() % uint32_t(n));
      float* o = f.radiance.data() + (size_t(p) * size_t(n * n) + size_t(j * n + i)) * 3;
      for (int c = 0; c < 3; ++c) o[c] = 2000.0f;
    }
  }
  return f;
}

ProbeField roundTrip(const ProbeCodec& codec, const ProbeField& f, size_t* bytes = nullptr) {
  const std::vector<std::byte> b = codec.encode(f);
  if (bytes) *bytes = b.size();
  ProbeField out = f;
  out.radiance.clear();
  codec.decode(b, out);
  return out;
}

TEST(ProbeCodecs, RawFp16IsExactToHalfRounding) {
  const ProbeField f = skyField(5, 8, true);
  const auto codec = makeRawFp16Codec();
  size_t bytes = 0;
  const ProbeField d = roundTrip(*codec, f, &bytes);
  EXPECT_EQ(bytes, 11u + 4u + f.radiance.size() * 2);
  ASSERT_EQ(d.radiance.size(), f.radiance.size());
  for (size_t i = 0; i < f.radiance.size(); ++i)
    EXPECT_LE(std::abs(d.radiance[i] - f.radiance[i]), std::ldexp(std::abs(f.radiance[i]), -11)) << i;
  EXPECT_TRUE(d.irradiance.empty());
}

TEST(ProbeCodecs, ZstdDecodesBitIdenticalToRawFp16) {
  const ProbeField f = skyField(16, 16, true);
  size_t rawBytes = 0, zBytes = 0;
  const ProbeField a = roundTrip(*makeRawFp16Codec(), f, &rawBytes);
  const ProbeField b = roundTrip(*makeZstdFp16Codec(9), f, &zBytes);
  EXPECT_EQ(a.radiance, b.radiance);
  std::printf("raw fp16 %zu bytes, zstd level 9 %zu bytes\n", rawBytes, zBytes);
  EXPECT_LT(zBytes, rawBytes);
}

TEST(ProbeCodecs, ShConstantFieldIsExact) {
  ProbeField f = emptyField(3, 16);
  for (size_t i = 0; i < f.radiance.size(); ++i) f.radiance[i] = 0.5f + 0.25f * float(i % 3);
  for (int lmax : {2, 7}) {
    const auto codec = makeShCodec(lmax);
    size_t bytes = 0;
    const ProbeField d = roundTrip(*codec, f, &bytes);
    EXPECT_EQ(bytes, 11u + 1u + 4u + 3u * size_t(shCoefficientCount(lmax)) * 3u * 2u);
    // c_0 = sqrt(4 pi) L rounds to FP16 (relative 2^-11); the other coefficients are ~1e-12 -> 0.
    for (size_t i = 0; i < f.radiance.size(); ++i)
      EXPECT_NEAR(d.radiance[i], f.radiance[i], 1e-3f * f.radiance[i]);
    ASSERT_EQ(d.irradiance.size(), size_t(3 * 8 * 8 * 3));
    for (size_t i = 0; i < d.irradiance.size(); ++i)
      EXPECT_NEAR(d.irradiance[i], std::numbers::pi_v<float> * (0.5f + 0.25f * float(i % 3)), 2e-3f);
  }
}

// A smooth field: L7 must beat L2 on radiance, and the direct SH irradiance of both must match the
// texel-sum irradiance of the original (irradiance needs only bands <= 2, so L2 is already close).
TEST(ProbeCodecs, ShErrorsOnSmoothField) {
  ProbeField f = skyField(4, 16, false);
  ProbeField ref = f;
  deriveIrradiance(ref);
  const ProbeField d2 = roundTrip(*makeShCodec(2), f), d7 = roundTrip(*makeShCodec(7), f);
  const double r2 = relativeRms(d2.radiance, f.radiance), r7 = relativeRms(d7.radiance, f.radiance);
  const double e2 = relativeRms(d2.irradiance, ref.irradiance),
               e7 = relativeRms(d7.irradiance, ref.irradiance);
  std::printf("smooth field: radiance rel RMS L2 %.4f L7 %.4f; irradiance rel RMS L2 %.4f L7 %.4f\n", r2, r7,
              e2, e7);
  EXPECT_LT(r7, r2);
  EXPECT_LT(r2, 0.05);
  EXPECT_LT(e2, 0.01);
  EXPECT_LT(e7, 0.01);
}

// APV-style SH L1: 15 B per probe; its coefficients within the int8 step of SH L1's (|error| <= sqrt(3) L0 /
// 254 per L1 coefficient, FP16 rounding on L0), so its irradiance is within 1 % of SH L1's.
TEST(ProbeCodecs, ShL1Q8StaysWithinItsQuantizationStepOfShL1) {
  const ProbeField f = skyField(6, 16, false);
  size_t bytes = 0;
  const ProbeField q = roundTrip(*makeShL1Q8Codec(), f, &bytes);
  const ProbeField full = roundTrip(*makeShCodec(1), f);
  EXPECT_EQ(bytes, 11u + 4u + 6u * 15u);
  const double e = relativeRms(q.irradiance, full.irradiance), r = relativeRms(q.radiance, full.radiance);
  std::printf("sh_l1_q8 vs sh_l1: irradiance rel RMS %.5f, radiance %.5f\n", e, r);
  EXPECT_LT(e, 0.01);
  EXPECT_LT(r, 0.01);
  EXPECT_GT(e, 0.0);  // it is quantized
  // A black probe stays black, a constant one keeps L1 = 0 exactly.
  ProbeField dark = emptyField(2, 8);
  for (size_t i = dark.radiance.size() / 2; i < dark.radiance.size(); ++i) dark.radiance[i] = 0.75f;
  const ProbeField d = roundTrip(*makeShL1Q8Codec(), dark);
  for (size_t i = 0; i < d.irradiance.size() / 2; ++i) EXPECT_EQ(d.irradiance[i], 0.0f);
  for (size_t i = d.irradiance.size() / 2; i < d.irradiance.size(); ++i)
    EXPECT_NEAR(d.irradiance[i], 0.75f * std::numbers::pi_v<float>, 2e-3f);
}

TEST(ProbeCodecs, PcaRecoversALowRankCellAndMeetsItsTarget) {
  // Rank 3 around a mean: k = 3 components reproduce it to FP16 rounding.
  const int P = 40, n = 8, D = n * n * 3;
  const ProbeField base = skyField(4, n, false, 11);
  ProbeField f = emptyField(P, n);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int p = 0; p < P; ++p) {
    const float w1 = u(rng), w2 = u(rng), w3 = u(rng);
    for (int d = 0; d < D; ++d)
      f.radiance[size_t(p * D + d)] = base.radiance[size_t(d)] + w1 * base.radiance[size_t(D + d)] +
                                      w2 * base.radiance[size_t(2 * D + d)] +
                                      w3 * base.radiance[size_t(3 * D + d)];
  }
  size_t bytes = 0;
  const ProbeField d = roundTrip(*makePcaCodec(1e-4), f, &bytes);
  const double err = relativeRms(d.radiance, f.radiance);
  // header 11 + k 2 + (scale 4 + D halves) mean + (4 + 3 D) basis + (4 + 3 P) coefficients
  EXPECT_EQ(bytes, size_t(11 + 2 + 4 + 2 * D + 4 + 2 * 3 * D + 4 + 2 * 3 * P));
  std::printf("rank-3 cell: relative RMS %.2e with %zu bytes\n", err, bytes);
  EXPECT_LT(err, 2e-3);

  // A full-rank noisy cell: a looser target keeps fewer components, and each meets its target (plus
  // FP16 rounding).
  ProbeField noisy = f;
  std::normal_distribution<float> g(0.0f, 0.05f);
  for (float& v : noisy.radiance) v *= 1.0f + g(rng);
  size_t tightBytes = 0, looseBytes = 0;
  const ProbeField tight = roundTrip(*makePcaCodec(0.01), noisy, &tightBytes);
  const ProbeField loose = roundTrip(*makePcaCodec(0.04), noisy, &looseBytes);
  const double et = relativeRms(tight.radiance, noisy.radiance),
               el = relativeRms(loose.radiance, noisy.radiance);
  std::printf("noisy cell: target 0.01 -> %.4f (%zu B), target 0.04 -> %.4f (%zu B)\n", et, tightBytes, el,
              looseBytes);
  EXPECT_LT(looseBytes, tightBytes);
  EXPECT_LT(et, 0.01 + 1e-3);
  EXPECT_LT(el, 0.04 + 1e-3);
}

// More probes than map values (P > D): the covariance path instead of the Gram path; and an all-black
// cell keeps no component at all.
TEST(ProbeCodecs, PcaCovariancePathAndBlackCell) {
  const int P = 80, n = 4;
  ProbeField f = skyField(P, n, false, 21);
  std::mt19937 rng(9);
  std::normal_distribution<float> g(0.0f, 0.02f);
  for (float& v : f.radiance) v *= 1.0f + g(rng);
  size_t tightBytes = 0, looseBytes = 0;
  const ProbeField tight = roundTrip(*makePcaCodec(0.005), f, &tightBytes);
  const ProbeField loose = roundTrip(*makePcaCodec(0.03), f, &looseBytes);
  const double et = relativeRms(tight.radiance, f.radiance), el = relativeRms(loose.radiance, f.radiance);
  std::printf("P > D cell: target 0.005 -> %.4f (%zu B), target 0.03 -> %.4f (%zu B)\n", et, tightBytes, el,
              looseBytes);
  EXPECT_LT(et, 0.005 + 1e-3);
  EXPECT_LT(el, 0.03 + 1e-3);
  EXPECT_LT(looseBytes, tightBytes);

  const ProbeField black = emptyField(5, 4);
  size_t bytes = 0;
  const ProbeField d = roundTrip(*makePcaCodec(0.01), black, &bytes);
  EXPECT_EQ(bytes, size_t(11 + 2 + 4 + 2 * 48 + 4 + 4));  // k = 0: header, mean, empty basis and coefficients
  for (float v : d.radiance) EXPECT_EQ(v, 0.0f);
}

TEST(ProbeCodecs, AstcHdrBytesAndError) {
  // Smooth maps: the block size sets the error. With a sun texel 10^3 above its neighbours the block
  // holding it dominates the error (printed, bounded loosely).
  const ProbeField smooth = skyField(6, 16, false), sunny = skyField(6, 16, true);
  for (int block : {4, 6, 8}) {
    size_t bytes = 0;
    const ProbeField d = roundTrip(*makeAstcHdrCodec(block, 60.0f), smooth, &bytes);
    const size_t blocks = size_t((16 + block - 1) / block) * size_t((16 + block - 1) / block);
    EXPECT_EQ(bytes, 11u + 1u + 4u + 6u * blocks * 16u);
    const double err = relativeRms(d.radiance, smooth.radiance);
    const double errSun =
        relativeRms(roundTrip(*makeAstcHdrCodec(block, 60.0f), sunny).radiance, sunny.radiance);
    std::printf("astc %dx%d: %zu bytes, radiance rel RMS %.4f smooth, %.4f with a sun texel\n", block, block,
                bytes, err, errSun);
    EXPECT_LT(err, block == 4 ? 0.02 : 0.05);
    EXPECT_LT(errSun, 0.3);
  }
}

TEST(ProbeCodecs, DeriveIrradianceOfConstantIsPi) {
  ProbeField f = emptyField(2, 16);
  std::fill(f.radiance.begin(), f.radiance.end(), 2.0f);
  deriveIrradiance(f);
  ASSERT_EQ(f.irradiance.size(), size_t(2 * 64 * 3));
  // Texel-centre cosines (the capture's own sum) are exact only in the limit: 0.34 % at n = 16.
  for (float e : f.irradiance)
    EXPECT_NEAR(e, 2.0f * std::numbers::pi_v<float>, 0.005f * 2.0f * std::numbers::pi_v<float>);
}

std::vector<std::unique_ptr<ProbeCodec>> allCodecs() {
  std::vector<std::unique_ptr<ProbeCodec>> c;
  c.push_back(makeRawFp16Codec());
  c.push_back(makeZstdFp16Codec(3));
  c.push_back(makeShCodec(2));
  c.push_back(makeShCodec(7));
  c.push_back(makeShL1Q8Codec());
  c.push_back(makePcaCodec(0.05));
  c.push_back(makeAstcHdrCodec(8, 10.0f));
  return c;
}

// meshoptimizer-style: every truncation of a valid encoding is rejected with lfgi::Error, never a crash
// (run under ASan to check that nothing reads past the end).
TEST(ProbeCodecs, EveryTruncationIsRejected) {
  const ProbeField f = skyField(2, 4, true);
  for (const auto& codec : allCodecs()) {
    const std::vector<std::byte> b = codec->encode(f);
    for (size_t len = 0; len < b.size(); ++len) {
      ProbeField out = f;
      EXPECT_THROW(codec->decode(std::span(b.data(), len), out), Error) << codec->name() << " length " << len;
    }
    ProbeField out = f;
    std::vector<std::byte> longer = b;
    longer.push_back(std::byte{0});
    EXPECT_THROW(codec->decode(longer, out), Error) << codec->name() << " trailing byte";
  }
}

TEST(ProbeCodecs, RejectsForeignBytesLayoutMismatchAndBadInput) {
  const ProbeField f = skyField(2, 4, false);
  const auto codecs = allCodecs();
  for (const auto& a : codecs) {
    const std::vector<std::byte> b = a->encode(f);
    for (const auto& other : codecs) {
      if (other->name() == a->name()) continue;
      ProbeField out = f;
      EXPECT_THROW(other->decode(b, out), Error) << a->name() << " bytes read by " << other->name();
    }
    ProbeField wrongCount = emptyField(3, 4);
    EXPECT_THROW(a->decode(b, wrongCount), Error) << a->name();
    ProbeField wrongRes = emptyField(2, 8);
    EXPECT_THROW(a->decode(b, wrongRes), Error) << a->name();
    ProbeField bad = f;
    bad.radiance[5] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(a->encode(bad), Error) << a->name();
    bad.radiance.pop_back();
    EXPECT_THROW(a->encode(bad), Error) << a->name();
  }
  EXPECT_THROW(makeShCodec(8), Error);
  EXPECT_THROW(makePcaCodec(0.0), Error);
  EXPECT_THROW(makeAstcHdrCodec(7, 60.0f), Error);
  EXPECT_THROW(makeZstdFp16Codec(0), Error);
}

}  // namespace
}  // namespace lfgi
