// Error metrics between a test signal a and a reference b, over flat float spans (images, probe maps,
// SH coefficients). Sums run in double. Every function throws lfgi::Error (naming itself) if the spans
// differ in size or are empty; NaN in either input propagates to the result.
#pragma once

#include <span>

namespace lfgi {

// sqrt(sum (a - b)^2 / sum b^2): the project's headline error (docs/DESIGN.md §5, "<= 5 % relative RMS").
// 0 if both are all zero; +Inf if only the reference is all zero.
double relativeRms(std::span<const float> a, std::span<const float> reference);

// sqrt(mean (a - b)^2), in the unit of the inputs.
double rmse(std::span<const float> a, std::span<const float> reference);

// 10 log10(peak^2 / mean (a - b)^2) in dB, for a stated peak value (e.g. 1 for display-referred [0, 1]
// data, or the reference's maximum for HDR data). +Inf if identical. Throws if peak <= 0 or not finite.
double psnr(std::span<const float> a, std::span<const float> reference, double peak);

// max |a - b|, in the unit of the inputs.
double maxAbsError(std::span<const float> a, std::span<const float> reference);

}  // namespace lfgi
