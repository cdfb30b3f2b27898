#include "core/sh_l1_q8.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "core/half.h"

namespace lfgi {
namespace {

// Every code against every L0 half the int8 layout keeps (+0 and the normal halves up to kShL1Q8MaxL0):
// the half a code decodes to encodes to the same code, so the layout round-trips bit-exact.
TEST(ShL1Q8, EveryCodeRoundTripsAtEveryKeptL0) {
  int checked = 0;
  for (uint32_t bits = 0; bits < 0x7c00u; ++bits) {
    const float l0 = halfToFloat(uint16_t(bits));
    if (l0 != 0.0f && (l0 < 6.103515625e-05f || l0 > kShL1Q8MaxL0)) continue;
    for (int code = -127; code <= 127; ++code) {
      const uint16_t h = floatToHalfClamped(shL1Q8Value(l0, int8_t(code)));
      ASSERT_NE(h & 0x7c00u, 0x7c00u) << l0 << " " << code;  // finite
      const int want = l0 > 0.0f ? code : 0;
      ASSERT_EQ(shL1Q8Code(l0, halfToFloat(h)), want) << "L0 " << l0 << " code " << code;
      ++checked;
    }
  }
  EXPECT_GT(checked, 7'000'000);
}

TEST(ShL1Q8, CodesAreTheClampedRatio) {
  EXPECT_EQ(shL1Q8Code(1.0f, 1.7320508f), 127);
  EXPECT_EQ(shL1Q8Code(1.0f, -10.0f), -127);           // clamped, never -128
  EXPECT_EQ(shL1Q8Code(2.0f, 0.5f * 1.7320508f), 32);  // 0.25 * 127 = 31.75
  EXPECT_EQ(shL1Q8Code(0.0f, 1.0f), 0);
  EXPECT_EQ(shL1Q8Code(-1.0f, 1.0f), 0);
  EXPECT_EQ(shL1Q8Code(1.0f, std::nanf("")), 0);
  EXPECT_EQ(shL1Q8Value(0.0f, 5), 0.0f);
  EXPECT_FALSE(std::signbit(shL1Q8Value(0.0f, -5)));
  EXPECT_FLOAT_EQ(shL1Q8Value(2.0f, 127), 2.0f * 1.7320508f);
}

// Quantizing random entries (radiance-like L0 over 8 decades, negative and subnormal L0 included) gives a
// fixed point within half a code (and an FP16 rounding) of the input, and pack / unpack restores it bit for
// bit in 15 bytes.
TEST(ShL1Q8, QuantizedEntriesPackIntoFifteenBytesExactly) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), e(-7.0f, 4.3f);
  for (int trial = 0; trial < 20000; ++trial) {
    uint16_t h[12];
    float f[12];
    for (int ch = 0; ch < 3; ++ch) f[ch] = trial % 97 == 0 ? -0.5f : std::pow(10.0f, e(rng));
    for (int i = 3; i < 12; ++i) f[i] = u(rng) * 1.7320508f * f[i % 3];
    for (int i = 0; i < 12; ++i) h[i] = floatToHalfClamped(f[i]);
    const bool wasQ8 = shL1HalvesAreQ8(h);
    uint16_t q[12];
    std::memcpy(q, h, sizeof q);
    quantizeShL1HalvesQ8(q);
    ASSERT_TRUE(shL1HalvesAreQ8(q));
    if (wasQ8) {
      ASSERT_EQ(std::memcmp(q, h, sizeof q), 0);
    }
    for (int i = 3; i < 12; ++i) {
      const float l0 = halfToFloat(q[i % 3]), step = 1.7320508f * l0 / 127.0f;
      if (l0 > 0.0f) {
        const float in = halfToFloat(h[i]);  // half a code, plus the decoded value's own FP16 rounding
        ASSERT_LE(std::abs(halfToFloat(q[i]) - in), 0.5f * step + std::abs(in) / 1024.0f + 6e-8f) << i;
      }
    }
    uint8_t bytes[kShL1Q8Bytes];
    packShL1Q8(q, bytes);
    uint16_t back[12];
    ASSERT_TRUE(unpackShL1Q8(bytes, back));
    ASSERT_EQ(std::memcmp(back, q, sizeof q), 0) << trial;
  }
}

TEST(ShL1Q8, UnpackRejectsBytesTheWriterNeverProduces) {
  uint16_t h[12] = {};
  h[0] = h[1] = h[2] = floatToHalfClamped(1.0f);
  uint8_t bytes[kShL1Q8Bytes];
  packShL1Q8(h, bytes);
  uint16_t back[12];
  ASSERT_TRUE(unpackShL1Q8(bytes, back));
  bytes[6] = 0x80;  // code -128
  EXPECT_FALSE(unpackShL1Q8(bytes, back));
  bytes[6] = 5;
  bytes[0] = bytes[1] = 0;  // L0 red = 0 with a nonzero red L1 code
  EXPECT_FALSE(unpackShL1Q8(bytes, back));
}

}  // namespace
}  // namespace lfgi
