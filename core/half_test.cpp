#include "core/half.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "core/error.h"

namespace lfgi {
namespace {

constexpr std::uint16_t kHalfMaxBits = 0x7bff;

TEST(Half, OverflowClampsToLargestFinite) {
  EXPECT_EQ(floatToHalfClamped(1e6f), kHalfMaxBits);
  EXPECT_EQ(halfToFloat(floatToHalfClamped(1e6f)), 65504.0f);
  EXPECT_EQ(halfToFloat(floatToHalfClamped(-1e6f)), -65504.0f);
  EXPECT_EQ(halfToFloat(floatToHalfClamped(65519.0f)), 65504.0f);  // rounds down, not to Inf
  EXPECT_EQ(halfToFloat(floatToHalfClamped(65520.0f)), 65504.0f);  // would round to Inf unclamped
  EXPECT_EQ(floatToHalfClamped(std::numeric_limits<float>::infinity()), kHalfMaxBits);
  EXPECT_EQ(halfToFloat(floatToHalfClamped(-std::numeric_limits<float>::infinity())), -65504.0f);
  EXPECT_EQ(floatToHalfClamped(std::numeric_limits<float>::quiet_NaN()), 0);
}

TEST(Half, SpanReportsClampedAndNanCounts) {
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<float> in = {1.0f, 1e6f, -1e7f, inf, -inf, std::nanf(""), 0.5f, 65504.0f, 70000.0f};
  std::vector<std::uint16_t> out(in.size());
  const HalfConversionStats stats = floatToHalfClamped(in, out);
  EXPECT_EQ(stats.clamped, 5u);  // 1e6, -1e7, inf, -inf, 70000
  EXPECT_EQ(stats.nanZeroed, 1u);
  EXPECT_EQ(stats.total(), 6u);
  std::vector<float> back(in.size());
  halfToFloat(out, back);
  for (float v : back) EXPECT_TRUE(std::isfinite(v));
  EXPECT_EQ(back[0], 1.0f);
  EXPECT_EQ(back[5], 0.0f);
  EXPECT_EQ(back[7], 65504.0f);
  std::vector<std::uint16_t> small(2);
  EXPECT_THROW(floatToHalfClamped(in, small), Error);
  EXPECT_THROW(halfToFloat(out, std::span<float>(back.data(), 3)), Error);
}

TEST(Half, EveryFiniteHalfRoundTripsExactly) {
  int finite = 0;
  for (std::uint32_t bits = 0; bits < 65536; ++bits) {
    const auto h = static_cast<std::uint16_t>(bits);
    const bool isFinite = (h & 0x7c00) != 0x7c00;
    const float f = halfToFloat(h);
    EXPECT_EQ(std::isfinite(f), isFinite) << std::hex << bits;
    if (!isFinite) continue;
    ++finite;
    ASSERT_EQ(floatToHalfClamped(f), h) << std::hex << bits;
  }
  EXPECT_EQ(finite, 65536 - 2048);
}

TEST(Half, RoundsToNearestEven) {
  // Between 1 and 1 + 2^-10 (the next half), the midpoint 1 + 2^-11 rounds to the even 1.
  EXPECT_EQ(halfToFloat(floatToHalfClamped(1.0f + std::ldexp(1.0f, -11))), 1.0f);
  // Between 1 + 2^-10 (odd mantissa) and 1 + 2^-9, the midpoint rounds up to the even 1 + 2^-9.
  EXPECT_EQ(halfToFloat(floatToHalfClamped(1.0f + 3.0f * std::ldexp(1.0f, -11))),
            1.0f + std::ldexp(1.0f, -9));
  EXPECT_EQ(halfToFloat(floatToHalfClamped(1.0f + std::ldexp(1.0f, -11) + std::ldexp(1.0f, -20))),
            1.0f + std::ldexp(1.0f, -10));
  // Smallest subnormal half is kept, not flushed.
  EXPECT_EQ(halfToFloat(floatToHalfClamped(std::ldexp(1.0f, -24))), std::ldexp(1.0f, -24));
}

}  // namespace
}  // namespace lfgi
