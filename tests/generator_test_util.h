// Test helpers shared by the generator decoder, quantization and cell-file tests (core/ and gpu/): random
// latents and weights with fixed seeds, and the relative max error the decoders are held to.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/generator.h"

namespace lfgi::test {

// count * dim standard-normal latents.
inline std::vector<float> randomLatents(size_t count, int dim, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> nd(0.0f, 1.0f);
  std::vector<float> z(count * size_t(dim));
  for (float& v : z) v = nd(rng);
  return z;
}

// max |a - b| / max |b|: fast decoders sum in a different order than the reference.
inline double relMaxError(const std::vector<float>& a, const std::vector<float>& b) {
  double scale = 0.0, err = 0.0;
  for (size_t i = 0; i < b.size(); ++i) {
    scale = std::max(scale, double(std::abs(b[i])));
    err = std::max(err, double(std::abs(a[i] - b[i])));
  }
  return err / std::max(scale, 1e-30);
}

// Every weight and bias uniform in [-amplitude, amplitude], drawn from rng in layer order.
inline GeneratorWeights uniformRandomWeights(const GeneratorArch& arch, std::mt19937& rng,
                                             float amplitude = 0.5f) {
  std::uniform_real_distribution<float> u(-amplitude, amplitude);
  auto fill = [&](size_t n) {
    std::vector<float> v(n);
    for (float& x : v) x = u(rng);
    return v;
  };
  GeneratorWeights w;
  w.arch = arch;
  const size_t c0 = size_t(arch.convChannels.front());
  w.linearWeight = fill(16 * c0 * size_t(arch.inputDim()));
  w.linearBias = fill(16 * c0);
  for (int i = 0; i < arch.layers(); ++i) {
    const size_t ci = size_t(arch.convChannels[size_t(i)]), co = size_t(arch.convChannels[size_t(i) + 1]);
    w.convWeight.push_back(fill(ci * co * 16));
    w.convBias.push_back(fill(co));
  }
  return w;
}

}  // namespace lfgi::test
