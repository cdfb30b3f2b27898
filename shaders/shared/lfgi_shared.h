// Included by GLSL and by C++. Declares each CPU<->GPU struct and the pure math used on both sides once.
// C++ sees these in namespace lfgi::shared with glm types; GLSL sees them at global scope.
// Write only the common subset: no swizzles, no out/inout params, float literals with an 'f' suffix.
#ifndef LFGI_SHARED_H
#define LFGI_SHARED_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
// clang-format off
#define LFGI_SHARED_BEGIN                                                                         \
  namespace lfgi::shared {                                                                        \
  using uint = std::uint32_t;                                                                     \
  using glm::vec2; using glm::vec3; using glm::vec4; using glm::ivec2; using glm::uvec2;          \
  using glm::ivec3; using glm::uvec3; using glm::ivec4; using glm::uvec4;                         \
  using glm::abs; using glm::sign; using glm::min; using glm::max; using glm::clamp;              \
  using glm::floor; using glm::dot; using glm::normalize; using glm::length;
#define LFGI_SHARED_END }
// clang-format on
#define LFGI_INLINE inline
// Layout checks are written without a trailing semicolon (GLSL rejects a stray one at global scope).
#define LFGI_CHECK_SIZE(T, bytes) static_assert(sizeof(T) == (bytes), #T " size differs from GLSL std430");
#define LFGI_CHECK_OFFSET(T, m, off) static_assert(offsetof(T, m) == (off), #T "." #m " offset differs");
#else
#define LFGI_SHARED_BEGIN
#define LFGI_SHARED_END
#define LFGI_INLINE
#define LFGI_CHECK_SIZE(T, bytes)
#define LFGI_CHECK_OFFSET(T, m, off)
#endif

#endif  // LFGI_SHARED_H
