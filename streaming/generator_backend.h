// The generator network behind one interface with a CPU and a Vulkan backend (docs/DESIGN.md §6), for the
// streaming manager's cell decode (CellFileSource, decodeCellField in streaming/cell_file_source.h).
//
// A backend produces only the network's raw outputs ([count][outChannels][R][R], generatorForward's
// layout) in batches it chooses; everything after the network (decodeChannels, the irradiance
// convolution, SH-evaluated probes, the scatter into the cell's probe order) is decodeCellField's and is
// the same code for both backends.
//
//   CpuGeneratorBackend: GeneratorCpu (OpenBLAS sgemm) built per decode (it copies the weights; its scratch
//     lives in the decode call). Thread-safe: any number of threads decode at once.
//   GpuGeneratorBackend: gpu::GeneratorDecodePass (rowstrip kernel by default: the barrier-free one that is
//     fast on lavapipe). Owns or borrows one gpu::Context.
//     Threading: a gpu::Context is one-thread-at-a-time, so decode() holds the backend's mutex for the device
//     part of each batch (latent upload, kernels, readback into a per-thread copy); the sink's
//     post-processing runs unlocked, so one IO thread's CPU work overlaps another's device batch. Concurrent
//     callers are otherwise serialised batch by batch, in no particular order. A borrowed context must not
//     be used by anyone else while a decode may run: the mutex only orders this backend's users.
//     Residency: the batch buffers (latent upload + device, scratch, output device + readback) are created
//     for the largest batch seen and reused (no device allocation per decode once warm); a cell's weights are
//     uploaded once into a GeneratorGpuModel kept in a small LRU cache keyed by ModelRef::key (relights of
//     a resident cell do not re-upload; key 0 = no caching).
//
// chooseGeneratorBackend (DecoderChoice::Auto) times both backends' raw decode on the same model and
// latents (a warm-up batch, then a timed one: the first GPU use JIT-compiles its pipelines) and picks the
// higher probes/s. On lavapipe the CPU wins by ~an order of magnitude; on a real GPU the GPU should.
#pragma once

#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "core/generator.h"

namespace lfgi::gpu {
struct Context;
class GeneratorDecodePass;
class GeneratorGpuModel;
class GeneratorScratch;
class Buffer;
}  // namespace lfgi::gpu

namespace lfgi::streaming {

enum class DecoderChoice : uint8_t { Cpu, Gpu, Auto };
const char* decoderChoiceName(DecoderChoice choice);  // "cpu", "gpu", "auto"
// "cpu" | "gpu" | "auto"; anything else throws lfgi::Error naming the value.
DecoderChoice parseDecoderChoice(const std::string& text);

// A model to decode: the float weights and a cache key (e.g. the cell and its file's input hash; 0: do not
// cache device copies of it).
struct ModelRef {
  const GeneratorWeights& weights;
  uint64_t key = 0;
};

// A ModelRef key for these weights: a hash of the architecture and every weight (never 0).
uint64_t generatorModelKey(const GeneratorWeights& weights);

// Receives consecutive batches: probes [first, first + count) of the decode, raw outputs of those probes.
// The span is valid only during the call.
using RawBatchSink = std::function<void(size_t first, size_t count, std::span<const float> raw)>;

class GeneratorBackend {
 public:
  virtual ~GeneratorBackend() = default;
  virtual const char* name() const = 0;  // "cpu" | "gpu"
  // Decodes `count` probes (latents: count * latentDim floats, cond: condDim floats for all of them) and
  // hands every batch to sink in probe order. Throws lfgi::Error on size mismatches or device errors.
  virtual void decode(const ModelRef& model, std::span<const float> latents, std::span<const float> cond,
                      size_t count, const RawBatchSink& sink) = 0;
};

class CpuGeneratorBackend final : public GeneratorBackend {
 public:
  const char* name() const override { return "cpu"; }
  // Batches of whole GeneratorCpu chunks, ~1024 probes.
  void decode(const ModelRef& model, std::span<const float> latents, std::span<const float> cond,
              size_t count, const RawBatchSink& sink) override;
};

struct GpuBackendOptions {
  uint32_t batchProbes = 1024;  // probes per submission (scratch capacity)
  size_t cachedModels = 16;     // LRU cache of uploaded cell models
  bool tiledKernel = false;     // GeneratorKernel::Tiled (shared memory, for real GPUs) instead of RowStrip
};

class GpuGeneratorBackend final : public GeneratorBackend {
 public:
  // Creates its own gpu::Context (throws lfgi::Error, from gpu::createContext, naming why no device is
  // usable).
  explicit GpuGeneratorBackend(GpuBackendOptions options = {});
  // Borrows ctx (must outlive the backend; see the threading note above).
  GpuGeneratorBackend(gpu::Context& ctx, GpuBackendOptions options = {});
  ~GpuGeneratorBackend() override;
  GpuGeneratorBackend(const GpuGeneratorBackend&) = delete;
  GpuGeneratorBackend& operator=(const GpuGeneratorBackend&) = delete;

  const char* name() const override { return "gpu"; }
  void decode(const ModelRef& model, std::span<const float> latents, std::span<const float> cond,
              size_t count, const RawBatchSink& sink) override;

  gpu::Context& context() { return *ctx_; }
  std::string deviceName() const;
  // Device buffers (re)created so far for batches and models: stays constant once warm (tests check it).
  uint64_t bufferAllocations() const;
  uint64_t modelUploads() const;

 private:
  struct Batch;  // the reused batch buffers
  struct CachedModel {
    uint64_t key;
    std::shared_ptr<gpu::GeneratorGpuModel> model;
  };
  std::shared_ptr<gpu::GeneratorGpuModel> modelFor(const ModelRef& ref);  // mutex_ held
  Batch& batchFor(const GeneratorArch& arch);                             // mutex_ held

  GpuBackendOptions options_;
  std::unique_ptr<gpu::Context> owned_;
  gpu::Context* ctx_ = nullptr;
  mutable std::mutex mutex_;
  std::unique_ptr<gpu::GeneratorDecodePass> pass_;
  std::vector<std::unique_ptr<Batch>> batches_;
  std::list<CachedModel> models_;  // most recently used first
  uint64_t allocations_ = 0, uploads_ = 0;
};

// What chooseGeneratorBackend measured and picked.
struct DecoderSelection {
  DecoderChoice requested = DecoderChoice::Cpu;
  std::string backend = "cpu";  // the one used: "cpu" | "gpu"
  std::string device;           // the Vulkan device's name when a GPU backend exists, else empty
  double cpuProbesPerS = 0.0;   // raw network decode rate measured (Auto only; 0: not measured)
  double gpuProbesPerS = 0.0;
  size_t measuredProbes = 0;  // probes per timed decode
  std::string reason;         // why this backend (measured rates, forced, or the fallback's reason)
};

// Builds the backend for `choice`:
//   Cpu: CpuGeneratorBackend.   Gpu: GpuGeneratorBackend; no Vulkan device throws lfgi::Error (says so).
//   Auto: both, timed on (model, latents, cond) (512 .. 2048 probes: the count probes' latents repeated or
//     cut), the faster kept; no
//     Vulkan device logs the reason and keeps the CPU. With no model to time (nullptr), the GPU is not
//     tried and the reason says so.
// selection receives what was measured and picked.
std::unique_ptr<GeneratorBackend> chooseGeneratorBackend(DecoderChoice choice, const GeneratorWeights* model,
                                                         std::span<const float> latents,
                                                         std::span<const float> cond, size_t count,
                                                         DecoderSelection& selection,
                                                         const GpuBackendOptions& gpuOptions = {});

// Probes/s of backend's raw decode of count probes (one untimed warm-up decode, then the best of `reps`).
double measureProbesPerSecond(GeneratorBackend& backend, const ModelRef& model,
                              std::span<const float> latents, std::span<const float> cond, size_t count,
                              int reps = 2);

}  // namespace lfgi::streaming
