#include "core/byte_stream.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/error.h"

namespace lfgi {
namespace {

TEST(ByteStream, EveryFieldRoundTripsExactlyAndTheEndIsChecked) {
  ByteWriter w;
  w.u8(0xAB);
  w.i8(-7);
  w.u16(0xBEEF);
  w.u32(0xDEADBEEFu);
  w.u64(0x0123456789ABCDEFull);
  w.f32(-1.5e-3f);
  const std::vector<float> values = {0.0f, 1.0f, -2.5f, 1000.0f, 3.0e-3f};
  w.halves(values);
  // 1 + 1 + 2 + 4 + 8 + 4 bytes of fields, then the f32 scale and one FP16 per value.
  ASSERT_EQ(w.bytes.size(), size_t(20 + 4 + 2 * values.size()));

  ByteReader r{w.bytes, "test"};
  EXPECT_EQ(r.u8("a"), 0xAB);
  EXPECT_EQ(r.i8("b"), -7);
  EXPECT_EQ(r.u16("c"), 0xBEEF);
  EXPECT_EQ(r.u32("d"), 0xDEADBEEFu);
  EXPECT_EQ(r.u64("e"), 0x0123456789ABCDEFull);
  EXPECT_EQ(r.f32("f"), -1.5e-3f);
  std::vector<float> back(values.size());
  r.halves(back, "g");
  for (size_t i = 0; i < values.size(); ++i)  // FP16: 11 significant bits
    EXPECT_NEAR(back[i], values[i], std::abs(values[i]) * 1e-3f + 1e-6f) << i;
  EXPECT_NO_THROW(r.expectEnd());
}

TEST(ByteStream, TruncationTrailingBytesAndBadHalvesNameTheCodecAndField) {
  ByteWriter w;
  w.u32(5);
  const auto message = [](auto&& read) {
    try {
      read();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ByteReader shortRead{w.bytes, "demo"};
  const std::string truncated = message([&] { shortRead.u64("count"); });
  EXPECT_NE(truncated.find("demo decode: truncated input: count needs 8 bytes"), std::string::npos)
      << truncated;
  EXPECT_EQ(shortRead.pos, 0u);  // a failed read consumes nothing

  ByteReader trailing{w.bytes, "demo"};
  trailing.u8("first");
  EXPECT_NE(message([&] { trailing.expectEnd(); }).find("3 trailing bytes"), std::string::npos);

  ByteWriter bad;
  bad.f32(std::numeric_limits<float>::quiet_NaN());  // the scale of a halves array
  bad.u16(0);
  ByteReader badScale{bad.bytes, "demo"};
  std::vector<float> one(1);
  EXPECT_NE(message([&] { badScale.halves(one, "radiance"); }).find("radiance scale"), std::string::npos);

  ByteWriter inf;
  inf.f32(1.0f);
  inf.u16(0x7C00);  // +Inf as FP16
  ByteReader infValue{inf.bytes, "demo"};
  EXPECT_NE(message([&] { infValue.halves(one, "radiance"); }).find("is not finite"), std::string::npos);
}

TEST(ByteStream, ExposureScaleIsAPowerOfTwoPlacingTheMaximumIn2To13And2To14) {
  for (float maxAbs : {1e-6f, 0.3f, 1.0f, 12345.0f, 6.0e7f}) {
    const std::vector<float> v = {0.5f * maxAbs, -maxAbs};
    const float s = exposureScale(v);
    int e = 0;
    EXPECT_EQ(std::frexp(s, &e), 0.5f) << maxAbs;  // a power of two
    EXPECT_GE(maxAbs / s, 8192.0f) << maxAbs;
    EXPECT_LE(maxAbs / s, 16384.0f) << maxAbs;
  }
  EXPECT_EQ(exposureScale(std::vector<float>{0.0f, 0.0f}), 1.0f);
}

}  // namespace
}  // namespace lfgi
