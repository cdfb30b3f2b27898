#include "core/generator.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.h"
#include "core/hash.h"

namespace lfgi {

namespace {

constexpr int kBase = 4;  // the linear layer's output is [C0][4][4]
constexpr int kTaps = kGeneratorKernel * kGeneratorKernel;

bool allFinite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
}

}  // namespace

size_t GeneratorArch::parameterCount() const {
  size_t c0 = size_t(convChannels.front());
  size_t n = c0 * kBase * kBase * size_t(inputDim()) + c0 * kBase * kBase;
  for (int i = 0; i < layers(); ++i)
    n += size_t(convChannels[size_t(i)]) * size_t(convChannels[size_t(i) + 1]) * kTaps +
         size_t(convChannels[size_t(i) + 1]);
  return n;
}

double GeneratorArch::macsPerProbe() const {
  double macs = double(convChannels.front()) * kBase * kBase * inputDim();
  int inRes = kBase;
  for (int i = 0; i < layers(); ++i) {
    // every input texel scatters into kTaps output texels (minus the dropped border terms)
    macs += double(convChannels[size_t(i)]) * convChannels[size_t(i) + 1] * inRes * inRes * kTaps;
    inRes *= 2;
  }
  return macs;
}

void GeneratorArch::validate() const {
  if (latentDim < 1 || latentDim > 256) fail("GeneratorArch.latentDim = {} outside [1, 256]", latentDim);
  if (condDim != 0 && condDim != kConditioningDim)
    fail("GeneratorArch.condDim = {}: must be 0 or {}", condDim, kConditioningDim);
  if (convChannels.size() < 2 || convChannels.size() > 6)
    fail("GeneratorArch.convChannels has {} entries: need 2..6 (1..5 transposed-conv layers)",
         convChannels.size());
  for (size_t i = 0; i < convChannels.size(); ++i)
    if (convChannels[i] < 1 || convChannels[i] > 1024)
      fail("GeneratorArch.convChannels[{}] = {} outside [1, 1024]", i, convChannels[i]);
  if (latentSource == LatentSource::PositionFourier) {
    if (fourierOctaves < 1 || fourierOctaves > 16)
      fail("GeneratorArch.fourierOctaves = {} outside [1, 16]", fourierOctaves);
    if (latentDim != 6 * fourierOctaves)
      fail("GeneratorArch.latentDim = {}: a position latent has 6 * fourierOctaves = {} values", latentDim,
           6 * fourierOctaves);
  } else if (latentSource != LatentSource::Stored) {
    fail("GeneratorArch.latentSource = {}: unknown", int(latentSource));
  }
}

void GeneratorWeights::validate() const {
  arch.validate();
  auto check = [](const std::vector<float>& v, size_t want, const char* name, int layer) {
    if (v.size() != want)
      fail("GeneratorWeights.{}[{}] holds {} floats, the architecture needs {}", name, layer, v.size(), want);
    if (!allFinite(v)) fail("GeneratorWeights.{}[{}] holds a non-finite value", name, layer);
  };
  size_t c0 = size_t(arch.convChannels.front());
  check(linearWeight, c0 * kBase * kBase * size_t(arch.inputDim()), "linearWeight", 0);
  check(linearBias, c0 * kBase * kBase, "linearBias", 0);
  if (convWeight.size() != size_t(arch.layers()) || convBias.size() != size_t(arch.layers()))
    fail("GeneratorWeights has {} conv weight and {} bias arrays, the architecture has {} layers",
         convWeight.size(), convBias.size(), arch.layers());
  for (int i = 0; i < arch.layers(); ++i) {
    size_t ci = size_t(arch.convChannels[size_t(i)]), co = size_t(arch.convChannels[size_t(i) + 1]);
    check(convWeight[size_t(i)], ci * co * kTaps, "convWeight", i);
    check(convBias[size_t(i)], co, "convBias", i);
  }
}

uint64_t weightsContentHash(const GeneratorWeights& w) {
  uint64_t h = kFnv1aOffset;
  const GeneratorArch& a = w.arch;
  for (int v : {a.latentDim, a.condDim, int(a.latentSource), a.fourierOctaves}) h = fnv1aValue(h, v);
  for (int c : a.convChannels) h = fnv1aValue(h, c);
  h = fnv1aSpan(h, w.linearWeight);
  h = fnv1aSpan(h, w.linearBias);
  for (const auto& v : w.convWeight) h = fnv1aSpan(h, v);
  for (const auto& v : w.convBias) h = fnv1aSpan(h, v);
  return h;
}

size_t adapterChannels(const GeneratorArch& arch, int stages) {
  size_t n = 0;
  for (int s = 0; s < stages && s < int(arch.convChannels.size()); ++s)
    n += size_t(arch.convChannels[size_t(s)]);
  return n;
}

GeneratorAdapter identityAdapter(const GeneratorArch& arch, int stages) {
  GeneratorAdapter a;
  a.stages = stages;
  a.scale.assign(adapterChannels(arch, stages), 0.0f);
  a.shift = a.scale;
  a.validate(arch);
  return a;
}

void GeneratorAdapter::validate(const GeneratorArch& arch) const {
  if (stages < 0 || stages > arch.layers() + 1)
    fail("GeneratorAdapter.stages = {} outside [0, {}] (layers + 1) of the shared model", stages,
         arch.layers() + 1);
  const size_t want = adapterChannels(arch, stages);
  if (scale.size() != want || shift.size() != want)
    fail("GeneratorAdapter holds {} scale and {} shift floats, {} stages of the shared model need {}",
         scale.size(), shift.size(), stages, want);
  if (!allFinite(scale) || !allFinite(shift)) fail("GeneratorAdapter holds a non-finite value");
}

GeneratorWeights applyAdapter(const GeneratorWeights& shared, const GeneratorAdapter& adapter) {
  shared.validate();
  const GeneratorArch& a = shared.arch;
  adapter.validate(a);
  GeneratorWeights w = shared;
  size_t base = 0;
  for (int s = 0; s < adapter.stages; ++s) {
    const size_t channels = size_t(a.convChannels[size_t(s)]);
    for (size_t c = 0; c < channels; ++c) {
      const float g = 1.0f + adapter.scale[base + c], b = adapter.shift[base + c];
      if (s == 0) {
        const size_t in = size_t(a.inputDim());
        for (size_t r = c * size_t(kBase * kBase); r < (c + 1) * size_t(kBase * kBase); ++r) {
          for (size_t i = 0; i < in; ++i) w.linearWeight[r * in + i] *= g;
          w.linearBias[r] = g * w.linearBias[r] + b;
        }
      } else {
        // ConvTranspose2d weight [in][out][4][4]: output channel c is strided over the inputs.
        std::vector<float>& cw = w.convWeight[size_t(s - 1)];
        const size_t ci = size_t(a.convChannels[size_t(s - 1)]);
        for (size_t i = 0; i < ci; ++i)
          for (size_t t = 0; t < size_t(kTaps); ++t) cw[(i * channels + c) * size_t(kTaps) + t] *= g;
        w.convBias[size_t(s - 1)][c] = g * w.convBias[size_t(s - 1)][c] + b;
      }
    }
    base += channels;
  }
  return w;
}

std::array<float, kConditioningDim> conditioningVector(float timeOfDayHours, float weather) {
  double a = 2.0 * std::numbers::pi * double(timeOfDayHours) / 24.0;
  return {float(std::sin(a)), float(std::cos(a)), std::clamp(weather, 0.0f, 1.0f)};
}

void positionLatent(glm::vec3 p01, int octaves, std::span<float> out) {
  if (out.size() < size_t(6 * octaves))
    fail("positionLatent: output holds {} floats, need {}", out.size(), 6 * octaves);
  size_t k = 0;
  for (int o = 0; o < octaves; ++o) {
    double f = std::ldexp(std::numbers::pi, o);
    for (int a = 0; a < 3; ++a) {
      out[k++] = float(std::sin(f * p01[a]));
      out[k++] = float(std::cos(f * p01[a]));
    }
  }
}

// Reference: plain loops in double accumulation order of the formulas in the header. Not fast; the
// fast CPU and GPU decoders are tested against it.
void generatorForward(const GeneratorWeights& w, std::span<const float> latents, std::span<const float> cond,
                      size_t count, std::span<float> out) {
  const GeneratorArch& a = w.arch;
  const size_t L = size_t(a.latentDim), C = size_t(a.condDim), in = L + C;
  const size_t R = size_t(a.outputResolution()), outC = size_t(a.outChannels());
  if (latents.size() != count * L)
    fail("generatorForward: {} latent floats for {} probes of {}", latents.size(), count, L);
  if (cond.size() != C) fail("generatorForward: {} conditioning floats, the model takes {}", cond.size(), C);
  if (out.size() != count * outC * R * R)
    fail("generatorForward: output holds {} floats, need {}", out.size(), count * outC * R * R);
  const size_t c0 = size_t(a.convChannels.front()), h0 = c0 * kBase * kBase;
  std::vector<float> x(in), cur, next;
  for (size_t p = 0; p < count; ++p) {
    std::copy_n(latents.begin() + ptrdiff_t(p * L), L, x.begin());
    std::copy(cond.begin(), cond.end(), x.begin() + ptrdiff_t(L));
    cur.assign(h0, 0.0f);
    for (size_t o = 0; o < h0; ++o) {
      float s = w.linearBias[o];
      for (size_t i = 0; i < in; ++i) s += w.linearWeight[o * in + i] * x[i];
      cur[o] = std::max(s, 0.0f);
    }
    size_t res = kBase;
    for (int layer = 0; layer < a.layers(); ++layer) {
      const size_t ci = size_t(a.convChannels[size_t(layer)]), co = size_t(a.convChannels[size_t(layer) + 1]);
      const size_t ores = res * 2;
      const std::vector<float>& wt = w.convWeight[size_t(layer)];
      next.assign(co * ores * ores, 0.0f);
      for (size_t o = 0; o < co; ++o)
        std::fill_n(next.begin() + ptrdiff_t(o * ores * ores), ores * ores, w.convBias[size_t(layer)][o]);
      for (size_t i = 0; i < ci; ++i)
        for (size_t iy = 0; iy < res; ++iy)
          for (size_t ix = 0; ix < res; ++ix) {
            float v = cur[(i * res + iy) * res + ix];
            if (v == 0.0f) continue;
            for (size_t o = 0; o < co; ++o) {
              const float* k = &wt[(i * co + o) * kTaps];
              for (int ky = 0; ky < kGeneratorKernel; ++ky) {
                ptrdiff_t oy = ptrdiff_t(2 * iy) - 1 + ky;
                if (oy < 0 || oy >= ptrdiff_t(ores)) continue;
                for (int kx = 0; kx < kGeneratorKernel; ++kx) {
                  ptrdiff_t ox = ptrdiff_t(2 * ix) - 1 + kx;
                  if (ox < 0 || ox >= ptrdiff_t(ores)) continue;
                  next[(o * ores + size_t(oy)) * ores + size_t(ox)] += v * k[ky * kGeneratorKernel + kx];
                }
              }
            }
          }
      if (layer + 1 < a.layers())
        for (float& v : next) v = std::max(v, 0.0f);
      cur.swap(next);
      res = ores;
    }
    std::copy(cur.begin(), cur.end(), out.begin() + ptrdiff_t(p * outC * R * R));
  }
}

void decodeChannels(std::span<const float> raw, int resolution, const GeneratorOutputScale& scale,
                    std::span<float> radiance, std::span<float> distance, std::span<float> normal,
                    std::span<float> albedo) {
  const size_t T = size_t(resolution) * size_t(resolution);
  if (raw.size() != size_t(kGeneratorChannels) * T)
    fail("decodeChannels: {} raw floats, need {} channels of {} texels", raw.size(), kGeneratorChannels, T);
  auto need = [T](std::span<float> s, size_t per, const char* name) {
    if (!s.empty() && s.size() != T * per)
      fail("decodeChannels: {} holds {} floats, need {}", name, s.size(), T * per);
  };
  need(radiance, 3, "radiance");
  need(distance, 2, "distance");
  need(normal, 3, "normal");
  need(albedo, 3, "albedo");
  auto ch = [&](int c, size_t t) { return raw[size_t(c) * T + t]; };
  const float range2 = scale.range * scale.range;
  for (size_t t = 0; t < T; ++t) {
    if (!radiance.empty())
      for (int c = 0; c < 3; ++c) {
        // Clamped to [0, 20] as training measures it (e^20 ~ 5e8 x exposure): an overflowing or NaN output
        // (a collapsed model, lighting far outside the keys) decodes finite instead of Inf/NaN.
        const float y = ch(c, t);
        radiance[t * 3 + size_t(c)] = scale.exposure * std::expm1(y > 0.0f ? std::min(y, 20.0f) : 0.0f);
      }
    if (!distance.empty()) {
      distance[t * 2 + 0] = ch(3, t) * scale.range;
      distance[t * 2 + 1] = std::max(ch(4, t), 0.0f) * range2;
    }
    if (!normal.empty()) {
      glm::vec3 n(ch(5, t), ch(6, t), ch(7, t));
      float len = glm::length(n);
      n = len > 1e-6f ? n / len : glm::vec3(0.0f);
      for (int c = 0; c < 3; ++c) normal[t * 3 + size_t(c)] = n[c];
    }
    if (!albedo.empty())
      for (int c = 0; c < 3; ++c) albedo[t * 3 + size_t(c)] = std::clamp(ch(8 + c, t), 0.0f, 1.0f);
  }
}

}  // namespace lfgi
