#include "core/vdb_container.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <sstream>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <openvdb/io/Stream.h>

namespace lfgi::vdbfile {

static_assert(std::endian::native == std::endian::little,
              "lfgi files store little-endian blobs as memory images");

namespace {

// OpenVDB archive header: int64 magic, u32 file version, u32 x2 library version, u8 grid-offsets flag,
// then the archive UUID as 36 ASCII characters (io/Archive.cc, writeHeader).
constexpr size_t kUuidOffset = 21, kUuidChars = 36;

std::string channelsText(const std::vector<int>& c) {
  return fmt::format("{}", fmt::join(c, ","));
}

std::vector<int> parseChannels(const std::string& s, const std::string& what) {
  std::vector<int> out;
  size_t pos = 0;
  while (pos <= s.size()) {
    size_t end = s.find(',', pos);
    if (end == std::string::npos) end = s.size();
    std::string item = s.substr(pos, end - pos);
    if (item.empty() || item.size() > 4 ||
        !std::all_of(item.begin(), item.end(), [](char c) { return c >= '0' && c <= '9'; }))
      fail("{}: '{}' is not a comma-separated list of channel counts", what, s);
    out.push_back(std::stoi(item));
    if (out.size() > 16) fail("{}: more than 16 entries", what);
    pos = end + 1;
  }
  return out;
}

const char* latentSourceName(LatentSource s) {
  return s == LatentSource::Stored ? "stored" : "position_fourier";
}

}  // namespace

void initOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

void appendCodes(std::vector<uint8_t>& out, std::span<const int8_t> codes, int bits) {
  if (bits == 8) {
    appendPod<int8_t>(out, codes);
    return;
  }
  for (size_t i = 0; i < codes.size(); i += 2) {
    uint8_t lo = uint8_t(codes[i]) & 0xf;
    uint8_t hi = i + 1 < codes.size() ? uint8_t(codes[i + 1]) & 0xf : 0;
    out.push_back(uint8_t(lo | (hi << 4)));
  }
}

std::vector<int8_t> readCodes(BlobReader& r, size_t count, int bits) {
  if (bits == 8) return r.read<int8_t>(count);
  std::vector<uint8_t> packed = r.read<uint8_t>((count + 1) / 2);
  std::vector<int8_t> codes(count);
  for (size_t i = 0; i < count; ++i) {
    int v = (packed[i / 2] >> ((i % 2) * 4)) & 0xf;
    codes[i] = int8_t(v >= 8 ? v - 16 : v);
  }
  return codes;
}

std::vector<uint8_t> encodeWeights(const QuantizedWeights& w) {
  std::vector<uint8_t> out;
  for (const QuantizedTensor& t : w.tensors) {
    switch (t.encoding) {
      case TensorEncoding::Float32:
        appendPod<float>(out, t.f32);
        break;
      case TensorEncoding::Float16:
        appendPod<uint16_t>(out, t.f16);
        break;
      case TensorEncoding::Int8PerChannel:
        appendPod<float>(out, t.scales);
        appendPod<int8_t>(out, t.codes);
        break;
    }
  }
  return out;
}

// The shapes come from a quantized model of the same arch (quantizeWeights of zeros gives them without
// duplicating the layout rules).
QuantizedWeights decodeWeights(const std::vector<uint8_t>& blob, const GeneratorArch& arch, WeightPrecision p,
                               const std::string& what) {
  GeneratorWeights zeros;
  zeros.arch = arch;
  size_t c0 = size_t(arch.convChannels.front());
  zeros.linearWeight.assign(16 * c0 * size_t(arch.inputDim()), 0.0f);
  zeros.linearBias.assign(16 * c0, 0.0f);
  for (int i = 0; i < arch.layers(); ++i) {
    size_t ci = size_t(arch.convChannels[size_t(i)]), co = size_t(arch.convChannels[size_t(i) + 1]);
    zeros.convWeight.emplace_back(ci * co * 16, 0.0f);
    zeros.convBias.emplace_back(co, 0.0f);
  }
  QuantizedWeights q = quantizeWeights(zeros, p);
  BlobReader r(blob, what);
  for (QuantizedTensor& t : q.tensors) {
    size_t n = size_t(t.elements());
    switch (t.encoding) {
      case TensorEncoding::Float32:
        t.f32 = r.read<float>(n);
        break;
      case TensorEncoding::Float16:
        t.f16 = r.read<uint16_t>(n);
        break;
      case TensorEncoding::Int8PerChannel:
        t.scales = r.read<float>(size_t(t.channels));
        t.codes = r.read<int8_t>(n);
        break;
    }
  }
  r.finish();
  q.validate();
  return q;
}

std::string hex64(uint64_t v) {
  return fmt::format("{:016x}", v);
}

uint64_t parseHex64(const std::string& s, const std::string& what) {
  if (s.size() != 16 ||
      !std::all_of(s.begin(), s.end(), [](char c) { return std::isxdigit(uint8_t(c)) != 0; }))
    fail("{}: '{}' is not 16 hex digits", what, s);
  return std::stoull(s, nullptr, 16);
}

float MetaReader::getFinite(const char* field) const {
  float v = get<float>(field);
  if (!std::isfinite(v)) fail("{}: field '{}' is {} (must be finite)", name_, field, v);
  return v;
}
double MetaReader::getFiniteDouble(const char* field) const {
  double v = get<double>(field);
  if (!std::isfinite(v)) fail("{}: field '{}' is {} (must be finite)", name_, field, v);
  return v;
}
int64_t MetaReader::getInt(const char* field, int64_t lo, int64_t hi) const {
  int64_t v;
  openvdb::Metadata::ConstPtr p = m_[field];
  if (p && p->typeName() == openvdb::Int32Metadata::staticTypeName())
    v = get<int32_t>(field);
  else
    v = get<int64_t>(field);
  if (v < lo || v > hi) fail("{}: field '{}' = {} outside [{}, {}]", name_, field, v, lo, hi);
  return v;
}
std::vector<uint8_t> MetaReader::blob(const char* field) const {
  openvdb::Metadata::ConstPtr p = m_[field];
  if (!p) fail("{}: field '{}' is missing", name_, field);
  auto u = std::dynamic_pointer_cast<const openvdb::UnknownMetadata>(p);
  if (!u || p->typeName() != kBlobType)
    fail("{}: field '{}' has type {}, expected {}", name_, field, p->typeName(), kBlobType);
  return u->value();
}

void putBlob(openvdb::MetaMap& m, const char* field, std::vector<uint8_t> bytes) {
  openvdb::UnknownMetadata u(kBlobType);
  u.setValue(bytes);
  m.insertMeta(field, u);
}

void putArch(openvdb::MetaMap& m, const GeneratorArch& a, WeightPrecision precision) {
  m.insertMeta("generator_latent_dim", openvdb::Int32Metadata(a.latentDim));
  m.insertMeta("generator_cond_dim", openvdb::Int32Metadata(a.condDim));
  m.insertMeta("generator_conv_channels", openvdb::StringMetadata(channelsText(a.convChannels)));
  m.insertMeta("generator_latent_source", openvdb::StringMetadata(latentSourceName(a.latentSource)));
  m.insertMeta("generator_fourier_octaves", openvdb::Int32Metadata(a.fourierOctaves));
  m.insertMeta("generator_weight_precision", openvdb::StringMetadata(weightPrecisionName(precision)));
}

std::pair<GeneratorArch, WeightPrecision> readArch(const MetaReader& r) {
  const std::string& name = r.name();
  GeneratorArch a;
  a.latentDim = int(r.getInt("generator_latent_dim", 1, 256));
  a.condDim = int(r.getInt("generator_cond_dim", 0, kConditioningDim));
  a.convChannels =
      parseChannels(r.get<std::string>("generator_conv_channels"), name + ": generator_conv_channels");
  std::string src = r.get<std::string>("generator_latent_source");
  if (src == "stored")
    a.latentSource = LatentSource::Stored;
  else if (src == "position_fourier")
    a.latentSource = LatentSource::PositionFourier;
  else
    fail("{}: generator_latent_source '{}' is unknown (stored, position_fourier)", name, src);
  a.fourierOctaves = int(r.getInt("generator_fourier_octaves", 0, 16));
  try {
    a.validate();
  } catch (const Error& e) {
    fail("{}: generator architecture: {}", name, e.what());
  }
  std::string prec = r.get<std::string>("generator_weight_precision");
  WeightPrecision p;
  if (prec == "fp16")
    p = WeightPrecision::Float16;
  else if (prec == "int8")
    p = WeightPrecision::Int8;
  else
    fail("{}: generator_weight_precision '{}' is unknown (fp16, int8)", name, prec);
  return {a, p};
}

void applyOverrides(openvdb::MetaMap& m, std::span<const detail::CellFileOverride> overrides) {
  for (const detail::CellFileOverride& o : overrides) {
    openvdb::Metadata::Ptr p = m[o.field];
    if (p) m.removeMeta(o.field);
    if (o.erase) continue;
    if (p && p->typeName() == openvdb::Int32Metadata::staticTypeName())
      m.insertMeta(o.field, openvdb::Int32Metadata(int32_t(o.intValue)));
    else if (p && p->typeName() == openvdb::StringMetadata::staticTypeName())
      m.insertMeta(o.field, openvdb::StringMetadata(o.text));
    else if (p && p->typeName() == openvdb::Vec3IMetadata::staticTypeName()) {
      openvdb::Vec3i v(0, 0, 0);
      if (std::sscanf(o.text.c_str(), "%d,%d,%d", &v[0], &v[1], &v[2]) != 3)
        fail("override {}: expected X,Y,Z", o.field);
      m.insertMeta(o.field, openvdb::Vec3IMetadata(v));
    } else if (p && p->typeName() == kBlobType)
      putBlob(m, o.field.c_str(), std::vector<uint8_t>(o.text.begin(), o.text.end()));
    else if (p && !o.text.empty() &&
             p->typeName() == openvdb::FloatMetadata::staticTypeName())  // "nan", "-1.5"
      m.insertMeta(o.field, openvdb::FloatMetadata(std::strtof(o.text.c_str(), nullptr)));
    else if (p && !o.text.empty() && p->typeName() == openvdb::DoubleMetadata::staticTypeName())
      m.insertMeta(o.field, openvdb::DoubleMetadata(std::strtod(o.text.c_str(), nullptr)));
    else
      m.insertMeta(o.field, openvdb::Int64Metadata(o.intValue));
  }
}

std::vector<std::byte> seal(const openvdb::GridCPtrVec& grids, const openvdb::MetaMap& m,
                            const char (&trailerMagic)[9], const std::string& what) {
  std::ostringstream os(std::ios::binary);
  try {
    openvdb::io::Stream stream(os);
    stream.setCompression(openvdb::io::COMPRESS_ACTIVE_MASK);
    stream.write(grids, m);
  } catch (const openvdb::Exception& e) {
    fail("{}: OpenVDB: {}", what, e.what());
  }
  std::string s = os.str();

  // Deterministic archive UUID (OpenVDB draws a random one per write): derived from everything after it.
  if (s.size() < kUuidOffset + kUuidChars || s[kUuidOffset + 8] != '-' || s[kUuidOffset + 13] != '-')
    fail("{}: OpenVDB header layout is not the expected one (archive UUID not at byte {})", what,
         kUuidOffset);
  XXH128_hash_t h = XXH3_128bits(s.data() + kUuidOffset + kUuidChars, s.size() - kUuidOffset - kUuidChars);
  std::string hex = fmt::format("{:016x}{:016x}", h.high64, h.low64);
  std::string uuid = hex.substr(0, 8) + "-" + hex.substr(8, 4) + "-" + hex.substr(12, 4) + "-" +
                     hex.substr(16, 4) + "-" + hex.substr(20, 12);
  s.replace(kUuidOffset, kUuidChars, uuid);

  std::vector<std::byte> out(s.size() + kTrailerBytes);
  std::memcpy(out.data(), s.data(), s.size());
  uint64_t length = s.size(), sum = XXH3_64bits(s.data(), s.size());
  std::memcpy(out.data() + s.size(), trailerMagic, 8);
  std::memcpy(out.data() + s.size() + 8, &length, 8);
  std::memcpy(out.data() + s.size() + 16, &sum, 8);
  return out;
}

OpenedStream open(std::span<const std::byte> bytes, const std::string& name, const char (&trailerMagic)[9],
                  size_t maxBytes, const char* kind) {
  // Envelope: size, trailer, checksum. Nothing below trusts a byte that failed these.
  if (bytes.size() > maxBytes)
    fail("{}: {} bytes, more than the {} limit {}", name, bytes.size(), kind, maxBytes);
  if (bytes.size() < kTrailerBytes + 8)
    fail("{}: truncated or not a {} ({} bytes, too short for the OpenVDB header and trailer)", name, kind,
         bytes.size());
  const std::byte* tail = bytes.data() + bytes.size() - kTrailerBytes;
  uint64_t length = 0, sum = 0;
  std::memcpy(&length, tail + 8, 8);
  std::memcpy(&sum, tail + 16, 8);
  if (std::memcmp(tail, trailerMagic, 8) != 0) {
    int64_t vdbMagic = 0;
    std::memcpy(&vdbMagic, bytes.data(), 8);
    if (vdbMagic != openvdb::OPENVDB_MAGIC) fail("{}: not a {} (no OpenVDB magic at the start)", name, kind);
    fail("{}: truncated or not a {} (the '{}' trailer is missing at the end)", name, kind,
         std::string(trailerMagic, 8));
  }
  if (length != bytes.size() - kTrailerBytes)
    fail("{}: truncated or padded: the trailer records {} bytes of OpenVDB data, the file holds {}", name,
         length, bytes.size() - kTrailerBytes);
  uint64_t actual = XXH3_64bits(bytes.data(), size_t(length));
  if (actual != sum)
    fail("{}: corrupt: checksum of the OpenVDB data is {:016x}, the trailer records {:016x}", name, actual,
         sum);

  // OpenVDB parse (the bytes are the ones our writer produced).
  initOpenVdb();
  OpenedStream o;
  try {
    std::istringstream is(std::string(reinterpret_cast<const char*>(bytes.data()), size_t(length)),
                          std::ios::binary);
    openvdb::io::Stream stream(is, false);
    o.meta = stream.getMetadata();
    o.grids = stream.getGrids();
  } catch (const std::exception& e) {
    fail("{}: OpenVDB could not read the file: {}", name, e.what());
  }
  if (!o.meta || !o.grids) fail("{}: OpenVDB returned no metadata or grids", name);
  return o;
}

}  // namespace lfgi::vdbfile
