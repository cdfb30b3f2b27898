#include "core/sh_l1_q8.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/half.h"

namespace lfgi {

namespace {

constexpr float kSqrt3 = 1.7320508f;
constexpr float kMinNormalHalf = 6.103515625e-05f;  // 2^-14

float canonicalL0(float l0) {
  if (!(l0 >= kMinNormalHalf)) return 0.0f;  // negative, NaN, zero or subnormal
  return std::min(l0, kShL1Q8MaxL0);
}

}  // namespace

int8_t shL1Q8Code(float l0, float l1) {
  if (!(l0 > 0.0f) || !std::isfinite(l0) || !std::isfinite(l1)) return 0;
  const float ratio = std::clamp(l1 / (kSqrt3 * l0), -1.0f, 1.0f);
  return int8_t(std::lround(ratio * 127.0f));
}

float shL1Q8Value(float l0, int8_t code) {
  if (!(l0 > 0.0f) || code == 0) return 0.0f;
  return float(code) / 127.0f * kSqrt3 * l0;
}

void quantizeShL1HalvesQ8(uint16_t* h) {
  for (int ch = 0; ch < 3; ++ch) {
    const float l0 = halfToFloat(floatToHalfClamped(canonicalL0(halfToFloat(h[ch]))));
    h[ch] = floatToHalfClamped(l0);
    for (int k = 1; k < 4; ++k) {
      uint16_t& l1 = h[3 * k + ch];
      l1 = floatToHalfClamped(shL1Q8Value(l0, shL1Q8Code(l0, halfToFloat(l1))));
    }
  }
}

bool shL1HalvesAreQ8(const uint16_t* h) {
  uint16_t q[12];
  std::memcpy(q, h, sizeof q);
  quantizeShL1HalvesQ8(q);
  return std::memcmp(q, h, sizeof q) == 0;
}

void packShL1Q8(const uint16_t* h, uint8_t* bytes) {
  for (int ch = 0; ch < 3; ++ch) {
    bytes[2 * ch] = uint8_t(h[ch] & 0xffu);
    bytes[2 * ch + 1] = uint8_t(h[ch] >> 8);
  }
  for (int k = 1; k < 4; ++k)
    for (int ch = 0; ch < 3; ++ch)
      bytes[6 + 3 * (k - 1) + ch] = uint8_t(shL1Q8Code(halfToFloat(h[ch]), halfToFloat(h[3 * k + ch])));
}

bool unpackShL1Q8(const uint8_t* bytes, uint16_t* h) {
  for (int ch = 0; ch < 3; ++ch) h[ch] = uint16_t(bytes[2 * ch] | (bytes[2 * ch + 1] << 8));
  for (int k = 1; k < 4; ++k)
    for (int ch = 0; ch < 3; ++ch) {
      const int8_t code = int8_t(bytes[6 + 3 * (k - 1) + ch]);
      const float l0 = halfToFloat(h[ch]);
      if (code == -128 || (code != 0 && !(l0 > 0.0f))) return false;
      h[3 * k + ch] = floatToHalfClamped(shL1Q8Value(l0, code));
    }
  return true;
}

}  // namespace lfgi
