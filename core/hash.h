// The project's two non-cryptographic hashes, written once:
//  - FNV-1a (64-bit; Fowler, Noll & Vo): content hashes and cache keys of byte strings (weights, captures,
//    probe fields). Fold values in one after another; a value's bytes are hashed as stored in memory.
//  - splitmix64 (Steele, Lea & Flood 2014): the finaliser mixes a 64-bit key into a well-spread one, and
//    counter-based random streams (element i of stream k = finalize(k + i * golden)) need no state shared
//    between threads, cells or triangles.
// Header-only and constexpr where it can be, so the GPU-side code's counterparts can be checked against it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

namespace lfgi {

inline constexpr uint64_t kFnv1aOffset = 14695981039346656037ull;
inline constexpr uint64_t kFnv1aPrime = 1099511628211ull;

// h folded with `size` bytes at data (h = kFnv1aOffset starts a new hash).
inline uint64_t fnv1a(uint64_t h, const void* data, size_t size) {
  const auto* b = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) h = (h ^ b[i]) * kFnv1aPrime;
  return h;
}

// h folded with the bytes of one trivially copyable value.
template <typename T>
uint64_t fnv1aValue(uint64_t h, const T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  return fnv1a(h, &v, sizeof(T));
}

// h folded with the element count (u64) and then the bytes of every element: two spans that differ only in
// where one ends and the next begins hash differently.
template <typename T>
uint64_t fnv1aSpan(uint64_t h, std::span<const T> v) {
  static_assert(std::is_trivially_copyable_v<T>);
  h = fnv1aValue(h, uint64_t(v.size()));
  return fnv1a(h, v.data(), v.size_bytes());
}
template <typename T>
uint64_t fnv1aSpan(uint64_t h, const std::vector<T>& v) {
  return fnv1aSpan(h, std::span<const T>(v));
}

inline constexpr uint64_t kGoldenGamma = 0x9e3779b97f4a7c15ull;  // 2^64 / golden ratio, odd

// splitmix64's output function: a bijective 64-bit mix.
constexpr uint64_t splitmix64Finalize(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// One splitmix64 step from state x: finalize(x + golden). splitmix64(0) is the generator's first output
// when seeded with 0.
constexpr uint64_t splitmix64(uint64_t x) {
  return splitmix64Finalize(x + kGoldenGamma);
}

// [0, 1) from the top 53 bits.
constexpr double unitDouble(uint64_t h) {
  return double(h >> 11) * 0x1.0p-53;
}

}  // namespace lfgi
