// SH L1 in Unity APV's split: L0 as is, each L1 coefficient as L1 / (sqrt(3) L0) in int8 snorm (|L1| <=
// sqrt(3) L0 for any radiance >= 0, so the ratio fits [-1, 1]). The one definition of that quantizer, used
// by the sh_l1_q8 probe codec (core/probe_codecs.h) and the cell file's int8 fallback (core/cell_file.h
// CellFallback::Precision::L1Int8).
#pragma once

#include <cstdint>

namespace lfgi {

// round(clamp(l1 / (sqrt(3) l0), -1, 1) * 127); 0 when l0 <= 0 (or either is not finite).
int8_t shL1Q8Code(float l0, float l1);
// code / 127 * sqrt(3) * l0; exactly +0 when l0 <= 0 or code is 0.
float shL1Q8Value(float l0, int8_t code);

// One SH L1 entry as 12 FP16 halves (core/sh.h ShL1 order, rgb innermost) in the int8 layout: per channel
// L0 clamped to [0, kShL1Q8MaxL0] and flushed to +0 below the smallest normal half (so every code maps
// to a distinct half and back), each L1 replaced by the half its code decodes to. The result is a fixed
// point: quantizing it again changes no bit (shL1HalvesAreQ8 is that test).
inline constexpr float kShL1Q8MaxL0 = 32768.0f;  // sqrt(3) * 32768 stays below the largest half
void quantizeShL1HalvesQ8(uint16_t* halves);
bool shL1HalvesAreQ8(const uint16_t* halves);

// The 15 stored bytes of an entry that shL1HalvesAreQ8: L0 as 3 halves (little-endian), then the 9 L1
// codes (coefficient k = 1..3, rgb innermost); and back (false when a code is -128 or nonzero against a
// zero L0: bytes this writer never produces).
inline constexpr int kShL1Q8Bytes = 15;
void packShL1Q8(const uint16_t* halves, uint8_t* bytes);
bool unpackShL1Q8(const uint8_t* bytes, uint16_t* halves);

}  // namespace lfgi
