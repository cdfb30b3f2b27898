// Push constants of the ceiling micro-kernels (fma_peak, gemm_rowstrip, atomic_min64).
#ifndef LFGI_SHARED_CEILINGS_H
#define LFGI_SHARED_CEILINGS_H

#include "lfgi_shared.h"

LFGI_SHARED_BEGIN

struct FmaParams {
  uint iterations;  // loop trips; each does 8 independent vec4 FMAs = 64 flops
  uint threads;
  uint pad0, pad1;
};
LFGI_CHECK_SIZE(FmaParams, 16)

// C[M x N] = A[M x K] * B[K x N], row-major floats; N and K multiples of 4, M a multiple of 4.
struct GemmParams {
  uint m, n, k, pad;
};
LFGI_CHECK_SIZE(GemmParams, 16)

struct AtomicParams {
  uint slots;    // 64-bit slots in the target buffer (power of two)
  uint updates;  // atomicMin calls per invocation
  uint threads;
  uint seed;
};
LFGI_CHECK_SIZE(AtomicParams, 16)

LFGI_SHARED_END

#endif  // LFGI_SHARED_CEILINGS_H
