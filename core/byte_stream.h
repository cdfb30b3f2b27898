// Bounds-checked little-endian byte strings: what the probe codecs (core/probe_codecs.h) and the bench's
// per-cell codec layouts write and read. Host byte order is little-endian on every platform lfgi builds for
// (x86-64, arm64), so values are copied as stored in memory.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace lfgi {

struct ByteWriter {
  std::vector<std::byte> bytes;
  void u8(uint8_t v);
  void i8(int8_t v) { u8(uint8_t(v)); }
  void u16(uint16_t v);
  void u32(uint32_t v);
  void u64(uint64_t v);
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
  int8_t i8(const char* what) { return int8_t(u8(what)); }
  uint16_t u16(const char* what);
  uint32_t u32(const char* what);
  uint64_t u64(const char* what);
  float f32(const char* what);
  // Reads what ByteWriter::halves wrote into out (out.size() values); rejects a bad scale and Inf/NaN.
  void halves(std::span<float> out, const char* what);
  void expectEnd() const;
};

// Power of two that maps max |values| into [2^13, 2^14] (1 for an all-zero span).
float exposureScale(std::span<const float> values);

}  // namespace lfgi
