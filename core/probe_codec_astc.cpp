// ASTC HDR of the octahedral radiance atlas (core/probe_codecs.h) with ARM's reference encoder
// (libastcenc 4.x). Each probe's map is its own column of blocks (padded by edge replication to a whole
// number of blocks), so no block mixes two probes: the atlas is one tile wide and P tiles tall.
#include <algorithm>
#include <cmath>
#include <mutex>

#include <astcenc.h>

#include "core/error.h"
#include "core/probe_codecs.h"
#include "core/probe_codecs_internal.h"

namespace lfgi {

using namespace codec_detail;

namespace {

constexpr size_t kBlockBytes = 16;  // every ASTC block is 128 bits, whatever its footprint

class AstcHdrCodec final : public ProbeCodec {
 public:
  AstcHdrCodec(int block, float quality) : block_(block), quality_(quality) {
    if (block != 4 && block != 5 && block != 6 && block != 8 && block != 10 && block != 12)
      fail("astc codec: block size {} is not one of 4, 5, 6, 8, 10, 12", block);
    if (!(quality >= 0.0f && quality <= 100.0f)) fail("astc codec: quality {} outside [0, 100]", quality);
    astcenc_config config{};
    astcenc_error e = astcenc_config_init(ASTCENC_PRF_HDR_RGB_LDR_A, unsigned(block), unsigned(block), 1,
                                          quality, 0, &config);
    if (e != ASTCENC_SUCCESS) fail("astc codec: astcenc_config_init: {}", astcenc_get_error_string(e));
    e = astcenc_context_alloc(&config, 1, &context_);
    if (e != ASTCENC_SUCCESS) fail("astc codec: astcenc_context_alloc: {}", astcenc_get_error_string(e));
  }
  ~AstcHdrCodec() override { astcenc_context_free(context_); }
  AstcHdrCodec(const AstcHdrCodec&) = delete;
  AstcHdrCodec& operator=(const AstcHdrCodec&) = delete;

  std::string name() const override { return "astc_hdr"; }
  std::string setting() const override { return fmt::format("{}x{} q{}", block_, block_, quality_); }

  std::vector<std::byte> encode(const ProbeField& f) const override {
    checkField("astc_hdr", f);
    const int n = f.resolution, T = tile(n);
    const size_t P = size_t(f.probeCount());
    const float scale = exposureScale(f.radiance);
    // RGBA float atlas, T x (T * P); alpha 1 (LDR alpha, ignored on decode).
    std::vector<float> atlas(size_t(T) * size_t(T) * P * 4);
    for (size_t p = 0; p < P; ++p)
      for (int y = 0; y < T; ++y)
        for (int x = 0; x < T; ++x) {
          const int sx = std::min(x, n - 1), sy = std::min(y, n - 1);
          const float* s = f.radiance.data() + ((p * size_t(n) + size_t(sy)) * size_t(n) + size_t(sx)) * 3;
          float* d = atlas.data() + ((p * size_t(T) + size_t(y)) * size_t(T) + size_t(x)) * 4;
          for (int c = 0; c < 3; ++c) d[c] = std::min(s[c] / scale, 65504.0f);
          d[3] = 1.0f;
        }
    void* slice = atlas.data();
    astcenc_image image{unsigned(T), unsigned(T * P), 1, ASTCENC_TYPE_F32, &slice};
    const astcenc_swizzle swz{ASTCENC_SWZ_R, ASTCENC_SWZ_G, ASTCENC_SWZ_B, ASTCENC_SWZ_A};
    ByteWriter w;
    writeHeader(w, {{'L', 'A', 'S', 'T'}, 1, n, uint32_t(P)});
    w.u8(uint8_t(block_));
    w.f32(scale);
    const size_t at = w.bytes.size(), payload = payloadBytes(n, P);
    w.bytes.resize(at + payload);
    const std::lock_guard lock(mutex_);
    const astcenc_error e = astcenc_compress_image(
        context_, &image, &swz, reinterpret_cast<uint8_t*>(w.bytes.data() + at), payload, 0);
    astcenc_compress_reset(context_);
    if (e != ASTCENC_SUCCESS)
      fail("astc_hdr encode: astcenc_compress_image: {}", astcenc_get_error_string(e));
    return std::move(w.bytes);
  }

  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "astc_hdr"};
    readHeader(r, "LAST", 1, out);
    const int block = r.u8("block size");
    if (block != block_)
      fail("astc_hdr decode: bytes use {}x{} blocks, this codec {}x{}", block, block, block_, block_);
    const float scale = r.f32("scale");
    if (!std::isfinite(scale) || scale <= 0.0f)
      fail("astc_hdr decode: scale {} is not a positive number", scale);
    prepareOut(out);
    const int n = out.resolution, T = tile(n);
    const size_t P = size_t(out.probeCount()), payload = payloadBytes(n, P);
    const std::byte* src = r.take(payload, "ASTC blocks");
    r.expectEnd();
    std::vector<float> atlas(size_t(T) * size_t(T) * P * 4);
    void* slice = atlas.data();
    astcenc_image image{unsigned(T), unsigned(T * P), 1, ASTCENC_TYPE_F32, &slice};
    const astcenc_swizzle swz{ASTCENC_SWZ_R, ASTCENC_SWZ_G, ASTCENC_SWZ_B, ASTCENC_SWZ_A};
    {
      const std::lock_guard lock(mutex_);
      const astcenc_error e =
          astcenc_decompress_image(context_, reinterpret_cast<const uint8_t*>(src), payload, &image, &swz, 0);
      astcenc_decompress_reset(context_);
      if (e != ASTCENC_SUCCESS)
        fail("astc_hdr decode: astcenc_decompress_image: {}", astcenc_get_error_string(e));
    }
    for (size_t p = 0; p < P; ++p)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
          const float* s = atlas.data() + ((p * size_t(T) + size_t(y)) * size_t(T) + size_t(x)) * 4;
          float* d = out.radiance.data() + ((p * size_t(n) + size_t(y)) * size_t(n) + size_t(x)) * 3;
          for (int c = 0; c < 3; ++c) {
            // Every ASTC bit pattern decodes to something; an error block decodes to NaN (magenta in LDR).
            if (!std::isfinite(s[c]))
              fail("astc_hdr decode: probe {} texel ({}, {}) decoded to {}", p, x, y, s[c]);
            d[c] = s[c] * scale;
          }
        }
  }

 private:
  int tile(int n) const { return (n + block_ - 1) / block_ * block_; }
  size_t payloadBytes(int n, size_t P) const {
    const size_t b = size_t(tile(n) / block_);
    return b * b * P * kBlockBytes;
  }

  int block_;
  float quality_;
  astcenc_context* context_ = nullptr;
  mutable std::mutex mutex_;
};

}  // namespace

std::unique_ptr<ProbeCodec> makeAstcHdrCodec(int block, float quality) {
  return std::make_unique<AstcHdrCodec>(block, quality);
}

}  // namespace lfgi
