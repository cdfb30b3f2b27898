// GPU decode of the generator network (core/generator.h): batched over probes, one dispatch per layer
// (shaders/gen_linear.comp, then gen_tconv_rowstrip.comp or gen_tconv_tiled.comp per transposed conv; layouts
// in shaders/shared/generator.h). Same function as generatorForward / GeneratorCpu, summed in another order.
//
// Kernels: RowStrip is barrier-free and register-blocked (4 output channels x 4 probes per invocation), the
// fast one on lavapipe, where a workgroup's invocations run as coroutines and barriers cost ~5x
// (docs/DESIGN.md §6). Tiled stages activations and weights in shared memory (16 channels x 16 texel-probe
// groups per workgroup), for real GPUs. The linear layer is < 2 % of the work and uses one barrier-free
// kernel.
//
// Residency: a GeneratorGpuModel holds one cell's repacked weights on the device (upload once, while the cell
// is resident); a GeneratorScratch holds the activations for up to `capacity` probes per batch; a
// GeneratorDecodePass holds the pipelines (one per Context) and records a batch decode.
// Threading: like Context, one thread at a time.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/generator.h"
#include "gpu/buffer.h"
#include "gpu/program.h"

namespace lfgi::gpu {

enum class GeneratorKernel { RowStrip, Tiled };
const char* generatorKernelName(GeneratorKernel kernel);  // "rowstrip", "tiled"

class GeneratorGpuModel {
 public:
  // Validates (lfgi::Error names the bad field), repacks and uploads the weights.
  GeneratorGpuModel(Context& ctx, const GeneratorWeights& weights);
  const GeneratorArch& arch() const { return arch_; }
  // Device bytes of the resident weights.
  size_t bytes() const;

 private:
  friend class GeneratorDecodePass;
  GeneratorArch arch_;
  Buffer linearWeight_, linearBias_;
  std::vector<Buffer> convWeight_, convBias_;
};

class GeneratorScratch {
 public:
  // Activations for up to `capacity` probes of models with this architecture's shape (or any with no larger
  // layers). Zero-filled once: kernels write interiors only, the borders stay zero.
  GeneratorScratch(Context& ctx, const GeneratorArch& arch, uint32_t capacity);
  uint32_t capacity() const { return capacity_; }
  size_t bytes() const;

 private:
  friend class GeneratorDecodePass;
  GeneratorArch arch_;
  uint32_t capacity_ = 0;
  std::vector<Buffer> act_;  // input of conv layer i: [Cpad_i][res_i + 2][res_i + 2][capacity / 4] vec4
};

class GeneratorDecodePass {
 public:
  explicit GeneratorDecodePass(Context& ctx);

  // Records the decode of `count` probes (count <= scratch.capacity()): latents [count][latentDim] floats,
  // out [count][outChannels][R][R] floats (generatorForward's layout), cond: condDim floats for the batch.
  // Throws lfgi::Error if sizes disagree (buffers too small, scratch built for a smaller architecture).
  void record(VkCommandBuffer cmd, const GeneratorGpuModel& model, GeneratorScratch& scratch,
              const Buffer& latents, std::span<const float> cond, uint32_t count, const Buffer& out,
              GeneratorKernel kernel) const;

  // Convenience: uploads latents, decodes all `count` probes as one batch (scratch of that capacity), waits
  // and returns count * outChannels * R * R floats. gpuMs (if given) receives the device time of the decode
  // only.
  std::vector<float> run(const GeneratorGpuModel& model, std::span<const float> latents,
                         std::span<const float> cond, size_t count, GeneratorKernel kernel,
                         double* gpuMs = nullptr);

 private:
  Context& ctx_;
  Program linear_, rowstrip_, tiled_;
};

}  // namespace lfgi::gpu
