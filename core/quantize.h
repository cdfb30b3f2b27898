// Quantized storage of the per-cell generator (docs/DESIGN.md §4 "Quantization"): weights as FP16 or as int8
// symmetric per output channel, latents as int8 (or 4-bit) symmetric per latent dimension. Decoders never
// see these types: dequantize*() turns them back into the floats core/generator.h runs on, so every
// decoder (CPU, GPU) decodes exactly what the cell file stores.
//
// Symmetric quantization with b bits: codes q in [-M, M], M = 2^(b-1) - 1 (127 for int8, 7 for 4-bit),
// one scale s per channel, s = max|x| / M over the channel, q = round(x / s), x' = q * s. So
// |x - x'| <= s / 2 (up to float rounding of x / s), values on the grid (x = k * s, |k| <= M, with the
// channel's max on the grid too) come back exactly, and an all-zero channel has s = 0 and decodes to 0.
// The code -2^(b-1) is never produced (so the range is symmetric and negation is exact).
//
// Channels (what a scale is shared over):
//   Linear weight [out][in]                 -> one scale per output row (out)
//   ConvTranspose2d weight [in][out][4][4]  -> one scale per output channel (out), i.e. strided
//   biases                                  -> kept as float32 in int8 mode (a few hundred floats; a bias
//                                              error shifts a whole output channel), FP16 in FP16 mode
//   latents [count][L]                      -> one scale per latent dimension (L)
// Every function rejects NaN/Inf inputs with an lfgi::Error naming the tensor and the element, and FP16
// quantization rejects |x| > 65504 (it would clamp; use int8, which has no range limit).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/generator.h"

namespace lfgi {

enum class WeightPrecision : uint8_t { Float16 = 1, Int8 = 2 };
const char* weightPrecisionName(WeightPrecision p);  // "fp16", "int8"

// How one tensor is stored.
enum class TensorEncoding : uint8_t { Float32 = 0, Float16 = 1, Int8PerChannel = 2 };

// One weight or bias array. Element (a, c, t) sits at (a * channels + c) * inner + t; c is the output
// channel a scale belongs to. Linear weight: outer 1, channels out, inner in. ConvTranspose2d weight:
// outer in, channels out, inner 16. Bias: outer 1, channels out, inner 1.
struct QuantizedTensor {
  TensorEncoding encoding = TensorEncoding::Float32;
  int64_t outer = 0, channels = 0, inner = 0;
  std::vector<float> f32;     // Float32: elements
  std::vector<uint16_t> f16;  // Float16: elements (IEEE binary16 bits)
  std::vector<int8_t> codes;  // Int8PerChannel: elements, each in [-127, 127]
  std::vector<float> scales;  // Int8PerChannel: channels scales (>= 0, finite)

  int64_t elements() const { return outer * channels * inner; }
  // Stored bytes: 4 per f32, 2 per f16, 1 per code, 4 per scale.
  size_t bytes() const;
  // Throws lfgi::Error(what + ": ...") unless the arrays match the encoding and shape, codes are in
  // range and every float is finite.
  void validate(const std::string& what) const;
};

// A generator's weights as stored. tensors: linearWeight, linearBias, then per conv layer i its weight
// and bias (2 + 2 * layers tensors), shaped as above.
struct QuantizedWeights {
  GeneratorArch arch;
  WeightPrecision precision = WeightPrecision::Int8;
  std::vector<QuantizedTensor> tensors;

  size_t bytes() const;  // sum of tensor bytes (the architecture itself is metadata)
  // Throws lfgi::Error unless arch is valid and every tensor has the shape and encoding the arch and
  // precision imply.
  void validate() const;
};

// Per-probe latents as stored: codes [count][dim] in [-M, M] (M = 127 for 8 bits, 7 for 4 bits), one
// scale per dimension.
struct QuantizedLatents {
  int dim = 0;
  int bits = 8;  // 8 or 4
  int64_t count = 0;
  std::vector<float> scales;  // dim
  std::vector<int8_t> codes;  // count * dim (4-bit codes are held one per byte here, packed in files)

  // Stored bytes: 4 per scale + ceil(count * dim * bits / 8) for the packed codes.
  size_t bytes() const;
  void validate(const std::string& what) const;
};

// Per-channel symmetric quantization of x laid out [outer][channels][inner] with `bits` in [2, 8].
// Throws on a size mismatch or a non-finite element (message starts with `what`).
struct PerChannelCodes {
  std::vector<int8_t> codes;
  std::vector<float> scales;
};
PerChannelCodes quantizePerChannel(std::span<const float> x, int64_t outer, int64_t channels, int64_t inner,
                                   int bits, const std::string& what);
// x'[(a * channels + c) * inner + t] = codes[...] * scales[c].
std::vector<float> dequantizePerChannel(std::span<const int8_t> codes, std::span<const float> scales,
                                        int64_t outer, int64_t channels, int64_t inner);

QuantizedWeights quantizeWeights(const GeneratorWeights& weights, WeightPrecision precision);
GeneratorWeights dequantizeWeights(const QuantizedWeights& weights);

// latents: count * dim floats, probe-major. bits 8 or 4.
QuantizedLatents quantizeLatents(std::span<const float> latents, int dim, int bits = 8);
std::vector<float> dequantizeLatents(const QuantizedLatents& latents);

// A per-cell generator adapter (core/generator.h GeneratorAdapter) as stored: its scale and shift
// arrays as two channels of one symmetric per-channel tensor (one scale each), `bits` in [2, 8].
struct QuantizedAdapter {
  int stages = 0;
  int bits = 8;
  int64_t channels = 0;       // adapterChannels(arch, stages): floats per array
  std::vector<float> scales;  // 2: of the scale array, of the shift array
  std::vector<int8_t> codes;  // 2 * channels: scale codes, then shift codes

  // Stored bytes: 1 (stages) + 4 per scale + ceil(2 * channels * bits / 8) packed codes.
  size_t bytes() const;
  // Throws lfgi::Error(what + ": ...") unless stages is in [0, arch.layers() + 1], channels is
  // adapterChannels(arch, stages), bits is 8 or 4, there are 2 scales (none with 0 channels), finite and
  // >= 0, and 2 * channels codes in [-M, M].
  void validate(const GeneratorArch& arch, const std::string& what) const;
  // The stages / channels / bits part of validate alone (a reader checks it before sizing the arrays).
  void validateHeader(const GeneratorArch& arch, const std::string& what) const;
};
QuantizedAdapter quantizeAdapter(const GeneratorAdapter& adapter, int bits = 8);
GeneratorAdapter dequantizeAdapter(const QuantizedAdapter& adapter);

}  // namespace lfgi
