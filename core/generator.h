// The per-cell generative probe codec's network (docs/DESIGN.md §4): a DCGAN-style generator (Radford et al.
// 2015, "Unsupervised Representation Learning with Deep Convolutional GANs") that decodes one probe's
// octahedral maps from a small latent code plus a lighting conditioning vector.
//
//   input  x = [z (latentDim) | c (condDim)]                               z: per-probe latent
//   linear h0 = ReLU(W0 x + b0), reshaped to [C0][4][4]                   W0: [16*C0][latentDim+condDim]
//   for i in 0..k-1:  h(i+1) = ConvTranspose2d(h(i), C(i) -> C(i+1), kernel 4, stride 2, padding 1)
//                     (+ ReLU for every layer but the last)            spatial size 4 << (i+1)
//   output y = h(k): [outChannels][R][R], R = 4 << k, one probe's octahedral maps (texel (i, j) of a
//                     channel at j * R + i, the core/octahedral.h interior layout)
//
// Weight layouts are exactly PyTorch's, row-major, so a state_dict exports without reshuffling:
//   Linear weight [out][in], bias [out];  ConvTranspose2d weight [in][out][4][4], bias [out].
// ConvTranspose2d (stride 2, padding 1, kernel 4): y[o][oy][ox] = b[o] + sum_{i,ky,kx} x[i][iy][ix] *
//   w[i][o][ky][kx] over oy = 2*iy - 1 + ky, ox = 2*ix - 1 + kx (terms outside the output are dropped).
//
// Output channels (kGeneratorChannels = 11) and their encodings (decodeChannels() inverts them):
//   0..2  radiance rgb        y = log1p(L / exposure)      ->  L = exposure * expm1(clamp(y, 0, 20)) (NaN ->
//   0) 3..4  distance moments    y = (r / range, r^2 / range^2) -> r = y * range, r^2 = max(y, 0) * range^2
//   5..7  normal xyz          y = n                         ->  n = normalize(y) (0 if |y| ~ 0)
//   8..10 albedo rgb          y = a                         ->  a = clamp(y, 0, 1)
//
// Conditioning: c = conditioningVector(timeOfDayHours, weather), condDim = 3.
// Latents: stored per probe (LatentSource::Stored), or derived from the probe's normalised position in its
// cell with Fourier features (LatentSource::PositionFourier: zero latent bytes; the paper's "z tied to
// probe position").
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace lfgi {

inline constexpr int kGeneratorChannels = 11;
inline constexpr int kGeneratorKernel = 4;
inline constexpr int kConditioningDim = 3;

enum class LatentSource : uint8_t { Stored = 0, PositionFourier = 1 };

struct GeneratorArch {
  int latentDim = 16;              // [1, 256]; for PositionFourier: 6 * fourierOctaves
  int condDim = kConditioningDim;  // 0 (no conditioning) or kConditioningDim
  // Channels of each stage: convChannels[0] = C0 (the 4x4 base), ..., convChannels[k] = outChannels.
  // k = convChannels.size() - 1 transposed-conv layers, output resolution 4 << k (k in [1, 5]).
  std::vector<int> convChannels = {32, 16, kGeneratorChannels};
  LatentSource latentSource = LatentSource::Stored;
  int fourierOctaves = 0;  // PositionFourier only

  int layers() const { return int(convChannels.size()) - 1; }
  int outputResolution() const { return 4 << layers(); }
  int outChannels() const { return convChannels.back(); }
  int inputDim() const { return latentDim + condDim; }
  // Number of float parameters (weights + biases).
  size_t parameterCount() const;
  // Multiply-adds to decode one probe.
  double macsPerProbe() const;
  // Throws lfgi::Error naming the bad field.
  void validate() const;
};

// Float weights (what every decoder runs on; quantized storage dequantizes into this).
struct GeneratorWeights {
  GeneratorArch arch;
  std::vector<float> linearWeight;             // [16*C0][inputDim]
  std::vector<float> linearBias;               // [16*C0]
  std::vector<std::vector<float>> convWeight;  // layer i: [C(i)][C(i+1)][4][4]
  std::vector<std::vector<float>> convBias;    // layer i: [C(i+1)]
  // Throws lfgi::Error unless every array has the size the arch implies and every value is finite.
  void validate() const;
};

// FNV-1a of the architecture and every weight and bias bit pattern: the identity of a shared model that
// cells refer to.
uint64_t weightsContentHash(const GeneratorWeights& weights);

// Decoding constants of one cell (stored in the cell file next to the weights).
struct GeneratorOutputScale {
  float exposure = 1.0f;  // radiance unit of channel 0..2 (> 0)
  float range = 64.0f;    // metres; distance normaliser of channels 3..4 (> 0)
};

// Per-cell adapter of a world-shared generator (bake/generator_training.h, "shared generator"): FiLM
// (Perez et al. 2018) on the pre-activations of the first `stages` stages. Stage 0 is the linear layer's
// output (channel c = rows c*16 .. c*16+15 of [C0][4][4]), stage s >= 1 the output of transposed conv
// s-1 (C(s) channels; s = layers() is the network's output). Stage s computes
//   h'[c] = (1 + scale[c]) * h[c] + shift[c]            (before the ReLU, where there is one)
// scale and shift hold the stages' channels back to back (stage 0 first). Zero scale and shift are the
// identity. Because FiLM is affine per output channel it folds exactly into that layer's weights and bias
// (applyAdapter), so every decoder (CPU, GPU) runs a shared model + adapter as a plain GeneratorWeights.
struct GeneratorAdapter {
  int stages = 0;                   // [0, layers() + 1]
  std::vector<float> scale, shift;  // adapterChannels(arch, stages) each
  // Throws lfgi::Error unless stages is in range for arch, both arrays have adapterChannels() floats and
  // every value is finite.
  void validate(const GeneratorArch& arch) const;
};
// Channels the first `stages` stages of arch have in total (C0 + C1 + ... ).
size_t adapterChannels(const GeneratorArch& arch, int stages);
// The identity adapter (zeros) of `stages` stages.
GeneratorAdapter identityAdapter(const GeneratorArch& arch, int stages);
// The shared weights with the adapter folded in: W'[c] = (1 + scale[c]) W[c], b'[c] = (1 + scale[c]) b[c]
// + shift[c] per output channel c of each adapted stage. Equal to running FiLM after the layer up to float
// rounding (~1 ulp per element).
GeneratorWeights applyAdapter(const GeneratorWeights& shared, const GeneratorAdapter& adapter);

// c = (sin(2 pi t / 24), cos(2 pi t / 24), weather), t in hours, weather in [0, 1] (0 clear, 1 overcast).
std::array<float, kConditioningDim> conditioningVector(float timeOfDayHours, float weather);

// Position-derived latent (LatentSource::PositionFourier): p01 = the probe's position normalised to
// [0, 1]^3 in its cell's probe box; z = [sin(2^o pi p01.a), cos(2^o pi p01.a)] for o < octaves, a = x, y, z
// (order: octave-major, then axis, then sin/cos). Writes 6 * octaves floats.
void positionLatent(glm::vec3 p01, int octaves, std::span<float> out);

// CPU reference decoder (core/generator.cpp; no libtorch): raw network outputs for `count` probes.
// latents: count * latentDim floats; cond: condDim floats shared by all probes (the frame's lighting);
// out: count * outChannels * R * R floats, probe-major, then channel, then texel. Throws lfgi::Error on
// size mismatches.
void generatorForward(const GeneratorWeights& weights, std::span<const float> latents,
                      std::span<const float> cond, size_t count, std::span<float> out);

// Inverts the output encodings above for one probe's raw output [outChannels][R][R] (outChannels must
// be kGeneratorChannels): radiance R*R*3, distance R*R*2, normal R*R*3, albedo R*R*3 (texel-major,
// interleaved), any of them may be empty to skip it.
void decodeChannels(std::span<const float> raw, int resolution, const GeneratorOutputScale& scale,
                    std::span<float> radiance, std::span<float> distance, std::span<float> normal,
                    std::span<float> albedo);

}  // namespace lfgi
