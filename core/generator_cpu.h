// Fast CPU decoder of the generator network (core/generator.h): the same function as generatorForward,
// batched over probes so every layer is one OpenBLAS sgemm (threads come from OpenBLAS).
//
// Activations are stored probe-innermost, [C][H][W][P] for a chunk of P probes, so that
//   - the linear layer is one sgemm  H0[16 C0][P] = W0[:, latent][16 C0][L] * Z^T[L][P]  (the conditioning is
//     shared by the batch, so its columns fold into the bias once per call), and
//   - each stride-2 transposed conv is one sgemm  cols[16 Co][H W P] = W^T[16 Co][Ci] * X[Ci][H W P] followed
//   by
//     a col2im gather (each output texel sums exactly 2 x 2 taps for kernel 4, stride 2, padding 1) whose
//     inner loop runs over contiguous probes, fused with bias and ReLU.
// Probes are processed in chunks sized so one layer's column matrix stays near the last-level cache.
// Speed (bench/codec_decode): 7-50 GFLOP per CPU-second, against ~140 for a square OpenBLAS sgemm: the GEMMs
// have K = Cin (16..128) and write a column matrix 16x the layer output, so they are memory-bound; a direct
// register-blocked kernel was not tried (the build targets baseline x86-64, OpenBLAS dispatches AVX-512).
//
// Threading: OpenBLAS threads the sgemms, the col2im gather and the final transpose run on
// std::thread::hardware_concurrency() threads. A GeneratorCpu holds scratch memory; use one per thread
// (forward() is not reentrant).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "core/generator.h"
#include "core/probe_field.h"

namespace lfgi {

class GeneratorCpu {
 public:
  // Validates the weights (lfgi::Error names the bad field) and copies them. chunkProbes: probes per sgemm
  // batch; 0 chooses from the architecture (column matrix <= ~8 MiB, a multiple of 16 in [16, 1024]).
  explicit GeneratorCpu(const GeneratorWeights& weights, size_t chunkProbes = 0);

  // Same contract and output layout as generatorForward (probe-major, then channel, then texel); matches it
  // to float rounding (different summation order). Throws lfgi::Error on size mismatches.
  void forward(std::span<const float> latents, std::span<const float> cond, size_t count,
               std::span<float> out);

  const GeneratorArch& arch() const { return weights_.arch; }
  size_t chunkProbes() const { return chunk_; }

 private:
  void forwardChunk(const float* latents, size_t count, float* out);

  GeneratorWeights weights_;
  size_t chunk_ = 0;
  std::vector<float> bias0_;  // linear bias with the conditioning folded in (per forward call)
  std::vector<float> zt_, act_, next_, cols_;
};

// Decodes every probe of `field` (field.grid and field.resolution must be set; resolution must equal the
// model's output resolution, and the model must emit kGeneratorChannels) into its radiance, distance, normal
// and albedo arrays (resized here). latents: probeCount * latentDim floats, probe-index order. Irradiance
// maps are not derived here: the caller convolves the decoded radiance (gpu::IrradianceConvolution, or
// bruteForceIrradiance / SH in core/sh.h), since that costs more than the decode itself for n = 16, m = 8.
void decodeProbeField(GeneratorCpu& decoder, std::span<const float> latents, std::span<const float> cond,
                      const GeneratorOutputScale& scale, ProbeField& field);

// Random weights for tests and benchmarks: He-style normal init (std sqrt(2 / fan-in), fan-in = inputDim for
// the linear layer, 4 Ci for a transposed conv, whose outputs each see 2 x 2 taps) so activations stay O(1)
// through any depth; biases uniform in [-0.1, 0.1]. Deterministic for a seed.
GeneratorWeights randomGeneratorWeights(const GeneratorArch& arch, unsigned seed);

}  // namespace lfgi
