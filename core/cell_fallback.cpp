#include "core/cell_fallback.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/half.h"
#include "core/octahedral.h"

namespace lfgi {

ShL1 shFromHalves(const uint16_t* h) {
  ShL1 sh;
  for (int k = 0; k < 4; ++k)
    for (int c = 0; c < 3; ++c) sh.c[size_t(k)][c] = halfToFloat(h[k * 3 + c]);
  return sh;
}

void shProbeMaps(const ShL1& sh, int n, int m, float* radiance, float* irradiance) {
  if (radiance)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const glm::vec3 L = glm::max(shEvaluate(sh, octTexelDirection(i, j, n)), glm::vec3(0.0f));
        float* o = radiance + size_t(j * n + i) * 3;
        o[0] = L.x, o[1] = L.y, o[2] = L.z;
      }
  if (irradiance)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const glm::vec3 E = glm::max(shIrradiance(sh, octTexelDirection(i, j, m)), glm::vec3(0.0f));
        float* o = irradiance + size_t(j * m + i) * 3;
        o[0] = E.x, o[1] = E.y, o[2] = E.z;
      }
}

ShL1 shLerp(const ShL1& a, const ShL1& b, float t) {
  ShL1 out;
  for (int k = 0; k < 4; ++k) out.c[size_t(k)] = a.c[size_t(k)] * (1.0f - t) + b.c[size_t(k)] * t;
  return out;
}

FallbackKeyBlend fallbackKeyBlend(const CellFallback& f, float timeOfDayHours, float weather) {
  const size_t K = std::min(f.keyHours.size(), f.keyOvercast.size());
  if (K == 0) return {};
  // The overcast value nearest to `weather` (ties: the lower), then the keys at it (ascending hours).
  float best = f.keyOvercast[0];
  for (size_t k = 1; k < K; ++k) {
    const float d = std::fabs(f.keyOvercast[k] - weather), db = std::fabs(best - weather);
    if (d < db || (d == db && f.keyOvercast[k] < best)) best = f.keyOvercast[k];
  }
  constexpr size_t npos = size_t(-1);
  size_t first = npos, last = npos, lo = npos, hi = npos;
  for (size_t k = 0; k < K; ++k) {
    if (f.keyOvercast[k] != best) continue;
    if (first == npos) first = k;
    last = k;
    if (f.keyHours[k] <= timeOfDayHours) lo = k;
    if (f.keyHours[k] >= timeOfDayHours && hi == npos) hi = k;
  }
  if (lo == npos) return {first, first, 0.0f};  // before the first key (or NaN hours): clamped
  if (hi == npos) return {last, last, 0.0f};    // after the last key: clamped
  if (lo == hi) return {lo, lo, 0.0f};
  const float t = (timeOfDayHours - f.keyHours[lo]) / (f.keyHours[hi] - f.keyHours[lo]);
  return {lo, hi, std::clamp(t, 0.0f, 1.0f)};
}

ShL1 fallbackEntry(const CellFallback& f, size_t entries, size_t entry, const FallbackKeyBlend& blend) {
  const ShL1 a = shFromHalves(f.shHalf.data() + (blend.a * entries + entry) * 12);
  if (blend.a == blend.b || blend.t == 0.0f) return a;
  const ShL1 b = shFromHalves(f.shHalf.data() + (blend.b * entries + entry) * 12);
  return shLerp(a, b, blend.t);
}

size_t fallbackEntries(const CellFile& cell) {
  const size_t keys = cell.fallback.keyCount();
  const size_t entries = keys ? cell.fallback.shHalf.size() / 12 / keys : 0;
  if (entries == 0) fail("cell {},{}: no fallback SH", cell.cellX, cell.cellZ);
  return cell.fallback.kind == CellFallback::Kind::PerCell ? 1 : entries;
}

// Key `key`'s cell SH: the per-cell entry, or the mean of the per-probe entries.
ShL1 cellKeySh(const CellFile& cell, size_t entries, size_t key) {
  const uint16_t* h = cell.fallback.shHalf.data() + key * entries * 12;
  if (entries == 1) return shFromHalves(h);
  ShL1 mean;
  for (size_t e = 0; e < entries; ++e) {
    const ShL1 sh = shFromHalves(h + e * 12);
    for (int k = 0; k < 4; ++k) mean.c[size_t(k)] += sh.c[size_t(k)];
  }
  for (glm::vec3& c : mean.c) c /= float(entries);
  return mean;
}

ShL1 cellFileFallback(const CellFile& cell, float timeOfDayHours, float weather) {
  const size_t entries = fallbackEntries(cell);
  const FallbackKeyBlend blend = fallbackKeyBlend(cell.fallback, timeOfDayHours, weather);
  const ShL1 a = cellKeySh(cell, entries, blend.a);
  if (blend.a == blend.b || blend.t == 0.0f) return a;
  const ShL1 b = cellKeySh(cell, entries, blend.b);
  return shLerp(a, b, blend.t);
}

}  // namespace lfgi
