#include "core/generator_cpu.h"

#include <cblas.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <thread>

#include "core/error.h"

namespace lfgi {

namespace {

constexpr size_t kBase = 4;
constexpr size_t kTaps = size_t(kGeneratorKernel) * kGeneratorKernel;

// For kernel 4, stride 2, padding 1 (oy = 2 iy - 1 + ky), output row oy receives exactly two (ky, iy) pairs;
// pairs whose iy falls outside [0, res) are dropped by pointing them at a zero row (valid = false).
struct TapPair {
  int k[2];
  int i[2];
};
TapPair tapsFor(int o) {
  int m = o >> 1;
  if ((o & 1) == 0) return {{1, 3}, {m, m - 1}};
  return {{0, 2}, {m + 1, m}};
}

// Splits [0, n) into one contiguous range per hardware thread (the calling thread takes the first).
template <typename F>
void parallelFor(size_t n, F f) {
  const size_t threads = std::min<size_t>(n, std::max(1u, std::thread::hardware_concurrency()));
  if (threads <= 1) {
    f(size_t(0), n);
    return;
  }
  std::vector<std::thread> pool;
  for (size_t t = 1; t < threads; ++t)
    pool.emplace_back([&, t] { f(n * t / threads, n * (t + 1) / threads); });
  f(size_t(0), n / threads);
  for (std::thread& th : pool) th.join();
}

}  // namespace

GeneratorCpu::GeneratorCpu(const GeneratorWeights& weights, size_t chunkProbes) : weights_(weights) {
  weights_.validate();
  const GeneratorArch& a = weights_.arch;
  if (chunkProbes == 0) {
    size_t perProbe = 1;
    size_t res = kBase;
    for (int l = 0; l < a.layers(); ++l) {
      perProbe = std::max(perProbe, kTaps * size_t(a.convChannels[size_t(l) + 1]) * res * res);
      res *= 2;
    }
    chunkProbes = std::clamp<size_t>((size_t(2) << 20) / perProbe / 16 * 16, 16, 1024);
  }
  chunk_ = chunkProbes;
}

void GeneratorCpu::forward(std::span<const float> latents, std::span<const float> cond, size_t count,
                           std::span<float> out) {
  const GeneratorArch& a = weights_.arch;
  const size_t L = size_t(a.latentDim), C = size_t(a.condDim), in = L + C;
  const size_t R = size_t(a.outputResolution()), outC = size_t(a.outChannels());
  if (latents.size() != count * L)
    fail("GeneratorCpu::forward: {} latent floats for {} probes of {}", latents.size(), count, L);
  if (cond.size() != C)
    fail("GeneratorCpu::forward: {} conditioning floats, the model takes {}", cond.size(), C);
  if (out.size() != count * outC * R * R)
    fail("GeneratorCpu::forward: output holds {} floats, need {}", out.size(), count * outC * R * R);
  const size_t rows0 = size_t(a.convChannels.front()) * kBase * kBase;
  bias0_.resize(rows0);
  for (size_t r = 0; r < rows0; ++r) {
    float s = weights_.linearBias[r];
    for (size_t c = 0; c < C; ++c) s += weights_.linearWeight[r * in + L + c] * cond[c];
    bias0_[r] = s;
  }
  for (size_t p0 = 0; p0 < count; p0 += chunk_) {
    size_t n = std::min(chunk_, count - p0);
    forwardChunk(latents.data() + p0 * L, n, out.data() + p0 * outC * R * R);
  }
}

void GeneratorCpu::forwardChunk(const float* latents, size_t P, float* out) {
  const GeneratorArch& a = weights_.arch;
  const size_t L = size_t(a.latentDim), in = L + size_t(a.condDim);
  const size_t rows0 = size_t(a.convChannels.front()) * kBase * kBase;

  zt_.resize(L * P);
  for (size_t p = 0; p < P; ++p)
    for (size_t k = 0; k < L; ++k) zt_[k * P + p] = latents[p * L + k];
  act_.resize(rows0 * P);
  for (size_t r = 0; r < rows0; ++r) std::fill_n(act_.data() + r * P, P, bias0_[r]);
  cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, int(rows0), int(P), int(L), 1.0f,
              weights_.linearWeight.data(), int(in), zt_.data(), int(P), 1.0f, act_.data(), int(P));
  for (float& v : act_) v = std::max(v, 0.0f);

  size_t res = kBase;
  for (int layer = 0; layer < a.layers(); ++layer) {
    const size_t ci = size_t(a.convChannels[size_t(layer)]), co = size_t(a.convChannels[size_t(layer) + 1]);
    const size_t ores = res * 2, cols = res * res * P;
    const bool hidden = layer + 1 < a.layers();
    cols_.resize(kTaps * co * cols);
    // W is [Ci][Co*16] row-major, so op(A) = W^T gives one row per (o, ky, kx).
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, int(kTaps * co), int(cols), int(ci), 1.0f,
                weights_.convWeight[size_t(layer)].data(), int(kTaps * co), act_.data(), int(cols), 0.0f,
                cols_.data(), int(cols));
    next_.resize(co * ores * ores * P);
    const float* bias = weights_.convBias[size_t(layer)].data();
    // The gather is a third of the time at one thread; output channels split across the cores.
    parallelFor(co, [&](size_t oBegin, size_t oEnd) {
      for (size_t o = oBegin; o < oEnd; ++o)
        for (int oy = 0; oy < int(ores); ++oy) {
          TapPair ty = tapsFor(oy);
          for (int ox = 0; ox < int(ores); ++ox) {
            TapPair tx = tapsFor(ox);
            const float* src[4];
            int nsrc = 0;
            for (int a2 = 0; a2 < 2; ++a2) {
              if (ty.i[a2] < 0 || ty.i[a2] >= int(res)) continue;
              for (int b2 = 0; b2 < 2; ++b2) {
                if (tx.i[b2] < 0 || tx.i[b2] >= int(res)) continue;
                size_t row = o * kTaps + size_t(ty.k[a2] * kGeneratorKernel + tx.k[b2]);
                src[nsrc++] = cols_.data() + row * cols + (size_t(ty.i[a2]) * res + size_t(tx.i[b2])) * P;
              }
            }
            float* dst = next_.data() + ((o * ores + size_t(oy)) * ores + size_t(ox)) * P;
            const float b = bias[o];
            if (nsrc == 4) {
              const float *s0 = src[0], *s1 = src[1], *s2 = src[2], *s3 = src[3];
              if (hidden)
                for (size_t p = 0; p < P; ++p)
                  dst[p] = std::max(b + ((s0[p] + s1[p]) + (s2[p] + s3[p])), 0.0f);
              else
                for (size_t p = 0; p < P; ++p) dst[p] = b + ((s0[p] + s1[p]) + (s2[p] + s3[p]));
            } else {
              std::fill_n(dst, P, b);
              for (int s = 0; s < nsrc; ++s)
                for (size_t p = 0; p < P; ++p) dst[p] += src[s][p];
              if (hidden)
                for (size_t p = 0; p < P; ++p) dst[p] = std::max(dst[p], 0.0f);
            }
          }
        }
    });
    act_.swap(next_);
    res = ores;
  }
  // [outC R R][P] -> [P][outC R R], in blocks that stay in L1.
  const size_t per = size_t(a.outChannels()) * res * res;
  constexpr size_t kBlock = 16;
  parallelFor((P + kBlock - 1) / kBlock, [&](size_t b0, size_t b1) {
    for (size_t p0 = b0 * kBlock; p0 < std::min(P, b1 * kBlock); p0 += kBlock)
      for (size_t t0 = 0; t0 < per; t0 += kBlock) {
        size_t t1 = std::min(per, t0 + kBlock), p1 = std::min(P, p0 + kBlock);
        for (size_t p = p0; p < p1; ++p)
          for (size_t t = t0; t < t1; ++t) out[p * per + t] = act_[t * P + p];
      }
  });
}

void decodeProbeField(GeneratorCpu& decoder, std::span<const float> latents, std::span<const float> cond,
                      const GeneratorOutputScale& scale, ProbeField& field) {
  const GeneratorArch& a = decoder.arch();
  if (a.outChannels() != kGeneratorChannels)
    fail("decodeProbeField: the model emits {} channels, a probe field needs {}", a.outChannels(),
         kGeneratorChannels);
  if (field.resolution != a.outputResolution())
    fail("decodeProbeField: ProbeField.resolution = {} but the model decodes {}x{} maps", field.resolution,
         a.outputResolution(), a.outputResolution());
  const size_t count = size_t(field.probeCount()), L = size_t(a.latentDim);
  if (latents.size() != count * L)
    fail("decodeProbeField: {} latent floats for {} probes of {}", latents.size(), count, L);
  const size_t T = size_t(field.resolution) * size_t(field.resolution), raw = size_t(kGeneratorChannels) * T;
  field.radiance.resize(count * T * 3);
  field.distance.resize(count * T * 2);
  field.normal.resize(count * T * 3);
  field.albedo.resize(count * T * 3);
  const size_t batch = std::max<size_t>(decoder.chunkProbes(), 1);
  std::vector<float> out(batch * raw);
  for (size_t p0 = 0; p0 < count; p0 += batch) {
    const size_t n = std::min(batch, count - p0);
    std::span<float> o(out.data(), n * raw);
    decoder.forward(latents.subspan(p0 * L, n * L), cond, n, o);
    for (size_t p = p0; p < p0 + n; ++p)
      decodeChannels(o.subspan((p - p0) * raw, raw), field.resolution, scale,
                     std::span(field.radiance).subspan(p * T * 3, T * 3),
                     std::span(field.distance).subspan(p * T * 2, T * 2),
                     std::span(field.normal).subspan(p * T * 3, T * 3),
                     std::span(field.albedo).subspan(p * T * 3, T * 3));
  }
}

GeneratorWeights randomGeneratorWeights(const GeneratorArch& arch, unsigned seed) {
  arch.validate();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ub(-0.1f, 0.1f);
  auto fill = [&](std::vector<float>& v, size_t n, double fanIn) {
    std::normal_distribution<float> nd(0.0f, float(std::sqrt(2.0 / fanIn)));
    v.resize(n);
    for (float& x : v) x = nd(rng);
  };
  auto fillBias = [&](std::vector<float>& v, size_t n) {
    v.resize(n);
    for (float& x : v) x = ub(rng);
  };
  GeneratorWeights w;
  w.arch = arch;
  const size_t rows0 = size_t(arch.convChannels.front()) * kBase * kBase;
  fill(w.linearWeight, rows0 * size_t(arch.inputDim()), arch.inputDim());
  fillBias(w.linearBias, rows0);
  for (int l = 0; l < arch.layers(); ++l) {
    size_t ci = size_t(arch.convChannels[size_t(l)]), co = size_t(arch.convChannels[size_t(l) + 1]);
    w.convWeight.emplace_back();
    w.convBias.emplace_back();
    fill(w.convWeight.back(), ci * co * kTaps, 4.0 * double(ci));
    fillBias(w.convBias.back(), co);
  }
  return w;
}

}  // namespace lfgi
