#include "core/byte_stream.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "core/half.h"

namespace lfgi {

void ByteWriter::u8(uint8_t v) {
  bytes.push_back(std::byte(v));
}
void ByteWriter::u16(uint16_t v) {
  raw(&v, 2);
}
void ByteWriter::u32(uint32_t v) {
  raw(&v, 4);
}
void ByteWriter::u64(uint64_t v) {
  raw(&v, 8);
}
void ByteWriter::f32(float v) {
  raw(&v, 4);
}
void ByteWriter::raw(const void* p, size_t n) {
  const auto* b = static_cast<const std::byte*>(p);
  bytes.insert(bytes.end(), b, b + n);
}

void ByteWriter::halves(std::span<const float> values) {
  const float scale = exposureScale(values);
  f32(scale);
  const size_t at = bytes.size();
  bytes.resize(at + 2 * values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    const uint16_t h = floatToHalfClamped(values[i] / scale);
    std::memcpy(bytes.data() + at + 2 * i, &h, 2);
  }
}

const std::byte* ByteReader::take(size_t n, const char* what) {
  if (n > data.size() - pos)
    fail("{} decode: truncated input: {} needs {} bytes at offset {}, only {} left", codec, what, n, pos,
         data.size() - pos);
  const std::byte* p = data.data() + pos;
  pos += n;
  return p;
}
uint8_t ByteReader::u8(const char* what) {
  return uint8_t(*take(1, what));
}
uint16_t ByteReader::u16(const char* what) {
  uint16_t v;
  std::memcpy(&v, take(2, what), 2);
  return v;
}
uint32_t ByteReader::u32(const char* what) {
  uint32_t v;
  std::memcpy(&v, take(4, what), 4);
  return v;
}
uint64_t ByteReader::u64(const char* what) {
  uint64_t v;
  std::memcpy(&v, take(8, what), 8);
  return v;
}
float ByteReader::f32(const char* what) {
  float v;
  std::memcpy(&v, take(4, what), 4);
  return v;
}
void ByteReader::halves(std::span<float> out, const char* what) {
  const float scale = f32(what);
  if (!std::isfinite(scale) || scale <= 0.0f)
    fail("{} decode: {} scale {} is not a positive number", codec, what, scale);
  const std::byte* p = take(2 * out.size(), what);
  for (size_t i = 0; i < out.size(); ++i) {
    uint16_t h;
    std::memcpy(&h, p + 2 * i, 2);
    const float v = halfToFloat(h);
    // A corrupt payload may hold Inf/NaN halves, which encode never writes.
    if (!std::isfinite(v)) fail("{} decode: {} value {} at index {} is not finite", codec, what, v, i);
    out[i] = v * scale;
  }
}
void ByteReader::expectEnd() const {
  if (pos != data.size()) fail("{} decode: {} trailing bytes after the payload", codec, data.size() - pos);
}

float exposureScale(std::span<const float> values) {
  float maxAbs = 0.0f;
  for (float v : values) maxAbs = std::max(maxAbs, std::abs(v));
  if (!(maxAbs > 0.0f) || !std::isfinite(maxAbs)) return 1.0f;
  // A power of two, so scaling is exact; the largest value lands in [2^13, 2^14].
  int e = 0;
  std::frexp(maxAbs, &e);  // maxAbs = f * 2^e, f in [0.5, 1)
  return std::ldexp(1.0f, std::clamp(e - 14, -100, 100));
}

}  // namespace lfgi
