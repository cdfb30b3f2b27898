#include "streaming/generator_backend.h"

#include <algorithm>
#include <chrono>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/generator_cpu.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/generator_pass.h"

namespace lfgi::streaming {

namespace {

size_t rawFloatsPerProbe(const GeneratorArch& a) {
  const size_t R = size_t(a.outputResolution());
  return size_t(a.outChannels()) * R * R;
}

void checkSizes(const GeneratorArch& a, std::span<const float> latents, std::span<const float> cond,
                size_t count, const char* backend) {
  if (latents.size() != count * size_t(a.latentDim))
    fail("{} generator backend: {} latent floats for {} probes of {}", backend, latents.size(), count,
         a.latentDim);
  if (cond.size() != size_t(a.condDim))
    fail("{} generator backend: {} conditioning floats, the model takes {}", backend, cond.size(), a.condDim);
}

}  // namespace

const char* decoderChoiceName(DecoderChoice choice) {
  switch (choice) {
    case DecoderChoice::Cpu:
      return "cpu";
    case DecoderChoice::Gpu:
      return "gpu";
    case DecoderChoice::Auto:
      return "auto";
  }
  return "?";
}

DecoderChoice parseDecoderChoice(const std::string& text) {
  if (text == "cpu") return DecoderChoice::Cpu;
  if (text == "gpu") return DecoderChoice::Gpu;
  if (text == "auto") return DecoderChoice::Auto;
  fail("decoder '{}': expected cpu, gpu or auto", text);
}

void CpuGeneratorBackend::decode(const ModelRef& model, std::span<const float> latents,
                                 std::span<const float> cond, size_t count, const RawBatchSink& sink) {
  const GeneratorArch& a = model.weights.arch;
  checkSizes(a, latents, cond, count, "cpu");
  GeneratorCpu decoder(model.weights);
  // Whole decoder chunks (the same sgemm batches as one forward over every probe: identical values).
  const size_t batch = decoder.chunkProbes() * std::max<size_t>(1, 1024 / decoder.chunkProbes());
  const size_t L = size_t(a.latentDim), per = rawFloatsPerProbe(a);
  thread_local std::vector<float> raw;
  raw.resize(std::min(batch, count) * per);
  for (size_t p0 = 0; p0 < count; p0 += batch) {
    const size_t n = std::min(batch, count - p0);
    const std::span<float> out(raw.data(), n * per);
    decoder.forward(latents.subspan(p0 * L, n * L), cond, n, out);
    sink(p0, n, out);
  }
}

// The reused buffers of one batch size and architecture shape (grown, never shrunk).
struct GpuGeneratorBackend::Batch {
  GeneratorArch arch;  // the scratch's shape
  uint32_t capacity = 0;
  size_t latentFloats = 0, rawFloats = 0;  // per probe
  gpu::Buffer latentUpload, latentDevice, outDevice, outReadback;
  std::unique_ptr<gpu::GeneratorScratch> scratch;
};

GpuGeneratorBackend::GpuGeneratorBackend(GpuBackendOptions options) : options_(options) {
  owned_ = gpu::createContext();
  ctx_ = owned_.get();
  pass_ = std::make_unique<gpu::GeneratorDecodePass>(*ctx_);
}

GpuGeneratorBackend::GpuGeneratorBackend(gpu::Context& ctx, GpuBackendOptions options)
    : options_(options), ctx_(&ctx), pass_(std::make_unique<gpu::GeneratorDecodePass>(ctx)) {}

GpuGeneratorBackend::~GpuGeneratorBackend() {
  // Buffers and pipelines before the context they belong to.
  models_.clear();
  batches_.clear();
  pass_.reset();
}

std::string GpuGeneratorBackend::deviceName() const {
  return ctx_->info.name;
}

uint64_t GpuGeneratorBackend::bufferAllocations() const {
  const std::lock_guard lock(mutex_);
  return allocations_;
}

uint64_t GpuGeneratorBackend::modelUploads() const {
  const std::lock_guard lock(mutex_);
  return uploads_;
}

namespace {
// Does the scratch built for `have` hold activations of `want` (same layer count, no larger stage)?
bool scratchFits(const GeneratorArch& have, const GeneratorArch& want) {
  if (have.layers() != want.layers()) return false;
  for (size_t l = 0; l < want.convChannels.size(); ++l)
    if (want.convChannels[l] > have.convChannels[l]) return false;
  return true;
}
}  // namespace

GpuGeneratorBackend::Batch& GpuGeneratorBackend::batchFor(const GeneratorArch& arch) {
  const uint32_t cap = std::max<uint32_t>(options_.batchProbes, 4);
  const size_t L = size_t(arch.latentDim), per = rawFloatsPerProbe(arch);
  // One set of buffers per layer count (scratch layouts differ), grown to the union of the shapes seen.
  std::unique_ptr<Batch>* slot = nullptr;
  for (auto& b : batches_)
    if (b->arch.layers() == arch.layers()) slot = &b;
  if (slot && scratchFits((*slot)->arch, arch) && (*slot)->latentFloats >= L && (*slot)->rawFloats >= per)
    return **slot;
  auto b = std::make_unique<Batch>();
  b->arch = arch;
  b->capacity = cap;
  b->latentFloats = L;
  b->rawFloats = per;
  if (slot) {
    const Batch& old = **slot;
    for (size_t l = 0; l < arch.convChannels.size(); ++l)
      b->arch.convChannels[l] = std::max(arch.convChannels[l], old.arch.convChannels[l]);
    b->latentFloats = std::max(L, old.latentFloats);
    b->rawFloats = std::max(per, old.rawFloats);
    slot->reset();  // free the old buffers first
  }
  const VkDeviceSize latBytes = VkDeviceSize(cap) * b->latentFloats * sizeof(float);
  const VkDeviceSize outBytes = VkDeviceSize(cap) * b->rawFloats * sizeof(float);
  b->latentUpload = gpu::Buffer(*ctx_, latBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, gpu::MemoryUsage::Upload);
  b->latentDevice = gpu::createStorageBuffer(*ctx_, latBytes);
  b->outDevice = gpu::createStorageBuffer(*ctx_, outBytes);
  b->outReadback = gpu::Buffer(*ctx_, outBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, gpu::MemoryUsage::Readback);
  b->scratch = std::make_unique<gpu::GeneratorScratch>(*ctx_, b->arch, cap);
  ++allocations_;
  if (slot) {
    *slot = std::move(b);
    return **slot;
  }
  batches_.push_back(std::move(b));
  return *batches_.back();
}

std::shared_ptr<gpu::GeneratorGpuModel> GpuGeneratorBackend::modelFor(const ModelRef& ref) {
  if (ref.key != 0) {
    for (auto it = models_.begin(); it != models_.end(); ++it)
      if (it->key == ref.key) {
        models_.splice(models_.begin(), models_, it);
        return models_.front().model;
      }
  }
  auto model = std::make_shared<gpu::GeneratorGpuModel>(*ctx_, ref.weights);
  ++uploads_;
  if (ref.key == 0 || options_.cachedModels == 0) return model;
  if (models_.size() >= options_.cachedModels) models_.pop_back();
  models_.push_front({ref.key, model});
  return model;
}

void GpuGeneratorBackend::decode(const ModelRef& model, std::span<const float> latents,
                                 std::span<const float> cond, size_t count, const RawBatchSink& sink) {
  const GeneratorArch& a = model.weights.arch;
  checkSizes(a, latents, cond, count, "gpu");
  if (count == 0) return;
  const size_t L = size_t(a.latentDim), per = rawFloatsPerProbe(a);
  const gpu::GeneratorKernel kernel =
      options_.tiledKernel ? gpu::GeneratorKernel::Tiled : gpu::GeneratorKernel::RowStrip;
  // The device part of each batch under the mutex; the raw outputs are copied out so that the sink's
  // post-processing runs unlocked (another thread's batch may use the device meanwhile).
  thread_local std::vector<float> raw;
  std::shared_ptr<gpu::GeneratorGpuModel> gm;  // held across batches even if the cache drops it
  size_t p0 = 0;
  while (p0 < count) {
    uint32_t n = 0;
    {
      const std::lock_guard lock(mutex_);
      if (!gm) gm = modelFor(model);
      Batch& b = batchFor(a);
      n = uint32_t(std::min<size_t>(b.capacity, count - p0));
      const VkDeviceSize latBytes = VkDeviceSize(n) * L * sizeof(float),
                         outBytes = VkDeviceSize(n) * per * sizeof(float);
      std::copy_n(latents.data() + p0 * L, size_t(n) * L, static_cast<float*>(b.latentUpload.mapped()));
      gpu::submitAndWait(*ctx_, [&](VkCommandBuffer cmd) {
        const VkBufferCopy up{0, 0, latBytes};
        vkCmdCopyBuffer(cmd, b.latentUpload.handle(), b.latentDevice.handle(), 1, &up);
        gpu::memoryBarrier(cmd);
        pass_->record(cmd, *gm, *b.scratch, b.latentDevice, cond, n, b.outDevice, kernel);
        const VkBufferCopy down{0, 0, outBytes};
        vkCmdCopyBuffer(cmd, b.outDevice.handle(), b.outReadback.handle(), 1, &down);
        gpu::memoryBarrier(cmd);
      });
      raw.resize(size_t(n) * per);
      std::copy_n(static_cast<const float*>(b.outReadback.mapped()), raw.size(), raw.data());
      if (p0 + n >= count) gm.reset();  // an uncached model's buffers are freed under the lock
    }
    sink(p0, n, raw);
    p0 += n;
  }
}

// The weights' content hash (FNV-1a over the architecture and every float weight): the GPU backend's
// model-cache key (two cells with the same weights share one upload; changed weights never hit a stale
// one). Never 0, which marks no model.
uint64_t generatorModelKey(const GeneratorWeights& w) {
  const uint64_t h = weightsContentHash(w);
  return h == 0 ? 1 : h;
}

double measureProbesPerSecond(GeneratorBackend& backend, const ModelRef& model,
                              std::span<const float> latents, std::span<const float> cond, size_t count,
                              int reps) {
  const RawBatchSink none = [](size_t, size_t, std::span<const float>) {};
  backend.decode(model, latents, cond, count, none);  // warm-up: pipelines, buffers, caches
  double best = 1e30;
  for (int r = 0; r < std::max(1, reps); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    backend.decode(model, latents, cond, count, none);
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return double(count) / std::max(best, 1e-9);
}

std::unique_ptr<GeneratorBackend> chooseGeneratorBackend(DecoderChoice choice, const GeneratorWeights* model,
                                                         std::span<const float> latents,
                                                         std::span<const float> cond, size_t count,
                                                         DecoderSelection& sel,
                                                         const GpuBackendOptions& gpuOptions) {
  sel = {};
  sel.requested = choice;
  if (choice == DecoderChoice::Cpu) {
    sel.backend = "cpu";
    sel.reason = "requested";
    return std::make_unique<CpuGeneratorBackend>();
  }
  if (choice == DecoderChoice::Gpu) {
    std::unique_ptr<GpuGeneratorBackend> gpu;
    try {
      gpu = std::make_unique<GpuGeneratorBackend>(gpuOptions);
    } catch (const Error& e) {
      fail("decoder gpu: no usable Vulkan device for the generator kernels: {}", e.what());
    }
    sel.backend = "gpu";
    sel.device = gpu->deviceName();
    sel.reason = "requested";
    return gpu;
  }
  auto cpu = std::make_unique<CpuGeneratorBackend>();
  sel.backend = "cpu";
  if (!model) {
    sel.reason = "auto: no generator cell to time (every cell decodes from SH), CPU kept";
    return cpu;
  }
  std::unique_ptr<GpuGeneratorBackend> gpu;
  try {
    gpu = std::make_unique<GpuGeneratorBackend>(gpuOptions);
  } catch (const Error& e) {
    sel.reason = fmt::format("auto: no Vulkan device ({}), CPU decode", e.what());
    spdlog::warn("streaming: decoder {}", sel.reason);
    return cpu;
  }
  sel.device = gpu->deviceName();
  // 512 .. 2048 probes: a cell's worth (a smaller cell's latents repeat), so fixed per-call costs (thread
  // start-up, one submission) weigh as they do in a load.
  const size_t L = size_t(model->arch.latentDim);
  if (count == 0 || latents.size() < count * L)
    fail("decoder auto: {} latent floats for {} probes", latents.size(), count);
  const size_t n = std::clamp<size_t>(count, 512, 2048);
  std::vector<float> z(n * L);
  for (size_t i = 0; i < n; ++i) std::copy_n(latents.data() + (i % count) * L, L, z.data() + i * L);
  const ModelRef ref{*model, generatorModelKey(*model)};  // the timed decodes reuse the upload
  try {
    sel.cpuProbesPerS = measureProbesPerSecond(*cpu, ref, z, cond, n);
    sel.gpuProbesPerS = measureProbesPerSecond(*gpu, ref, z, cond, n);
  } catch (const Error& e) {
    sel.reason = fmt::format("auto: the GPU decode failed on {} ({}), CPU decode", sel.device, e.what());
    spdlog::warn("streaming: decoder {}", sel.reason);
    return cpu;
  }
  sel.measuredProbes = n;
  const bool useGpu = sel.gpuProbesPerS > sel.cpuProbesPerS;
  sel.backend = useGpu ? "gpu" : "cpu";
  sel.reason = fmt::format("auto: measured {} probes: cpu {:.0f} probes/s, gpu ({}) {:.0f} probes/s", n,
                           sel.cpuProbesPerS, sel.device, sel.gpuProbesPerS);
  spdlog::info("streaming: decoder {} -> {}", sel.reason, sel.backend);
  if (useGpu) return gpu;
  return cpu;
}

}  // namespace lfgi::streaming
