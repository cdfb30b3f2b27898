#include "core/probe_codecs.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>

#include <zstd.h>

#include "core/error.h"
#include "core/half.h"
#include "core/octahedral.h"
#include "core/probe_codecs_internal.h"
#include "core/sh.h"
#include "core/sh_high_order.h"
#include "core/sh_l1_q8.h"

namespace lfgi {

namespace codec_detail {

void writeHeader(ByteWriter& w, const Header& h) {
  w.raw(h.magic, 4);
  w.u8(h.version);
  w.u16(uint16_t(h.resolution));
  w.u32(uint32_t(h.probes));
}

Header readHeader(ByteReader& r, const char magic[4], uint8_t version, const ProbeField& out) {
  Header h;
  const std::byte* m = r.take(4, "magic");
  if (std::memcmp(m, magic, 4) != 0)
    fail("{} decode: magic '{}' is not this codec's '{}'", r.codec,
         std::string(reinterpret_cast<const char*>(m), 4), std::string(magic, 4));
  std::memcpy(h.magic, magic, 4);
  h.version = r.u8("version");
  if (h.version != version)
    fail("{} decode: format version {} (this build reads {})", r.codec, h.version, version);
  h.resolution = r.u16("resolution");
  h.probes = r.u32("probe count");
  if (h.resolution != out.resolution)
    fail("{} decode: map resolution {} but the field expects {}", r.codec, h.resolution, out.resolution);
  if (int64_t(h.probes) != out.probeCount())
    fail("{} decode: {} probes but the field's grid has {}", r.codec, h.probes, out.probeCount());
  return h;
}

void checkField(const char* codec, const ProbeField& f) {
  if (f.resolution < 1 || f.resolution > 256)
    fail("{} encode: resolution {} outside [1, 256]", codec, f.resolution);
  const int64_t P = f.probeCount();
  if (P < 1 || P > int64_t(UINT32_MAX)) fail("{} encode: {} probes outside [1, 2^32)", codec, P);
  const size_t want = size_t(P) * size_t(f.resolution) * size_t(f.resolution) * 3;
  if (f.radiance.size() != want)
    fail("{} encode: radiance holds {} floats, {} probes of {}x{} need {}", codec, f.radiance.size(), P,
         f.resolution, f.resolution, want);
  for (size_t i = 0; i < want; ++i)
    if (!std::isfinite(f.radiance[i]))
      fail("{} encode: radiance[{}] = {} is not finite", codec, i, f.radiance[i]);
}

void prepareOut(ProbeField& out) {
  if (out.resolution < 1 || out.resolution > 256)
    fail("probe codec decode: field resolution {} outside [1, 256]", out.resolution);
  out.radiance.assign(size_t(out.probeCount()) * size_t(out.resolution) * size_t(out.resolution) * 3, 0.0f);
  out.irradiance.clear();
}

}  // namespace codec_detail

using namespace codec_detail;

namespace {

// ---------------------------------------------------------------------------------------------- raw FP16

class RawFp16Codec final : public ProbeCodec {
 public:
  std::string name() const override { return "raw_fp16"; }
  std::string setting() const override { return ""; }
  std::vector<std::byte> encode(const ProbeField& f) const override {
    checkField("raw_fp16", f);
    ByteWriter w;
    writeHeader(w, {{'L', 'R', 'A', 'W'}, 1, f.resolution, uint32_t(f.probeCount())});
    w.halves(f.radiance);
    return std::move(w.bytes);
  }
  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "raw_fp16"};
    readHeader(r, "LRAW", 1, out);
    prepareOut(out);
    r.halves(out.radiance, "radiance");
    r.expectEnd();
  }
};

// -------------------------------------------------------------------------------------------- zstd FP16

class ZstdFp16Codec final : public ProbeCodec {
 public:
  explicit ZstdFp16Codec(int level) : level_(level) {
    if (level < 1 || level > ZSTD_maxCLevel())
      fail("zstd codec: level {} outside [1, {}]", level, ZSTD_maxCLevel());
  }
  std::string name() const override { return "zstd_fp16"; }
  std::string setting() const override { return fmt::format("level {}", level_); }
  std::vector<std::byte> encode(const ProbeField& f) const override {
    checkField("zstd_fp16", f);
    const float scale = exposureScale(f.radiance);
    const size_t count = f.radiance.size();
    std::vector<uint8_t> planes(2 * count);
    for (size_t i = 0; i < count; ++i) {
      const uint16_t h = floatToHalfClamped(f.radiance[i] / scale);
      planes[i] = uint8_t(h & 0xff);
      planes[count + i] = uint8_t(h >> 8);
    }
    ByteWriter w;
    writeHeader(w, {{'L', 'Z', 'S', 'T'}, 1, f.resolution, uint32_t(f.probeCount())});
    w.f32(scale);
    const size_t at = w.bytes.size();
    w.bytes.resize(at + ZSTD_compressBound(planes.size()));
    const size_t n =
        ZSTD_compress(w.bytes.data() + at, w.bytes.size() - at, planes.data(), planes.size(), level_);
    if (ZSTD_isError(n)) fail("zstd_fp16 encode: {}", ZSTD_getErrorName(n));
    w.bytes.resize(at + n);
    return std::move(w.bytes);
  }
  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "zstd_fp16"};
    readHeader(r, "LZST", 1, out);
    const float scale = r.f32("scale");
    if (!std::isfinite(scale) || scale <= 0.0f)
      fail("zstd_fp16 decode: scale {} is not a positive number", scale);
    prepareOut(out);
    const size_t count = out.radiance.size();
    const size_t left = bytes.size() - r.pos;
    const std::byte* src = r.take(left, "zstd frame");
    const unsigned long long content = ZSTD_getFrameContentSize(src, left);
    if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN || content != 2 * count)
      fail("zstd_fp16 decode: zstd frame is corrupt or holds {} bytes, the field needs {}",
           content >= ZSTD_CONTENTSIZE_ERROR ? 0ull : content, 2 * count);
    std::vector<uint8_t> planes(2 * count);
    const size_t n = ZSTD_decompress(planes.data(), planes.size(), src, left);
    if (ZSTD_isError(n)) fail("zstd_fp16 decode: {}", ZSTD_getErrorName(n));
    if (n != planes.size())
      fail("zstd_fp16 decode: frame decompressed to {} bytes, expected {}", n, planes.size());
    for (size_t i = 0; i < count; ++i) {
      const float v = halfToFloat(uint16_t(planes[i] | (uint16_t(planes[count + i]) << 8)));
      if (!std::isfinite(v)) fail("zstd_fp16 decode: value {} at index {} is not finite", v, i);
      out.radiance[i] = v * scale;
    }
  }

 private:
  int level_;
};

// -------------------------------------------------------------------------------------------------- SH

// Basis values at the texel centres of an n x n map ([texel][k], float), optionally times A_l (irradiance).
std::shared_ptr<const std::vector<float>> texelCentreBasis(int lmax, int n, bool irradiance) {
  static std::mutex mutex;
  static std::map<std::tuple<int, int, bool>, std::shared_ptr<const std::vector<float>>> cache;
  const std::tuple key(lmax, n, irradiance);
  const std::lock_guard lock(mutex);
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  const int K = shCoefficientCount(lmax);
  auto b = std::make_shared<std::vector<float>>(size_t(n) * size_t(n) * size_t(K));
  std::vector<double> y(static_cast<size_t>(K));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      shBasis(lmax, glm::dvec3(octTexelDirection(i, j, n)), y);
      for (int k = 0; k < K; ++k)
        (*b)[(size_t(j) * size_t(n) + size_t(i)) * size_t(K) + size_t(k)] =
            float(y[size_t(k)] * (irradiance ? shIrradianceFactor(shBandOf(k)) : 1.0));
    }
  return cache.emplace(key, std::move(b)).first->second;
}

void evaluateSh(const float* coeff, int K, const std::vector<float>& basis, size_t texels, float* outRgb) {
  for (size_t t = 0; t < texels; ++t) {
    const float* y = basis.data() + t * size_t(K);
    float r = 0.0f, g = 0.0f, b = 0.0f;
    for (int k = 0; k < K; ++k) {
      r += coeff[3 * k] * y[k];
      g += coeff[3 * k + 1] * y[k];
      b += coeff[3 * k + 2] * y[k];
    }
    outRgb[3 * t] = r;
    outRgb[3 * t + 1] = g;
    outRgb[3 * t + 2] = b;
  }
}

// SH coefficients of bands 0..lmax of every probe's radiance ([probe][k][rgb]), exact texel weights.
std::vector<float> projectSh(const ProbeField& f, int lmax) {
  const int n = f.resolution, K = shCoefficientCount(lmax);
  const size_t texels = size_t(n) * size_t(n), P = size_t(f.probeCount());
  const auto weights = shTexelWeightsHigh(lmax, n);
  std::vector<float> coeff(P * size_t(K) * 3);
  std::vector<double> acc(size_t(K) * 3);
  for (size_t p = 0; p < P; ++p) {
    std::fill(acc.begin(), acc.end(), 0.0);
    const float* L = f.radiance.data() + p * texels * 3;
    for (size_t t = 0; t < texels; ++t) {
      const double* w = weights->data() + t * size_t(K);
      for (int k = 0; k < K; ++k)
        for (int c = 0; c < 3; ++c) acc[size_t(3 * k + c)] += double(L[3 * t + size_t(c)]) * w[k];
    }
    for (size_t i = 0; i < acc.size(); ++i) coeff[p * size_t(K) * 3 + i] = float(acc[i]);
  }
  return coeff;
}

// out.radiance at texel centres and out.irradiance (cosine convolution) from the coefficients.
void evaluateShField(const std::vector<float>& coeff, int lmax, const char* codec, ProbeField& out) {
  const int n = out.resolution, m = out.irradianceResolution, K = shCoefficientCount(lmax);
  if (m < 1 || m > 256) fail("{} decode: irradiance resolution {} outside [1, 256]", codec, m);
  const size_t P = size_t(out.probeCount());
  const auto rb = texelCentreBasis(lmax, n, false);
  const auto ib = texelCentreBasis(lmax, m, true);
  const size_t tn = size_t(n) * size_t(n), tm = size_t(m) * size_t(m);
  out.irradiance.assign(P * tm * 3, 0.0f);
  for (size_t p = 0; p < P; ++p) {
    const float* c = coeff.data() + p * size_t(K) * 3;
    evaluateSh(c, K, *rb, tn, out.radiance.data() + p * tn * 3);
    evaluateSh(c, K, *ib, tm, out.irradiance.data() + p * tm * 3);
  }
}

class ShCodec final : public ProbeCodec {
 public:
  explicit ShCodec(int lmax) : lmax_(lmax) {
    if (lmax < 1 || lmax > kShMaxBand) fail("SH codec: lmax {} outside [1, {}]", lmax, kShMaxBand);
  }
  std::string name() const override { return fmt::format("sh_l{}", lmax_); }
  std::string setting() const override { return fmt::format("{} coefficients", shCoefficientCount(lmax_)); }
  bool decodesIrradiance() const override { return true; }
  std::vector<std::byte> encode(const ProbeField& f) const override {
    checkField(name().c_str(), f);
    ByteWriter w;
    writeHeader(w, {{'L', 'S', 'H', 'C'}, 1, f.resolution, uint32_t(f.probeCount())});
    w.u8(uint8_t(lmax_));
    w.halves(projectSh(f, lmax_));
    return std::move(w.bytes);
  }
  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "sh"};
    readHeader(r, "LSHC", 1, out);
    const int lmax = r.u8("lmax");
    if (lmax != lmax_) fail("sh decode: bytes hold bands 0..{}, this codec is sh_l{}", lmax, lmax_);
    prepareOut(out);
    std::vector<float> coeff(size_t(out.probeCount()) * size_t(shCoefficientCount(lmax_)) * 3);
    r.halves(coeff, "coefficients");
    r.expectEnd();
    evaluateShField(coeff, lmax_, "sh", out);
  }

 private:
  int lmax_;
};

// SH L1 in Unity APV's split (core/sh_l1_q8.h): L0 per channel FP16 at a per-cell scale, each L1 as an int8
// snorm code of L1 / (sqrt(3) L0); 15 B per probe.
class ShL1Q8Codec final : public ProbeCodec {
 public:
  std::string name() const override { return "sh_l1_q8"; }
  std::string setting() const override { return "L0 FP16 + L1/L0 int8"; }
  bool decodesIrradiance() const override { return true; }
  std::vector<std::byte> encode(const ProbeField& f) const override {
    checkField(name().c_str(), f);
    const std::vector<float> coeff = projectSh(f, 1);
    const size_t P = size_t(f.probeCount());
    std::vector<float> l0(P * 3);
    for (size_t i = 0; i < l0.size(); ++i) l0[i] = std::max(0.0f, coeff[(i / 3) * 12 + i % 3]);
    ByteWriter w;
    writeHeader(w, {{'L', 'S', 'H', 'Q'}, 1, f.resolution, uint32_t(P)});
    w.halves(l0);  // per-cell power-of-two scale + FP16 (core/byte_stream.h)
    for (size_t p = 0; p < P; ++p)
      for (int k = 1; k < 4; ++k)
        for (int ch = 0; ch < 3; ++ch) {
          w.i8(shL1Q8Code(l0[p * 3 + size_t(ch)], coeff[p * 12 + size_t(3 * k + ch)]));
        }
    return std::move(w.bytes);
  }
  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "sh_l1_q8"};
    readHeader(r, "LSHQ", 1, out);
    prepareOut(out);
    const size_t P = size_t(out.probeCount());
    std::vector<float> l0(P * 3), coeff(P * 12);
    r.halves(l0, "L0");
    for (size_t p = 0; p < P; ++p) {
      float* c = coeff.data() + p * 12;
      for (int ch = 0; ch < 3; ++ch) c[ch] = l0[p * 3 + size_t(ch)];
      for (int k = 1; k < 4; ++k)
        for (int ch = 0; ch < 3; ++ch) {
          const int8_t q = r.i8("L1");
          if (q < -127) fail("sh_l1_q8 decode: L1 code -128 of probe {} is not a valid snorm code", p);
          c[3 * k + ch] = shL1Q8Value(c[ch], q);
        }
    }
    r.expectEnd();
    evaluateShField(coeff, 1, "sh_l1_q8", out);
  }
};

}  // namespace

std::unique_ptr<ProbeCodec> makeRawFp16Codec() {
  return std::make_unique<RawFp16Codec>();
}
std::unique_ptr<ProbeCodec> makeZstdFp16Codec(int level) {
  return std::make_unique<ZstdFp16Codec>(level);
}
std::unique_ptr<ProbeCodec> makeShCodec(int lmax) {
  return std::make_unique<ShCodec>(lmax);
}
std::unique_ptr<ProbeCodec> makeShL1Q8Codec() {
  return std::make_unique<ShL1Q8Codec>();
}

void deriveIrradiance(ProbeField& field) {
  const int n = field.resolution, m = field.irradianceResolution;
  if (n < 1 || n > 256 || m < 1 || m > 256)
    fail("deriveIrradiance: resolutions {} / {} outside [1, 256]", n, m);
  const size_t P = size_t(field.probeCount()), tn = size_t(n) * size_t(n), tm = size_t(m) * size_t(m);
  if (field.radiance.size() != P * tn * 3)
    fail("deriveIrradiance: radiance holds {} floats, {} probes of {}x{} need {}", field.radiance.size(), P,
         n, n, P * tn * 3);
  static std::mutex mutex;
  static std::map<int, std::vector<double>> solidAngles;
  const std::vector<double>* omega;
  {
    const std::lock_guard lock(mutex);
    auto it = solidAngles.find(n);
    if (it == solidAngles.end()) it = solidAngles.emplace(n, octTexelSolidAngles(n)).first;
    omega = &it->second;  // std::map nodes are stable
  }
  field.irradiance.assign(P * tm * 3, 0.0f);
  for (size_t p = 0; p < P; ++p) {
    const std::span<const float> L(field.radiance.data() + p * tn * 3, tn * 3);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const glm::vec3 e = bruteForceIrradiance(L, n, octTexelDirection(i, j, m), *omega);
        float* o = field.irradiance.data() + (p * tm + size_t(j) * size_t(m) + size_t(i)) * 3;
        o[0] = e.x;
        o[1] = e.y;
        o[2] = e.z;
      }
  }
}

}  // namespace lfgi
