#include "core/quantize.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/half.h"

namespace lfgi {

namespace {

constexpr int64_t kTaps = int64_t(kGeneratorKernel) * kGeneratorKernel;
constexpr int64_t kBase = 16;  // the linear layer's output is [C0][4][4]

int maxCode(int bits) {
  return (1 << (bits - 1)) - 1;
}

void requireFinite(std::span<const float> x, const std::string& what) {
  for (size_t i = 0; i < x.size(); ++i)
    if (!std::isfinite(x[i])) fail("{}: element {} is {} (quantization needs finite values)", what, i, x[i]);
}

struct Shape {
  int64_t outer, channels, inner;
};

// Shapes of the tensors in QuantizedWeights order.
std::vector<Shape> tensorShapes(const GeneratorArch& a) {
  std::vector<Shape> s;
  int64_t c0 = a.convChannels.front();
  s.push_back({1, kBase * c0, a.inputDim()});
  s.push_back({1, kBase * c0, 1});
  for (int i = 0; i < a.layers(); ++i) {
    int64_t ci = a.convChannels[size_t(i)], co = a.convChannels[size_t(i) + 1];
    s.push_back({ci, co, kTaps});
    s.push_back({1, co, 1});
  }
  return s;
}

std::string tensorName(size_t k) {
  if (k == 0) return "linearWeight";
  if (k == 1) return "linearBias";
  return fmt::format("conv{}{}", (k - 2) / 2, k % 2 == 0 ? "Weight" : "Bias");
}

QuantizedTensor encodeTensor(std::span<const float> x, Shape s, TensorEncoding e, const std::string& what) {
  QuantizedTensor t;
  t.encoding = e;
  t.outer = s.outer;
  t.channels = s.channels;
  t.inner = s.inner;
  if (int64_t(x.size()) != t.elements())
    fail("{}: {} floats, the shape needs {}", what, x.size(), t.elements());
  requireFinite(x, what);
  switch (e) {
    case TensorEncoding::Float32:
      t.f32.assign(x.begin(), x.end());
      break;
    case TensorEncoding::Float16:
      t.f16.resize(x.size());
      for (size_t i = 0; i < x.size(); ++i) {
        if (std::fabs(x[i]) > kHalfMax)
          fail("{}: element {} = {} exceeds the FP16 range (65504); store this model as int8", what, i, x[i]);
        t.f16[i] = floatToHalfClamped(x[i]);
      }
      break;
    case TensorEncoding::Int8PerChannel: {
      PerChannelCodes q = quantizePerChannel(x, s.outer, s.channels, s.inner, 8, what);
      t.codes = std::move(q.codes);
      t.scales = std::move(q.scales);
      break;
    }
  }
  return t;
}

std::vector<float> decodeTensor(const QuantizedTensor& t) {
  switch (t.encoding) {
    case TensorEncoding::Float32:
      return t.f32;
    case TensorEncoding::Float16: {
      std::vector<float> x(t.f16.size());
      halfToFloat(t.f16, x);
      return x;
    }
    case TensorEncoding::Int8PerChannel:
      return dequantizePerChannel(t.codes, t.scales, t.outer, t.channels, t.inner);
  }
  fail("QuantizedTensor: unknown encoding {}", int(t.encoding));
}

}  // namespace

const char* weightPrecisionName(WeightPrecision p) {
  switch (p) {
    case WeightPrecision::Float16:
      return "fp16";
    case WeightPrecision::Int8:
      return "int8";
  }
  return "unknown";
}

size_t QuantizedTensor::bytes() const {
  return f32.size() * 4 + f16.size() * 2 + codes.size() + scales.size() * 4;
}

void QuantizedTensor::validate(const std::string& what) const {
  if (outer < 1 || channels < 1 || inner < 1)
    fail("{}: shape {}x{}x{} is empty", what, outer, channels, inner);
  size_t n = size_t(elements());
  auto want = [&](size_t have, size_t need, const char* field) {
    if (have != need) fail("{}: {} holds {} values, expected {}", what, field, have, need);
  };
  switch (encoding) {
    case TensorEncoding::Float32:
      want(f32.size(), n, "f32");
      want(f16.size() + codes.size() + scales.size(), 0, "f16/codes/scales");
      requireFinite(f32, what);
      break;
    case TensorEncoding::Float16:
      want(f16.size(), n, "f16");
      want(f32.size() + codes.size() + scales.size(), 0, "f32/codes/scales");
      for (size_t i = 0; i < n; ++i)
        if ((f16[i] & 0x7c00u) == 0x7c00u) fail("{}: FP16 element {} is Inf or NaN", what, i);
      break;
    case TensorEncoding::Int8PerChannel:
      want(codes.size(), n, "codes");
      want(scales.size(), size_t(channels), "scales");
      want(f32.size() + f16.size(), 0, "f32/f16");
      for (size_t i = 0; i < n; ++i)
        if (codes[i] < -127) fail("{}: code {} is -128 (symmetric int8 uses [-127, 127])", what, i);
      for (size_t c = 0; c < scales.size(); ++c)
        if (!std::isfinite(scales[c]) || scales[c] < 0.0f) fail("{}: scale {} is {}", what, c, scales[c]);
      break;
    default:
      fail("{}: unknown encoding {}", what, int(encoding));
  }
}

size_t QuantizedWeights::bytes() const {
  size_t n = 0;
  for (const QuantizedTensor& t : tensors) n += t.bytes();
  return n;
}

void QuantizedWeights::validate() const {
  arch.validate();
  if (precision != WeightPrecision::Float16 && precision != WeightPrecision::Int8)
    fail("QuantizedWeights: unknown precision {}", int(precision));
  std::vector<Shape> shapes = tensorShapes(arch);
  if (tensors.size() != shapes.size())
    fail("QuantizedWeights: {} tensors, the architecture has {}", tensors.size(), shapes.size());
  for (size_t k = 0; k < shapes.size(); ++k) {
    const QuantizedTensor& t = tensors[k];
    std::string what = "QuantizedWeights." + tensorName(k);
    if (t.outer != shapes[k].outer || t.channels != shapes[k].channels || t.inner != shapes[k].inner)
      fail("{}: shape {}x{}x{}, the architecture needs {}x{}x{}", what, t.outer, t.channels, t.inner,
           shapes[k].outer, shapes[k].channels, shapes[k].inner);
    bool bias = k % 2 == 1;
    TensorEncoding want = precision == WeightPrecision::Float16 ? TensorEncoding::Float16
                          : bias                                ? TensorEncoding::Float32
                                                                : TensorEncoding::Int8PerChannel;
    if (t.encoding != want)
      fail("{}: encoding {}, {} weights store {}", what, int(t.encoding), weightPrecisionName(precision),
           int(want));
    t.validate(what);
  }
}

size_t QuantizedLatents::bytes() const {
  return scales.size() * 4 + (size_t(count) * size_t(dim) * size_t(bits) + 7) / 8;
}

void QuantizedLatents::validate(const std::string& what) const {
  if (bits != 8 && bits != 4) fail("{}: {} bits per latent (supported: 8, 4)", what, bits);
  if (dim < 1 || dim > 256) fail("{}: latent dimension {} outside [1, 256]", what, dim);
  if (count < 0) fail("{}: negative count {}", what, count);
  if (scales.size() != size_t(dim)) fail("{}: {} scales for {} dimensions", what, scales.size(), dim);
  if (codes.size() != size_t(count) * size_t(dim))
    fail("{}: {} codes for {} probes of {} dimensions", what, codes.size(), count, dim);
  int m = maxCode(bits);
  for (size_t i = 0; i < codes.size(); ++i)
    if (codes[i] < -m || codes[i] > m)
      fail("{}: code {} = {} outside [-{}, {}]", what, i, int(codes[i]), m, m);
  for (size_t d = 0; d < scales.size(); ++d)
    if (!std::isfinite(scales[d]) || scales[d] < 0.0f) fail("{}: scale {} is {}", what, d, scales[d]);
}

PerChannelCodes quantizePerChannel(std::span<const float> x, int64_t outer, int64_t channels, int64_t inner,
                                   int bits, const std::string& what) {
  if (bits < 2 || bits > 8) fail("{}: {} bits (supported: 2..8)", what, bits);
  if (outer < 0 || channels < 0 || inner < 0 || int64_t(x.size()) != outer * channels * inner)
    fail("{}: {} floats for shape {}x{}x{}", what, x.size(), outer, channels, inner);
  requireFinite(x, what);
  const int m = maxCode(bits);
  PerChannelCodes q;
  q.scales.assign(size_t(channels), 0.0f);
  std::vector<float> maxAbs(size_t(channels), 0.0f);
  for (int64_t a = 0; a < outer; ++a)
    for (int64_t c = 0; c < channels; ++c)
      for (int64_t t = 0; t < inner; ++t)
        maxAbs[size_t(c)] = std::max(maxAbs[size_t(c)], std::fabs(x[size_t((a * channels + c) * inner + t)]));
  for (size_t c = 0; c < size_t(channels); ++c) q.scales[c] = maxAbs[c] / float(m);
  q.codes.resize(x.size());
  for (int64_t a = 0; a < outer; ++a)
    for (int64_t c = 0; c < channels; ++c) {
      float s = q.scales[size_t(c)];
      for (int64_t t = 0; t < inner; ++t) {
        size_t i = size_t((a * channels + c) * inner + t);
        // s == 0 only for an all-zero channel (or one below FLT_TRUE_MIN * m): code 0.
        float r = s > 0.0f ? std::nearbyint(x[i] / s) : 0.0f;
        q.codes[i] = int8_t(std::clamp(r, float(-m), float(m)));
      }
    }
  return q;
}

std::vector<float> dequantizePerChannel(std::span<const int8_t> codes, std::span<const float> scales,
                                        int64_t outer, int64_t channels, int64_t inner) {
  if (int64_t(codes.size()) != outer * channels * inner || int64_t(scales.size()) != channels)
    fail("dequantizePerChannel: {} codes and {} scales for shape {}x{}x{}", codes.size(), scales.size(),
         outer, channels, inner);
  std::vector<float> x(codes.size());
  for (int64_t a = 0; a < outer; ++a)
    for (int64_t c = 0; c < channels; ++c)
      for (int64_t t = 0; t < inner; ++t) {
        size_t i = size_t((a * channels + c) * inner + t);
        x[i] = float(codes[i]) * scales[size_t(c)];
      }
  return x;
}

QuantizedWeights quantizeWeights(const GeneratorWeights& w, WeightPrecision precision) {
  w.arch.validate();
  if (precision != WeightPrecision::Float16 && precision != WeightPrecision::Int8)
    fail("quantizeWeights: unknown precision {}", int(precision));
  std::vector<Shape> shapes = tensorShapes(w.arch);
  std::vector<std::span<const float>> src{w.linearWeight, w.linearBias};
  if (w.convWeight.size() != size_t(w.arch.layers()) || w.convBias.size() != size_t(w.arch.layers()))
    fail("quantizeWeights: {} conv weight and {} bias arrays, the architecture has {} layers",
         w.convWeight.size(), w.convBias.size(), w.arch.layers());
  for (int i = 0; i < w.arch.layers(); ++i) {
    src.push_back(w.convWeight[size_t(i)]);
    src.push_back(w.convBias[size_t(i)]);
  }
  QuantizedWeights q;
  q.arch = w.arch;
  q.precision = precision;
  for (size_t k = 0; k < shapes.size(); ++k) {
    bool bias = k % 2 == 1;
    TensorEncoding e = precision == WeightPrecision::Float16 ? TensorEncoding::Float16
                       : bias                                ? TensorEncoding::Float32
                                                             : TensorEncoding::Int8PerChannel;
    q.tensors.push_back(
        encodeTensor(src[k], shapes[k], e, "quantizeWeights: GeneratorWeights." + tensorName(k)));
  }
  return q;
}

GeneratorWeights dequantizeWeights(const QuantizedWeights& q) {
  q.validate();
  GeneratorWeights w;
  w.arch = q.arch;
  w.linearWeight = decodeTensor(q.tensors[0]);
  w.linearBias = decodeTensor(q.tensors[1]);
  for (int i = 0; i < q.arch.layers(); ++i) {
    w.convWeight.push_back(decodeTensor(q.tensors[size_t(2 + 2 * i)]));
    w.convBias.push_back(decodeTensor(q.tensors[size_t(3 + 2 * i)]));
  }
  return w;
}

QuantizedLatents quantizeLatents(std::span<const float> latents, int dim, int bits) {
  if (bits != 8 && bits != 4) fail("quantizeLatents: {} bits per latent (supported: 8, 4)", bits);
  if (dim < 1 || dim > 256) fail("quantizeLatents: latent dimension {} outside [1, 256]", dim);
  if (latents.size() % size_t(dim) != 0)
    fail("quantizeLatents: {} floats is not a whole number of {}-dimensional latents", latents.size(), dim);
  QuantizedLatents q;
  q.dim = dim;
  q.bits = bits;
  q.count = int64_t(latents.size() / size_t(dim));
  // [count][dim] is [outer = count][channels = dim][inner = 1]: one scale per latent dimension.
  PerChannelCodes c = quantizePerChannel(latents, q.count, dim, 1, bits, "quantizeLatents: latents");
  q.codes = std::move(c.codes);
  q.scales = std::move(c.scales);
  return q;
}

std::vector<float> dequantizeLatents(const QuantizedLatents& q) {
  q.validate("dequantizeLatents");
  return dequantizePerChannel(q.codes, q.scales, q.count, q.dim, 1);
}

size_t QuantizedAdapter::bytes() const {
  return 1 + scales.size() * 4 + (codes.size() * size_t(bits) + 7) / 8;
}

void QuantizedAdapter::validateHeader(const GeneratorArch& arch, const std::string& what) const {
  if (stages < 0 || stages > arch.layers() + 1)
    fail("{}: {} adapter stages, the model has {} (layers + 1)", what, stages, arch.layers() + 1);
  if (channels != int64_t(adapterChannels(arch, stages)))
    fail("{}: adapter of {} channels, {} stages of the model have {}", what, channels, stages,
         adapterChannels(arch, stages));
  if (bits != 8 && bits != 4) fail("{}: {} bits per adapter code (supported: 8, 4)", what, bits);
}

void QuantizedAdapter::validate(const GeneratorArch& arch, const std::string& what) const {
  validateHeader(arch, what);
  const size_t wantScales = channels > 0 ? 2 : 0;
  if (scales.size() != wantScales)
    fail("{}: {} adapter scales, {} expected", what, scales.size(), wantScales);
  if (codes.size() != size_t(2 * channels))
    fail("{}: {} adapter codes for 2 x {} channels", what, codes.size(), channels);
  const int m = maxCode(bits);
  for (size_t i = 0; i < codes.size(); ++i)
    if (codes[i] < -m || codes[i] > m)
      fail("{}: adapter code {} = {} outside [-{}, {}]", what, i, int(codes[i]), m, m);
  for (size_t i = 0; i < scales.size(); ++i)
    if (!std::isfinite(scales[i]) || scales[i] < 0.0f) fail("{}: adapter scale {} is {}", what, i, scales[i]);
}

QuantizedAdapter quantizeAdapter(const GeneratorAdapter& adapter, int bits) {
  if (adapter.scale.size() != adapter.shift.size())
    fail("quantizeAdapter: {} scale and {} shift floats", adapter.scale.size(), adapter.shift.size());
  QuantizedAdapter q;
  q.stages = adapter.stages;
  q.bits = bits;
  q.channels = int64_t(adapter.scale.size());
  if (q.channels == 0) return q;
  std::vector<float> x = adapter.scale;
  x.insert(x.end(), adapter.shift.begin(), adapter.shift.end());
  PerChannelCodes c = quantizePerChannel(x, 1, 2, q.channels, bits, "adapter");
  q.codes = std::move(c.codes);
  q.scales = std::move(c.scales);
  return q;
}

GeneratorAdapter dequantizeAdapter(const QuantizedAdapter& q) {
  GeneratorAdapter a;
  a.stages = q.stages;
  if (q.channels == 0) return a;
  if (q.codes.size() != size_t(2 * q.channels) || q.scales.size() != 2)
    fail("QuantizedAdapter: {} codes and {} scales for {} channels", q.codes.size(), q.scales.size(),
         q.channels);
  const std::vector<float> x = dequantizePerChannel(q.codes, q.scales, 1, 2, q.channels);
  a.scale.assign(x.begin(), x.begin() + q.channels);
  a.shift.assign(x.begin() + q.channels, x.end());
  return a;
}

}  // namespace lfgi
