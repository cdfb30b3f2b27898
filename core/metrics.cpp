#include "core/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace lfgi {

namespace {

void checkSizes(const char* what, std::span<const float> a, std::span<const float> b) {
  if (a.size() != b.size())
    fail("{}: size mismatch ({} values vs {} in the reference)", what, a.size(), b.size());
  if (a.empty()) fail("{}: no values to compare", what);
}

double sumSquaredError(std::span<const float> a, std::span<const float> b) {
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = double(a[i]) - double(b[i]);
    sum += d * d;
  }
  return sum;
}

}  // namespace

double relativeRms(std::span<const float> a, std::span<const float> reference) {
  checkSizes("relativeRms", a, reference);
  double energy = 0.0;
  for (float b : reference) energy += double(b) * double(b);
  const double error = sumSquaredError(a, reference);
  if (energy == 0.0) return error == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
  return std::sqrt(error / energy);
}

double rmse(std::span<const float> a, std::span<const float> reference) {
  checkSizes("rmse", a, reference);
  return std::sqrt(sumSquaredError(a, reference) / double(a.size()));
}

double psnr(std::span<const float> a, std::span<const float> reference, double peak) {
  checkSizes("psnr", a, reference);
  if (!(peak > 0.0) || !std::isfinite(peak)) fail("psnr: peak {} must be finite and > 0", peak);
  const double mse = sumSquaredError(a, reference) / double(a.size());
  if (mse == 0.0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(peak * peak / mse);
}

double maxAbsError(std::span<const float> a, std::span<const float> reference) {
  checkSizes("maxAbsError", a, reference);
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = std::abs(double(a[i]) - double(reference[i]));
    if (std::isnan(d)) return d;
    worst = std::max(worst, d);
  }
  return worst;
}

}  // namespace lfgi
