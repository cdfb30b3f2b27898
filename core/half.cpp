#include "core/half.h"

#include <Imath/half.h>

#include <cmath>

#include "core/error.h"

namespace lfgi {

namespace {

enum class Scrub { kNone, kClamped, kNan };

std::uint16_t convert(float f, Scrub& scrub) {
  scrub = Scrub::kNone;
  if (std::isnan(f)) {
    scrub = Scrub::kNan;
    f = 0.0f;
  } else if (std::abs(f) > kHalfMax) {
    scrub = Scrub::kClamped;
    f = std::copysign(kHalfMax, f);
  }
  return Imath::half(f).bits();
}

}  // namespace

std::uint16_t floatToHalfClamped(float f) {
  Scrub ignored;
  return convert(f, ignored);
}

float halfToFloat(std::uint16_t bits) {
  Imath::half h;
  h.setBits(bits);
  return static_cast<float>(h);
}

HalfConversionStats floatToHalfClamped(std::span<const float> in, std::span<std::uint16_t> out) {
  if (in.size() != out.size())
    fail("floatToHalfClamped: {} input floats but room for {} halves", in.size(), out.size());
  HalfConversionStats stats;
  for (std::size_t i = 0; i < in.size(); ++i) {
    Scrub scrub;
    out[i] = convert(in[i], scrub);
    stats.clamped += scrub == Scrub::kClamped;
    stats.nanZeroed += scrub == Scrub::kNan;
  }
  return stats;
}

void halfToFloat(std::span<const std::uint16_t> in, std::span<float> out) {
  if (in.size() != out.size())
    fail("halfToFloat: {} input halves but room for {} floats", in.size(), out.size());
  for (std::size_t i = 0; i < in.size(); ++i) out[i] = halfToFloat(in[i]);
}

}  // namespace lfgi
