// The OpenVDB container behind lfgi's files (core/cell_file.h cell files, core/shared_model.h shared
// models): an OpenVDB stream whose file metadata holds typed fields and raw blobs, sealed by a 24-byte
// trailer (8-character magic, u64 stream length, u64 XXH3-64 of the stream) that the reader checks before
// OpenVDB parses a byte. Private to core: only cell_file.cpp and shared_model.cpp include it (OpenVDB's
// headers pull in Boost and TBB).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <openvdb/openvdb.h>

#include "core/cell_file.h"
#include "core/error.h"
#include "core/quantize.h"

namespace lfgi::vdbfile {

inline constexpr char kBlobType[] = "lfgi_bytes";
inline constexpr size_t kTrailerBytes = 24;

void initOpenVdb();

template <typename T>
void appendPod(std::vector<uint8_t>& out, std::span<const T> values) {
  const auto* p = reinterpret_cast<const uint8_t*>(values.data());
  out.insert(out.end(), p, p + values.size_bytes());
}

// Reads typed arrays from a blob, each read checked against what is left.
class BlobReader {
 public:
  BlobReader(const std::vector<uint8_t>& bytes, std::string what) : bytes_(bytes), what_(std::move(what)) {}
  template <typename T>
  std::vector<T> read(size_t count) {
    if (count > (bytes_.size() - pos_) / sizeof(T))
      fail("{} ends after {} bytes, {} more needed", what_, bytes_.size(),
           count * sizeof(T) - (bytes_.size() - pos_));
    std::vector<T> v(count);
    if (count) std::memcpy(v.data(), bytes_.data() + pos_, count * sizeof(T));
    pos_ += count * sizeof(T);
    return v;
  }
  void finish() const {
    if (pos_ != bytes_.size()) fail("{} holds {} bytes, {} expected", what_, bytes_.size(), pos_);
  }

 private:
  const std::vector<uint8_t>& bytes_;
  std::string what_;
  size_t pos_ = 0;
};

// Symmetric codes packed at `bits` (8: one per byte; 4: two's complement, two per byte, low nibble first).
void appendCodes(std::vector<uint8_t>& out, std::span<const int8_t> codes, int bits);
std::vector<int8_t> readCodes(BlobReader& r, size_t count, int bits);

// Quantized weights as one blob (per tensor: f32 | f16 | scales then codes); decodeWeights takes the
// shapes from arch + precision and validates the result.
std::vector<uint8_t> encodeWeights(const QuantizedWeights& w);
QuantizedWeights decodeWeights(const std::vector<uint8_t>& blob, const GeneratorArch& arch, WeightPrecision p,
                               const std::string& what);

std::string hex64(uint64_t v);
uint64_t parseHex64(const std::string& s, const std::string& what);

// Typed access to file metadata; every failure is "<name>: field '<f>' ...".
class MetaReader {
 public:
  MetaReader(const openvdb::MetaMap& m, const std::string& name) : m_(m), name_(name) {}

  template <typename T>
  T get(const char* field) const {
    openvdb::Metadata::ConstPtr p = m_[field];
    if (!p) fail("{}: field '{}' is missing", name_, field);
    auto typed = std::dynamic_pointer_cast<const openvdb::TypedMetadata<T>>(p);
    if (!typed)
      fail("{}: field '{}' has type {}, expected {}", name_, field, p->typeName(),
           openvdb::TypedMetadata<T>::staticTypeName());
    return typed->value();
  }
  float getFinite(const char* field) const;
  double getFiniteDouble(const char* field) const;
  int64_t getInt(const char* field, int64_t lo, int64_t hi) const;
  std::vector<uint8_t> blob(const char* field) const;
  bool has(const char* field) const { return bool(m_[field]); }
  const std::string& name() const { return name_; }

 private:
  const openvdb::MetaMap& m_;
  const std::string& name_;
};

void putBlob(openvdb::MetaMap& m, const char* field, std::vector<uint8_t> bytes);

// The generator architecture + weight precision fields (generator_latent_dim, generator_cond_dim,
// generator_conv_channels, generator_latent_source, generator_fourier_octaves, generator_weight_precision).
void putArch(openvdb::MetaMap& m, const GeneratorArch& arch, WeightPrecision precision);
std::pair<GeneratorArch, WeightPrecision> readArch(const MetaReader& r);

// The test seam of core/cell_file.h (detail::CellFileOverride) applied to any metadata map.
void applyOverrides(openvdb::MetaMap& m, std::span<const detail::CellFileOverride> overrides);

// Writes grids + metadata as an OpenVDB stream with a deterministic archive UUID (derived from the
// content) and appends the trailer. Errors start with `what`.
std::vector<std::byte> seal(const openvdb::GridCPtrVec& grids, const openvdb::MetaMap& m,
                            const char (&trailerMagic)[9], const std::string& what);

// Checks size <= maxBytes, the trailer and the checksum, then parses the stream. kind names the file type
// in errors ("cell file"); every error starts with `name`.
struct OpenedStream {
  openvdb::MetaMap::Ptr meta;
  openvdb::GridPtrVecPtr grids;
};
OpenedStream open(std::span<const std::byte> bytes, const std::string& name, const char (&trailerMagic)[9],
                  size_t maxBytes, const char* kind);

}  // namespace lfgi::vdbfile
