// FP16 storage with the project's overflow rule (docs/DESIGN.md §2): radiance spans 10^4-10^5 between sun and
// interior, and an FP16 Inf or NaN in a probe map poisons every bilinear tap and SH projection that
// touches it. So conversion never produces Inf or NaN: finite overflow and +-Inf clamp to +-65504 (the
// largest finite half), NaN becomes 0, and the number of such values is returned so the caller can
// report it (or pre-scale by a per-cell exposure instead).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace lfgi {

inline constexpr float kHalfMax = 65504.0f;

// float -> IEEE 754 binary16 bits, round to nearest even (Imath::half after clamping). |f| > 65504
// (including +-Inf) gives +-65504; NaN gives +0. Subnormal halves are produced, not flushed.
std::uint16_t floatToHalfClamped(float f);

// binary16 bits -> float (exact; every half is representable as a float, Inf and NaN included).
float halfToFloat(std::uint16_t bits);

// What a span conversion changed beyond rounding.
struct HalfConversionStats {
  std::size_t clamped = 0;    // finite |f| > 65504 or +-Inf, stored as +-65504
  std::size_t nanZeroed = 0;  // NaN, stored as 0
  std::size_t total() const { return clamped + nanZeroed; }
};

// Converts in[i] to out[i]. Throws lfgi::Error if the sizes differ.
HalfConversionStats floatToHalfClamped(std::span<const float> in, std::span<std::uint16_t> out);
void halfToFloat(std::span<const std::uint16_t> in, std::span<float> out);

}  // namespace lfgi
