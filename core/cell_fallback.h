// The streaming fallback stored in a cell file (core/cell_file.h CellFallback: SH L1 radiance per
// lighting key, per cell or per probe) evaluated at a time of day and weather. Pure functions on a read
// (valid) cell file, shared by the streaming source and the offline probe sources.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/cell_file.h"
#include "core/sh.h"

namespace lfgi {

// 12 FP16 halves (core/sh.h ShL1 order, rgb innermost) -> ShL1.
ShL1 shFromHalves(const uint16_t* h);
// (1 - t) a + t b, coefficient by coefficient (the blend between two lighting keys).
ShL1 shLerp(const ShL1& a, const ShL1& b, float t);

// Which stored fallback keys give the fallback at (timeOfDayHours, weather): the keys at the overcast
// nearest to `weather` (ties: the lower overcast), of which the two bracketing timeOfDayHours, SH =
// (1 - t) key a + t key b; before the first / after the last of them: that key alone (a = b, t = 0).
struct FallbackKeyBlend {
  size_t a = 0, b = 0;
  float t = 0.0f;
};
FallbackKeyBlend fallbackKeyBlend(const CellFallback& fallback, float timeOfDayHours, float weather);
// Entry `entry` (of `entries` per key) of the fallback blended between the keys.
ShL1 fallbackEntry(const CellFallback& fallback, size_t entries, size_t entry, const FallbackKeyBlend& blend);

// What a probe of SH L1 radiance `sh` gives shading: radiance at the n x n octahedral texel centres (skipped
// when radiance is null) and irradiance, the SH's cosine convolution, at the m x m texel centres (skipped
// when irradiance is null), both clamped at 0, rgb interleaved.
void shProbeMaps(const ShL1& sh, int n, int m, float* radiance, float* irradiance);

// The cell's SH L1 fallback at (timeOfDayHours, weather): per key the per-cell entry, or the mean of the
// per-probe entries, blended by fallbackKeyBlend (cell.fallback must be valid, as readCellFile
// guarantees).
ShL1 cellFileFallback(const CellFile& cell, float timeOfDayHours, float weather);
// Entries per key: 1 for a per-cell fallback, the active probe count for a per-probe one (throws
// lfgi::Error naming the cell when it holds none).
size_t fallbackEntries(const CellFile& cell);
// Key `key`'s cell SH: the per-cell entry, or the mean of the per-probe entries.
ShL1 cellKeySh(const CellFile& cell, size_t entries, size_t key);

}  // namespace lfgi
