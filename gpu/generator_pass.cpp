#include "gpu/generator_pass.h"

#include <algorithm>

#include "core/error.h"
#include "gpu/timing.h"
#include "shared/generator.h"

namespace lfgi::gpu {

namespace {

constexpr uint32_t kBase = 4;

uint32_t roundUp4(uint32_t v) {
  return (v + 3u) / 4u * 4u;
}

// Input channels of conv layer i as stored (the linear layer writes C0 channels; hidden convs write whole
// groups of 4).
uint32_t storedChannels(const GeneratorArch& a, int layer) {
  return layer == 0 ? uint32_t(a.convChannels[0]) : roundUp4(uint32_t(a.convChannels[size_t(layer)]));
}

Buffer uploadFloats(Context& ctx, const std::vector<float>& v) {
  Buffer b = createStorageBuffer(ctx, v.size() * sizeof(float));
  upload<float>(ctx, b, v);
  return b;
}

}  // namespace

const char* generatorKernelName(GeneratorKernel kernel) {
  return kernel == GeneratorKernel::RowStrip ? "rowstrip" : "tiled";
}

GeneratorGpuModel::GeneratorGpuModel(Context& ctx, const GeneratorWeights& w) : arch_(w.arch) {
  w.validate();
  const uint32_t in = uint32_t(arch_.inputDim()), rows4 = uint32_t(arch_.convChannels[0]) * kBase;
  std::vector<float> lw(size_t(rows4) * in * 4);
  for (uint32_t rb = 0; rb < rows4; ++rb)
    for (uint32_t k = 0; k < in; ++k)
      for (uint32_t j = 0; j < 4; ++j)
        lw[(size_t(rb) * in + k) * 4 + j] = w.linearWeight[size_t(rb * 4 + j) * in + k];
  linearWeight_ = uploadFloats(ctx, lw);
  linearBias_ = uploadFloats(ctx, w.linearBias);
  for (int l = 0; l < arch_.layers(); ++l) {
    const uint32_t ci = uint32_t(arch_.convChannels[size_t(l)]),
                   co = uint32_t(arch_.convChannels[size_t(l) + 1]);
    const uint32_t co4 = roundUp4(co) / 4;
    const std::vector<float>& src = w.convWeight[size_t(l)];
    std::vector<float> cw(size_t(4) * co4 * ci * 4 * 4, 0.0f);
    for (uint32_t phase = 0; phase < 4; ++phase)
      for (uint32_t ob = 0; ob < co4; ++ob)
        for (uint32_t c = 0; c < ci; ++c)
          for (uint32_t t = 0; t < 4; ++t) {
            int ky = shared::genTapKernel(phase >> 1, t >> 1), kx = shared::genTapKernel(phase & 1, t & 1);
            for (uint32_t j = 0; j < 4; ++j) {
              uint32_t o = ob * 4 + j;
              if (o >= co) continue;
              cw[((((size_t(phase) * co4 + ob) * ci + c) * 4 + t) * 4) + j] =
                  src[(size_t(c) * co + o) * 16 + size_t(ky * 4 + kx)];
            }
          }
    std::vector<float> cb(size_t(co4) * 4, 0.0f);
    std::copy(w.convBias[size_t(l)].begin(), w.convBias[size_t(l)].end(), cb.begin());
    convWeight_.push_back(uploadFloats(ctx, cw));
    convBias_.push_back(uploadFloats(ctx, cb));
  }
}

size_t GeneratorGpuModel::bytes() const {
  size_t n = linearWeight_.size() + linearBias_.size();
  for (size_t i = 0; i < convWeight_.size(); ++i) n += convWeight_[i].size() + convBias_[i].size();
  return n;
}

GeneratorScratch::GeneratorScratch(Context& ctx, const GeneratorArch& arch, uint32_t capacity)
    : arch_(arch), capacity_(roundUp4(std::max(capacity, 1u))) {
  arch_.validate();
  uint32_t res = kBase;
  for (int l = 0; l < arch_.layers(); ++l) {
    const VkDeviceSize texels = VkDeviceSize{res + 2} * (res + 2);
    act_.push_back(createStorageBuffer(ctx, storedChannels(arch_, l) * texels * capacity_ * sizeof(float)));
    fillBuffer(ctx, act_.back(), 0u);
    res *= 2;
  }
}

size_t GeneratorScratch::bytes() const {
  size_t n = 0;
  for (const Buffer& b : act_) n += b.size();
  return n;
}

GeneratorDecodePass::GeneratorDecodePass(Context& ctx)
    : ctx_(ctx),
      linear_(ctx, "gen_linear"),
      rowstrip_(ctx, "gen_tconv_rowstrip"),
      tiled_(ctx, "gen_tconv_tiled") {}

void GeneratorDecodePass::record(VkCommandBuffer cmd, const GeneratorGpuModel& model,
                                 GeneratorScratch& scratch, const Buffer& latents,
                                 std::span<const float> cond, uint32_t count, const Buffer& out,
                                 GeneratorKernel kernel) const {
  const GeneratorArch& a = model.arch();
  if (count == 0) return;
  if (count > scratch.capacity())
    fail("generator decode: {} probes in a batch, the scratch holds {}", count, scratch.capacity());
  if (size_t(a.layers()) != scratch.act_.size())
    fail("generator decode: the scratch was built for {} layers, the model has {}", scratch.act_.size(),
         a.layers());
  for (int l = 0; l < a.layers(); ++l) {
    uint32_t want = storedChannels(a, l), have = storedChannels(scratch.arch_, l);
    if (want > have)
      fail("generator decode: layer {} needs {} channels of scratch, it holds {}", l, want, have);
  }
  if (cond.size() != size_t(a.condDim))
    fail("generator decode: {} conditioning floats, the model takes {}", cond.size(), a.condDim);
  const uint32_t R = uint32_t(a.outputResolution()), outC = uint32_t(a.outChannels());
  if (latents.size() < VkDeviceSize{count} * uint32_t(a.latentDim) * sizeof(float))
    fail("generator decode: latent buffer holds {} bytes, {} probes need {}", latents.size(), count,
         count * uint32_t(a.latentDim) * sizeof(float));
  if (out.size() < VkDeviceSize{count} * outC * R * R * sizeof(float))
    fail("generator decode: output buffer holds {} bytes, {} probes need {}", out.size(), count,
         VkDeviceSize{count} * outC * R * R * sizeof(float));

  const uint32_t p4 = (count + 3) / 4, s4 = scratch.capacity() / 4;
  shared::GenLinearParams lp{};
  for (size_t c = 0; c < cond.size(); ++c) lp.cond[int(c)] = cond[c];
  lp.latentDim = uint32_t(a.latentDim);
  lp.condDim = uint32_t(a.condDim);
  lp.rows4 = uint32_t(a.convChannels[0]) * kBase;
  lp.probes = count;
  lp.probes4 = p4;
  lp.probeStride4 = s4;
  dispatch(ctx_, cmd, linear_, {&latents, &model.linearWeight_, &model.linearBias_, &scratch.act_[0]}, lp,
           {lp.rows4 * p4, 1, 1});
  memoryBarrier(cmd);
  uint32_t res = kBase;
  for (int l = 0; l < a.layers(); ++l) {
    const bool last = l + 1 == a.layers();
    shared::GenConvParams cp{};
    cp.cin = uint32_t(a.convChannels[size_t(l)]);
    cp.cout = uint32_t(a.convChannels[size_t(l) + 1]);
    cp.cout4 = roundUp4(cp.cout) / 4;
    cp.res = res;
    cp.probes = count;
    cp.probes4 = p4;
    cp.last = last ? 1u : 0u;
    cp.probeStride4 = s4;
    const Buffer& next = last ? out : scratch.act_[size_t(l) + 1];
    const Buffer* bufs[] = {&scratch.act_[size_t(l)], &model.convWeight_[size_t(l)],
                            &model.convBias_[size_t(l)], &next};
    if (kernel == GeneratorKernel::RowStrip) {
      dispatch(ctx_, cmd, rowstrip_, {bufs[0], bufs[1], bufs[2], bufs[3], &out}, cp,
               {cp.cout4 * 4 * res * res * p4, 1, 1});
    } else {
      const uint32_t columns = res * res * p4, tiles = (columns + 15) / 16;
      dispatch(ctx_, cmd, tiled_, {bufs[0], bufs[1], bufs[2], bufs[3], &out}, cp,
               {tiles * 64, 4 * ((cp.cout4 + 3) / 4), 1});
    }
    memoryBarrier(cmd);
    res *= 2;
  }
}

std::vector<float> GeneratorDecodePass::run(const GeneratorGpuModel& model, std::span<const float> latents,
                                            std::span<const float> cond, size_t count, GeneratorKernel kernel,
                                            double* gpuMs) {
  const GeneratorArch& a = model.arch();
  if (count == 0 || count > (1u << 24)) fail("generator decode: {} probes requested (1 .. 2^24)", count);
  if (latents.size() != count * size_t(a.latentDim))
    fail("generator decode: {} latent floats for {} probes of {}", latents.size(), count, a.latentDim);
  const size_t R = size_t(a.outputResolution()), outFloats = count * size_t(a.outChannels()) * R * R;
  Buffer lat = createStorageBuffer(ctx_, latents.size() * sizeof(float));
  upload<float>(ctx_, lat, latents);
  Buffer out = createStorageBuffer(ctx_, outFloats * sizeof(float));
  GeneratorScratch scratch(ctx_, a, uint32_t(count));
  GpuTimer timer(ctx_, 2);
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    record(cmd, model, scratch, lat, cond, uint32_t(count), out, kernel);
    timer.stamp(cmd, 1);
  });
  if (gpuMs) *gpuMs = timer.elapsedMs(0, 1);
  std::vector<float> result(outFloats);
  readback<float>(ctx_, out, result);
  return result;
}

}  // namespace lfgi::gpu
