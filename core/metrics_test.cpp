#include "core/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "core/error.h"

namespace lfgi {
namespace {

TEST(Metrics, IdenticalIsZeroError) {
  const std::vector<float> a = {1.0f, -2.0f, 3.5f, 0.0f};
  EXPECT_EQ(relativeRms(a, a), 0.0);
  EXPECT_EQ(rmse(a, a), 0.0);
  EXPECT_EQ(maxAbsError(a, a), 0.0);
  EXPECT_EQ(psnr(a, a, 1.0), std::numeric_limits<double>::infinity());
}

TEST(Metrics, KnownValues) {
  const std::vector<float> ref = {3.0f, 4.0f, 0.0f, 0.0f};  // sum of squares 25
  const std::vector<float> offset = {3.5f, 4.5f, 0.5f, 0.5f};
  EXPECT_DOUBLE_EQ(rmse(offset, ref), 0.5);
  EXPECT_DOUBLE_EQ(relativeRms(offset, ref), std::sqrt(4 * 0.25 / 25.0));  // 0.2
  EXPECT_DOUBLE_EQ(maxAbsError(offset, ref), 0.5);
  EXPECT_NEAR(psnr(offset, ref, 1.0), 10.0 * std::log10(1.0 / 0.25), 1e-12);  // 6.0206 dB
  EXPECT_NEAR(psnr(offset, ref, 255.0), 20.0 * std::log10(255.0 / 0.5), 1e-12);
  const std::vector<float> spike = {3.0f, 4.0f, 0.0f, -2.0f};
  EXPECT_DOUBLE_EQ(maxAbsError(spike, ref), 2.0);
  EXPECT_DOUBLE_EQ(rmse(spike, ref), 1.0);
}

TEST(Metrics, RejectsMismatchedAndEmptyInput) {
  const std::vector<float> a(4, 1.0f), b(5, 1.0f), empty;
  EXPECT_THROW(relativeRms(a, b), Error);
  EXPECT_THROW(rmse(a, b), Error);
  EXPECT_THROW(psnr(a, b, 1.0), Error);
  EXPECT_THROW(maxAbsError(a, b), Error);
  EXPECT_THROW(rmse(empty, empty), Error);
  EXPECT_THROW(psnr(a, a, 0.0), Error);
  try {
    rmse(a, b);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rmse"), std::string::npos);
  }
}

TEST(Metrics, ZeroReference) {
  const std::vector<float> zero(3, 0.0f), one(3, 1.0f);
  EXPECT_EQ(relativeRms(zero, zero), 0.0);
  EXPECT_EQ(relativeRms(one, zero), std::numeric_limits<double>::infinity());
}

}  // namespace
}  // namespace lfgi
