#include "core/hash.h"

#include <gtest/gtest.h>

#include <string_view>

namespace lfgi {
namespace {

uint64_t fnvOf(std::string_view s) {
  return fnv1a(kFnv1aOffset, s.data(), s.size());
}

// Published FNV-1a 64-bit test vectors (www.isthe.com/chongo/tech/comp/fnv).
TEST(Hash, Fnv1aMatchesTheReferenceVectors) {
  EXPECT_EQ(fnvOf(""), 0xcbf29ce484222325ull);
  EXPECT_EQ(fnvOf("a"), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(fnvOf("foobar"), 0x85944171f73967e8ull);
}

TEST(Hash, Fnv1aFoldsIncrementally) {
  EXPECT_EQ(fnv1a(fnvOf("foo"), "bar", 3), fnvOf("foobar"));
  const uint32_t v = 0x64636261u;  // "abcd" in little-endian memory
  EXPECT_EQ(fnv1aValue(kFnv1aOffset, v), fnvOf("abcd"));
}

TEST(Hash, Fnv1aSpanSeparatesBoundaries) {
  const std::vector<uint8_t> ab = {1, 2}, a = {1}, b = {2};
  const uint64_t joined = fnv1aSpan(kFnv1aOffset, ab);
  const uint64_t split = fnv1aSpan(fnv1aSpan(kFnv1aOffset, a), b);
  EXPECT_NE(joined, split);
  EXPECT_EQ(joined, fnv1a(fnv1aValue(kFnv1aOffset, uint64_t(2)), ab.data(), 2));
}

// splitmix64 seeded with 0 (Vigna's reference implementation) starts e220a8397b1dcdaf, 6e789e6aa1b965f4.
TEST(Hash, Splitmix64MatchesTheReferenceStream) {
  static_assert(splitmix64(0) == 0xe220a8397b1dcdafull);
  EXPECT_EQ(splitmix64(kGoldenGamma), 0x6e789e6aa1b965f4ull);
  EXPECT_EQ(splitmix64Finalize(0), 0u);
}

TEST(Hash, UnitDoubleSpansTheHalfOpenInterval) {
  EXPECT_EQ(unitDouble(0), 0.0);
  EXPECT_LT(unitDouble(~0ull), 1.0);
  EXPECT_GT(unitDouble(~0ull), 1.0 - 1e-15);
}

}  // namespace
}  // namespace lfgi
