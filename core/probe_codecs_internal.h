// Shared pieces of the baseline probe codecs (core/probe_codecs.h): bounds-checked little-endian byte
// writing/reading, the common header and FP16 arrays with a power-of-two exposure scale. Not a public
// interface: only the probe_codec*.cpp files include it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/probe_field.h"

namespace lfgi::codec_detail {

// Host byte order is little-endian on every platform lfgi builds for (x86-64, arm64).
struct ByteWriter {
  std::vector<std::byte> bytes;
  void u8(uint8_t v);
  void u16(uint16_t v);
  void u32(uint32_t v);
  void f32(float v);
  void raw(const void* p, size_t n);
  // f32 scale (exposureScale of values) then values / scale as FP16 (core/half.h clamping).
  void halves(std::span<const float> values);
};

// Every read checks the remaining length first and throws lfgi::Error naming `codec` and the field.
struct ByteReader {
  std::span<const std::byte> data;
  const char* codec;
  size_t pos = 0;
  const std::byte* take(size_t n, const char* what);
  uint8_t u8(const char* what);
  uint16_t u16(const char* what);
  uint32_t u32(const char* what);
  float f32(const char* what);
  // Reads what ByteWriter::halves wrote into out (out.size() values); rejects a bad scale and Inf/NaN.
  void halves(std::span<float> out, const char* what);
  void expectEnd() const;
};

// Power of two that maps max |values| into [2^13, 2^14] (1 for an all-zero span).
float exposureScale(std::span<const float> values);

// magic[4] | u8 version | u16 resolution | u32 probes  (11 bytes)
struct Header {
  char magic[4];
  uint8_t version = 1;
  int resolution = 0;
  uint32_t probes = 0;
};
void writeHeader(ByteWriter& w, const Header& h);
// Reads and checks the header against the expected magic/version and out's resolution and probe count.
Header readHeader(ByteReader& r, const char magic[4], uint8_t version, const ProbeField& out);

// Throws unless f's resolution, probe count and radiance size agree and every radiance value is finite.
void checkField(const char* codec, const ProbeField& f);
// Sizes out.radiance for out's grid and resolution (zeros) and clears out.irradiance.
void prepareOut(ProbeField& out);

}  // namespace lfgi::codec_detail
