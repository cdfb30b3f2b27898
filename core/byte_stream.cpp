#include "core/byte_stream.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "core/half.h"

namespace lfgi {

namespace {

// The value stored at p (unaligned).
template <typename T>
T load(const std::byte* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

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
  return load<uint16_t>(take(sizeof(uint16_t), what));
}
uint32_t ByteReader::u32(const char* what) {
  return load<uint32_t>(take(sizeof(uint32_t), what));
}
uint64_t ByteReader::u64(const char* what) {
  return load<uint64_t>(take(sizeof(uint64_t), what));
}
float ByteReader::f32(const char* what) {
  return load<float>(take(sizeof(float), what));
}
void ByteReader::halves(std::span<float> out, const char* what) {
  const float scale = f32(what);
  if (!std::isfinite(scale) || scale <= 0.0f)
    fail("{} decode: {} scale {} is not a positive number", codec, what, scale);
  const std::byte* p = take(2 * out.size(), what);
  for (size_t i = 0; i < out.size(); ++i) {
    const float v = halfToFloat(load<uint16_t>(p + 2 * i));
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
