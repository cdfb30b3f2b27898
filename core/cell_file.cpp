#include "core/cell_file.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <sstream>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi {

static_assert(std::endian::native == std::endian::little, "cell files store little-endian blobs as memory images");

namespace {

constexpr char kMagic[] = "lfgi-cell";
constexpr char kTrailerMagic[8] = {'L', 'F', 'G', 'I', 'C', 'E', 'L', 'L'};
constexpr size_t kTrailerBytes = 24;
constexpr char kBlobType[] = "lfgi_bytes";
constexpr char kGridName[] = "probes";
// OpenVDB archive header: int64 magic, u32 file version, u32 x2 library version, u8 grid-offsets flag,
// then the archive UUID as 36 ASCII characters (io/Archive.cc, writeHeader).
constexpr size_t kUuidOffset = 21, kUuidChars = 36;
constexpr size_t kShHalves = 12;  // SH L1: 4 coefficients x rgb

void initOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

// ---- little-endian blob helpers -------------------------------------------------------------------

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
      fail("{} ends after {} bytes, {} more needed", what_, bytes_.size(), count * sizeof(T) - (bytes_.size() - pos_));
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

std::vector<uint8_t> encodeWeights(const QuantizedWeights& w) {
  std::vector<uint8_t> out;
  for (const QuantizedTensor& t : w.tensors) {
    switch (t.encoding) {
      case TensorEncoding::Float32: appendPod<float>(out, t.f32); break;
      case TensorEncoding::Float16: appendPod<uint16_t>(out, t.f16); break;
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
      case TensorEncoding::Float32: t.f32 = r.read<float>(n); break;
      case TensorEncoding::Float16: t.f16 = r.read<uint16_t>(n); break;
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

std::vector<uint8_t> encodeLatents(const QuantizedLatents& l) {
  std::vector<uint8_t> out;
  appendPod<float>(out, l.scales);
  if (l.bits == 8) {
    appendPod<int8_t>(out, l.codes);
  } else {  // 4-bit two's complement, two per byte, low nibble first
    for (size_t i = 0; i < l.codes.size(); i += 2) {
      uint8_t lo = uint8_t(l.codes[i]) & 0xf;
      uint8_t hi = i + 1 < l.codes.size() ? uint8_t(l.codes[i + 1]) & 0xf : 0;
      out.push_back(uint8_t(lo | (hi << 4)));
    }
  }
  return out;
}

QuantizedLatents decodeLatents(const std::vector<uint8_t>& blob, int dim, int bits, int64_t count,
                               const std::string& what) {
  QuantizedLatents l;
  l.dim = dim;
  l.bits = bits;
  l.count = count;
  BlobReader r(blob, what);
  l.scales = r.read<float>(size_t(dim));
  size_t n = size_t(count) * size_t(dim);
  if (bits == 8) {
    l.codes = r.read<int8_t>(n);
  } else {
    std::vector<uint8_t> packed = r.read<uint8_t>((n + 1) / 2);
    l.codes.resize(n);
    for (size_t i = 0; i < n; ++i) {
      int v = (packed[i / 2] >> ((i % 2) * 4)) & 0xf;
      l.codes[i] = int8_t(v >= 8 ? v - 16 : v);
    }
  }
  r.finish();
  l.validate(what);
  return l;
}

std::string hex64(uint64_t v) { return fmt::format("{:016x}", v); }

uint64_t parseHex64(const std::string& s, const std::string& what) {
  if (s.size() != 16 || !std::all_of(s.begin(), s.end(), [](char c) { return std::isxdigit(uint8_t(c)) != 0; }))
    fail("{}: '{}' is not 16 hex digits", what, s);
  return std::stoull(s, nullptr, 16);
}

std::string channelsText(const std::vector<int>& c) { return fmt::format("{}", fmt::join(c, ",")); }

std::vector<int> parseChannels(const std::string& s, const std::string& what) {
  std::vector<int> out;
  size_t pos = 0;
  while (pos <= s.size()) {
    size_t end = s.find(',', pos);
    if (end == std::string::npos) end = s.size();
    std::string item = s.substr(pos, end - pos);
    if (item.empty() || item.size() > 4 || !std::all_of(item.begin(), item.end(), [](char c) { return c >= '0' && c <= '9'; }))
      fail("{}: '{}' is not a comma-separated list of channel counts", what, s);
    out.push_back(std::stoi(item));
    if (out.size() > 16) fail("{}: more than 16 entries", what);
    pos = end + 1;
  }
  return out;
}

const char* latentSourceName(LatentSource s) { return s == LatentSource::Stored ? "stored" : "position_fourier"; }

// ---- typed access to file metadata --------------------------------------------------------------------

class MetaReader {
 public:
  MetaReader(const openvdb::MetaMap& m, const std::string& name) : m_(m), name_(name) {}

  template <typename T>
  T get(const char* field) const {
    openvdb::Metadata::ConstPtr p = m_[field];
    if (!p) fail("{}: field '{}' is missing", name_, field);
    auto typed = std::dynamic_pointer_cast<const openvdb::TypedMetadata<T>>(p);
    if (!typed) fail("{}: field '{}' has type {}, expected {}", name_, field, p->typeName(),
                     openvdb::TypedMetadata<T>::staticTypeName());
    return typed->value();
  }
  float getFinite(const char* field) const {
    float v = get<float>(field);
    if (!std::isfinite(v)) fail("{}: field '{}' is {} (must be finite)", name_, field, v);
    return v;
  }
  double getFiniteDouble(const char* field) const {
    double v = get<double>(field);
    if (!std::isfinite(v)) fail("{}: field '{}' is {} (must be finite)", name_, field, v);
    return v;
  }
  int64_t getInt(const char* field, int64_t lo, int64_t hi) const {
    int64_t v;
    openvdb::Metadata::ConstPtr p = m_[field];
    if (p && p->typeName() == openvdb::Int32Metadata::staticTypeName()) v = get<int32_t>(field);
    else v = get<int64_t>(field);
    if (v < lo || v > hi) fail("{}: field '{}' = {} outside [{}, {}]", name_, field, v, lo, hi);
    return v;
  }
  std::vector<uint8_t> blob(const char* field) const {
    openvdb::Metadata::ConstPtr p = m_[field];
    if (!p) fail("{}: field '{}' is missing", name_, field);
    auto u = std::dynamic_pointer_cast<const openvdb::UnknownMetadata>(p);
    if (!u || p->typeName() != kBlobType)
      fail("{}: field '{}' has type {}, expected {}", name_, field, p->typeName(), kBlobType);
    return u->value();
  }
  bool has(const char* field) const { return bool(m_[field]); }

 private:
  const openvdb::MetaMap& m_;
  const std::string& name_;
};

void putBlob(openvdb::MetaMap& m, const char* field, std::vector<uint8_t> bytes) {
  openvdb::UnknownMetadata u(kBlobType);
  u.setValue(bytes);
  m.insertMeta(field, u);
}

openvdb::Vec3s toVdb(glm::vec3 v) { return {v.x, v.y, v.z}; }

// ---- encode ---------------------------------------------------------------------------------------------

std::vector<std::byte> encode(const CellFile& cell, std::span<const detail::CellFileOverride> overrides) {
  cell.validate("encodeCellFile");
  initOpenVdb();
  openvdb::MetaMap m;
  m.insertMeta("lfgi_magic", openvdb::StringMetadata(kMagic));
  m.insertMeta("lfgi_format_version", openvdb::Int32Metadata(kCellFileVersion));
  m.insertMeta("world_seed", openvdb::StringMetadata(hex64(cell.worldSeed)));
  m.insertMeta("cell_x", openvdb::Int32Metadata(cell.cellX));
  m.insertMeta("cell_z", openvdb::Int32Metadata(cell.cellZ));
  m.insertMeta("input_hash", openvdb::StringMetadata(hex64(cell.inputHash)));
  m.insertMeta("probe_origin", openvdb::Vec3SMetadata(toVdb(cell.grid.origin)));
  m.insertMeta("probe_spacing", openvdb::Vec3SMetadata(toVdb(cell.grid.spacing)));
  m.insertMeta("probe_dims", openvdb::Vec3IMetadata(openvdb::Vec3i(cell.grid.dims.x, cell.grid.dims.y, cell.grid.dims.z)));
  const int64_t active = cell.activeProbeCount();
  m.insertMeta("probe_count", openvdb::Int64Metadata(active));
  m.insertMeta("exposure", openvdb::FloatMetadata(cell.outputScale.exposure));
  m.insertMeta("range", openvdb::FloatMetadata(cell.outputScale.range));
  if (cell.generator) {
    const CellGenerator& g = *cell.generator;
    const GeneratorArch& a = g.weights.arch;
    m.insertMeta("model", openvdb::StringMetadata("network"));
    m.insertMeta("generator_latent_dim", openvdb::Int32Metadata(a.latentDim));
    m.insertMeta("generator_cond_dim", openvdb::Int32Metadata(a.condDim));
    m.insertMeta("generator_conv_channels", openvdb::StringMetadata(channelsText(a.convChannels)));
    m.insertMeta("generator_latent_source", openvdb::StringMetadata(latentSourceName(a.latentSource)));
    m.insertMeta("generator_fourier_octaves", openvdb::Int32Metadata(a.fourierOctaves));
    m.insertMeta("generator_weight_precision", openvdb::StringMetadata(weightPrecisionName(g.weights.precision)));
    putBlob(m, "generator_weights", encodeWeights(g.weights));
    if (a.latentSource == LatentSource::Stored) {
      m.insertMeta("latent_bits", openvdb::Int32Metadata(g.latents.bits));
      m.insertMeta("latent_count", openvdb::Int64Metadata(g.latents.count));
      putBlob(m, "latents", encodeLatents(g.latents));
    }
  } else {
    m.insertMeta("model", openvdb::StringMetadata("none"));
  }
  m.insertMeta("fallback_kind",
               openvdb::StringMetadata(cell.fallback.kind == CellFallback::Kind::PerCell ? "sh_l1_per_cell" : "sh_l1_per_probe"));
  {
    std::vector<uint8_t> sh, hours, overcast;
    appendPod<uint16_t>(sh, cell.fallback.shHalf);
    putBlob(m, "fallback_sh", std::move(sh));
    m.insertMeta("fallback_key_count", openvdb::Int32Metadata(int32_t(cell.fallback.keyCount())));
    appendPod<float>(hours, cell.fallback.keyHours);
    putBlob(m, "fallback_key_hours", std::move(hours));
    appendPod<float>(overcast, cell.fallback.keyOvercast);
    putBlob(m, "fallback_key_overcast", std::move(overcast));
  }
  m.insertMeta("error_achieved", openvdb::DoubleMetadata(cell.stats.errorAchieved));
  m.insertMeta("error_target", openvdb::DoubleMetadata(cell.stats.errorTarget));
  m.insertMeta("training_seconds", openvdb::DoubleMetadata(cell.stats.trainingSeconds));
  m.insertMeta("bake_model", openvdb::StringMetadata(cell.stats.model));

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
      if (std::sscanf(o.text.c_str(), "%d,%d,%d", &v[0], &v[1], &v[2]) != 3) fail("override {}: expected X,Y,Z", o.field);
      m.insertMeta(o.field, openvdb::Vec3IMetadata(v));
    } else if (p && p->typeName() == kBlobType)
      putBlob(m, o.field.c_str(), std::vector<uint8_t>(o.text.begin(), o.text.end()));
    else if (p && !o.text.empty() && p->typeName() == openvdb::FloatMetadata::staticTypeName())  // "nan", "-1.5"
      m.insertMeta(o.field, openvdb::FloatMetadata(std::strtof(o.text.c_str(), nullptr)));
    else if (p && !o.text.empty() && p->typeName() == openvdb::DoubleMetadata::staticTypeName())
      m.insertMeta(o.field, openvdb::DoubleMetadata(std::strtod(o.text.c_str(), nullptr)));
    else
      m.insertMeta(o.field, openvdb::Int64Metadata(o.intValue));
  }

  openvdb::MaskGrid::Ptr grid = openvdb::MaskGrid::create();
  grid->setName(kGridName);
  {
    openvdb::math::Mat4d xf = openvdb::math::Mat4d::identity();
    xf.setToScale(openvdb::Vec3d(cell.grid.spacing.x, cell.grid.spacing.y, cell.grid.spacing.z));
    xf.setTranslation(openvdb::Vec3d(cell.grid.origin.x, cell.grid.origin.y, cell.grid.origin.z));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(xf));
    auto acc = grid->getAccessor();
    for (int64_t i = 0; i < cell.grid.probeCount(); ++i) {
      if (!cell.active.empty() && cell.active[size_t(i)] == 0) continue;
      glm::ivec3 c = cell.grid.probeCoord(i);
      acc.setValueOn(openvdb::Coord(c.x, c.y, c.z));
    }
  }

  std::ostringstream os(std::ios::binary);
  try {
    openvdb::io::Stream stream(os);
    stream.setCompression(openvdb::io::COMPRESS_ACTIVE_MASK);
    stream.write(openvdb::GridCPtrVec{grid}, m);
  } catch (const openvdb::Exception& e) {
    fail("encodeCellFile: OpenVDB: {}", e.what());
  }
  std::string s = os.str();

  // Deterministic archive UUID (OpenVDB draws a random one per write): derived from everything after it.
  if (s.size() < kUuidOffset + kUuidChars || s[kUuidOffset + 8] != '-' || s[kUuidOffset + 13] != '-')
    fail("encodeCellFile: OpenVDB header layout is not the expected one (archive UUID not at byte {})", kUuidOffset);
  XXH128_hash_t h = XXH3_128bits(s.data() + kUuidOffset + kUuidChars, s.size() - kUuidOffset - kUuidChars);
  std::string hex = fmt::format("{:016x}{:016x}", h.high64, h.low64);
  std::string uuid = hex.substr(0, 8) + "-" + hex.substr(8, 4) + "-" + hex.substr(12, 4) + "-" + hex.substr(16, 4) +
                     "-" + hex.substr(20, 12);
  s.replace(kUuidOffset, kUuidChars, uuid);

  std::vector<std::byte> out(s.size() + kTrailerBytes);
  std::memcpy(out.data(), s.data(), s.size());
  uint64_t length = s.size(), sum = XXH3_64bits(s.data(), s.size());
  std::memcpy(out.data() + s.size(), kTrailerMagic, 8);
  std::memcpy(out.data() + s.size() + 8, &length, 8);
  std::memcpy(out.data() + s.size() + 16, &sum, 8);
  return out;
}

}  // namespace

// ---- CellFile -------------------------------------------------------------------------------------------

int64_t CellFile::activeProbeCount() const {
  if (active.empty()) return grid.probeCount();
  return int64_t(std::count_if(active.begin(), active.end(), [](uint8_t a) { return a != 0; }));
}

void CellFile::validate(const std::string& what) const {
  try {
    grid.validate();
  } catch (const Error& e) {
    fail("{}: probe grid: {}", what, e.what());
  }
  if (grid.probeCount() > kCellFileMaxProbes)
    fail("{}: probe grid {}x{}x{} has {} probes, more than the cell limit {}", what, grid.dims.x, grid.dims.y,
         grid.dims.z, grid.probeCount(), kCellFileMaxProbes);
  if (!active.empty() && int64_t(active.size()) != grid.probeCount())
    fail("{}: active mask holds {} entries for {} probes", what, active.size(), grid.probeCount());
  const int64_t n = activeProbeCount();
  if (!std::isfinite(outputScale.exposure) || outputScale.exposure <= 0.0f)
    fail("{}: exposure {} must be finite and > 0", what, outputScale.exposure);
  if (!std::isfinite(outputScale.range) || outputScale.range <= 0.0f)
    fail("{}: range {} must be finite and > 0", what, outputScale.range);
  if (generator) {
    try {
      generator->weights.validate();
    } catch (const Error& e) {
      fail("{}: generator weights: {}", what, e.what());
    }
    const GeneratorArch& a = generator->weights.arch;
    const QuantizedLatents& l = generator->latents;
    if (a.latentSource == LatentSource::Stored) {
      l.validate(what + ": latents");
      if (l.count != n) fail("{}: {} latents for {} active probes", what, l.count, n);
      if (l.dim != a.latentDim) fail("{}: latents have {} dimensions, the generator takes {}", what, l.dim, a.latentDim);
    } else if (l.count != 0 || !l.codes.empty() || !l.scales.empty()) {
      fail("{}: a position-derived latent model stores no latents, this one holds {}", what, l.count);
    }
  }
  size_t entries = fallback.kind == CellFallback::Kind::PerCell ? 1 : size_t(n);
  if (fallback.kind != CellFallback::Kind::PerCell && fallback.kind != CellFallback::Kind::PerProbe)
    fail("{}: unknown fallback kind {}", what, int(fallback.kind));
  const size_t keys = fallback.keyCount();
  if (keys < 1 || keys > size_t(kCellFileMaxFallbackKeys))
    fail("{}: {} fallback lighting keys (1 to {} allowed)", what, keys, kCellFileMaxFallbackKeys);
  if (fallback.keyOvercast.size() != keys)
    fail("{}: {} fallback key overcast values for {} key hours", what, fallback.keyOvercast.size(), keys);
  for (size_t k = 0; k < keys; ++k) {
    const float h = fallback.keyHours[k], w = fallback.keyOvercast[k];
    if (!(std::isfinite(h) && h >= 0.0f && h <= 24.0f))
      fail("{}: fallback key {} hours = {} (must be finite, in [0, 24])", what, k, h);
    if (!(std::isfinite(w) && w >= 0.0f && w <= 1.0f))
      fail("{}: fallback key {} overcast = {} (must be finite, in [0, 1])", what, k, w);
    if (k > 0) {
      const float ph = fallback.keyHours[k - 1], pw = fallback.keyOvercast[k - 1];
      if (!(ph < h || (ph == h && pw < w)))
        fail("{}: fallback keys not sorted strictly ascending by (hours, overcast): key {} ({} h, overcast {}) after "
             "key {} ({} h, overcast {})",
             what, k, h, w, k - 1, ph, pw);
    }
  }
  if (fallback.shHalf.size() != keys * entries * kShHalves)
    fail("{}: fallback holds {} halves, {} expected ({} keys x {} x 12)", what, fallback.shHalf.size(),
         keys * entries * kShHalves, keys, entries);
  for (size_t i = 0; i < fallback.shHalf.size(); ++i)
    if ((fallback.shHalf[i] & 0x7c00u) == 0x7c00u) fail("{}: fallback SH half {} is Inf or NaN", what, i);
  auto nonNegative = [&](double v, const char* field) {
    if (!std::isfinite(v) || v < 0.0) fail("{}: {} = {} must be finite and >= 0", what, field, v);
  };
  nonNegative(stats.errorAchieved, "errorAchieved");
  nonNegative(stats.errorTarget, "errorTarget");
  nonNegative(stats.trainingSeconds, "trainingSeconds");
  if (stats.model.size() > 4096) fail("{}: model description is {} characters (limit 4096)", what, stats.model.size());
}

std::vector<std::byte> encodeCellFile(const CellFile& cell) { return encode(cell, {}); }

std::vector<std::byte> detail::encodeCellFileWithOverrides(const CellFile& cell,
                                                           std::span<const CellFileOverride> overrides) {
  return encode(cell, overrides);
}

CellFile decodeCellFile(std::span<const std::byte> bytes, const std::string& name, CellFileBytes* bytesByPart) {
  // 1. Envelope: size, trailer, checksum. Nothing below trusts a byte that failed these.
  if (bytes.size() > kCellFileMaxBytes)
    fail("{}: {} bytes, more than the cell file limit {}", name, bytes.size(), kCellFileMaxBytes);
  if (bytes.size() < kTrailerBytes + 8)
    fail("{}: truncated or not a cell file ({} bytes, too short for the OpenVDB header and trailer)", name, bytes.size());
  const std::byte* tail = bytes.data() + bytes.size() - kTrailerBytes;
  uint64_t length = 0, sum = 0;
  std::memcpy(&length, tail + 8, 8);
  std::memcpy(&sum, tail + 16, 8);
  if (std::memcmp(tail, kTrailerMagic, 8) != 0) {
    int64_t vdbMagic = 0;
    std::memcpy(&vdbMagic, bytes.data(), 8);
    if (vdbMagic != openvdb::OPENVDB_MAGIC) fail("{}: not a cell file (no OpenVDB magic at the start)", name);
    fail("{}: truncated or not a cell file (the 'LFGICELL' trailer is missing at the end)", name);
  }
  if (length != bytes.size() - kTrailerBytes)
    fail("{}: truncated or padded: the trailer records {} bytes of OpenVDB data, the file holds {}", name, length,
         bytes.size() - kTrailerBytes);
  uint64_t actual = XXH3_64bits(bytes.data(), size_t(length));
  if (actual != sum)
    fail("{}: corrupt: checksum of the OpenVDB data is {:016x}, the trailer records {:016x}", name, actual, sum);

  // 2. OpenVDB parse (the bytes are the ones our writer produced).
  initOpenVdb();
  openvdb::MetaMap::Ptr meta;
  openvdb::GridPtrVecPtr grids;
  try {
    std::istringstream is(std::string(reinterpret_cast<const char*>(bytes.data()), size_t(length)), std::ios::binary);
    openvdb::io::Stream stream(is, false);
    meta = stream.getMetadata();
    grids = stream.getGrids();
  } catch (const std::exception& e) {
    fail("{}: OpenVDB could not read the file: {}", name, e.what());
  }
  if (!meta || !grids) fail("{}: OpenVDB returned no metadata or grids", name);

  // 3. Fields, each checked on its own and against the others.
  MetaReader r(*meta, name);
  std::string magic = r.get<std::string>("lfgi_magic");
  if (magic != kMagic) fail("{}: lfgi_magic is '{}', expected '{}' (not a cell file)", name, magic, kMagic);
  int64_t version = r.get<int32_t>("lfgi_format_version");
  if (version < 1 || version > kCellFileVersion)
    fail("{}: cell file format version {}, this build reads versions 1 to {} (rebake the cell)", name, version,
         kCellFileVersion);

  CellFile c;
  c.worldSeed = parseHex64(r.get<std::string>("world_seed"), name + ": world_seed");
  c.cellX = r.get<int32_t>("cell_x");
  c.cellZ = r.get<int32_t>("cell_z");
  c.inputHash = parseHex64(r.get<std::string>("input_hash"), name + ": input_hash");
  openvdb::Vec3s o = r.get<openvdb::Vec3s>("probe_origin"), sp = r.get<openvdb::Vec3s>("probe_spacing");
  openvdb::Vec3i d = r.get<openvdb::Vec3i>("probe_dims");
  c.grid.origin = {o.x(), o.y(), o.z()};
  c.grid.spacing = {sp.x(), sp.y(), sp.z()};
  c.grid.dims = {d.x(), d.y(), d.z()};
  try {
    c.grid.validate();
  } catch (const Error& e) {
    fail("{}: probe grid: {}", name, e.what());
  }
  if (c.grid.probeCount() > kCellFileMaxProbes)
    fail("{}: probe_dims {}x{}x{} = {} probes, more than the cell limit {}", name, d.x(), d.y(), d.z(),
         c.grid.probeCount(), kCellFileMaxProbes);
  const int64_t probeCount = r.getInt("probe_count", 0, c.grid.probeCount());
  c.outputScale.exposure = r.getFinite("exposure");
  c.outputScale.range = r.getFinite("range");

  // The probe topology.
  if (grids->size() != 1) fail("{}: {} grids, a cell file holds exactly one ('{}')", name, grids->size(), kGridName);
  openvdb::MaskGrid::Ptr mask = openvdb::gridPtrCast<openvdb::MaskGrid>((*grids)[0]);
  if (!mask || mask->getName() != kGridName)
    fail("{}: the grid is '{}' of type {}, expected '{}' of type {}", name, (*grids)[0]->getName(), (*grids)[0]->type(),
         kGridName, openvdb::MaskGrid::gridType());
  if (mask->tree().activeTileCount() != 0) fail("{}: grid '{}' has active tiles (probes are voxels)", name, kGridName);
  const openvdb::Index64 voxels = mask->activeVoxelCount();
  if (int64_t(voxels) != probeCount)
    fail("{}: probe_count = {}, but grid '{}' has {} active voxels", name, probeCount, kGridName, voxels);
  {
    const openvdb::math::Transform& xf = mask->transform();
    openvdb::Vec3d w0 = xf.indexToWorld(openvdb::Coord(0, 0, 0)), w1 = xf.indexToWorld(openvdb::Coord(1, 1, 1));
    for (int k = 0; k < 3; ++k) {
      double so = double(c.grid.origin[k]), ss = double(c.grid.spacing[k]);
      if (std::fabs(w0[k] - so) > 1e-5 * (1.0 + std::fabs(so)) || std::fabs((w1[k] - w0[k]) - ss) > 1e-5 * ss)
        fail("{}: grid '{}' transform disagrees with probe_origin/probe_spacing on axis {}", name, kGridName, k);
    }
  }
  std::vector<uint8_t> active(size_t(c.grid.probeCount()), 0);
  for (auto it = mask->cbeginValueOn(); it; ++it) {
    openvdb::Coord q = it.getCoord();
    glm::ivec3 g(q.x(), q.y(), q.z());
    if (glm::any(glm::lessThan(g, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(g, c.grid.dims)))
      fail("{}: probe voxel ({}, {}, {}) lies outside the probe grid {}x{}x{}", name, g.x, g.y, g.z, d.x(), d.y(), d.z());
    active[size_t(c.grid.linearIndex(g))] = 1;
  }
  if (probeCount != c.grid.probeCount()) c.active = std::move(active);

  // The model.
  std::string model = r.get<std::string>("model");
  CellFileBytes parts;
  if (model == "network") {
    GeneratorArch a;
    a.latentDim = int(r.getInt("generator_latent_dim", 1, 256));
    a.condDim = int(r.getInt("generator_cond_dim", 0, kConditioningDim));
    a.convChannels = parseChannels(r.get<std::string>("generator_conv_channels"), name + ": generator_conv_channels");
    std::string src = r.get<std::string>("generator_latent_source");
    if (src == "stored") a.latentSource = LatentSource::Stored;
    else if (src == "position_fourier") a.latentSource = LatentSource::PositionFourier;
    else fail("{}: generator_latent_source '{}' is unknown (stored, position_fourier)", name, src);
    a.fourierOctaves = int(r.getInt("generator_fourier_octaves", 0, 16));
    try {
      a.validate();
    } catch (const Error& e) {
      fail("{}: generator architecture: {}", name, e.what());
    }
    std::string prec = r.get<std::string>("generator_weight_precision");
    WeightPrecision p;
    if (prec == "fp16") p = WeightPrecision::Float16;
    else if (prec == "int8") p = WeightPrecision::Int8;
    else fail("{}: generator_weight_precision '{}' is unknown (fp16, int8)", name, prec);
    CellGenerator g;
    std::vector<uint8_t> wb = r.blob("generator_weights");
    try {
      g.weights = decodeWeights(wb, a, p, "generator_weights");
    } catch (const Error& e) {
      fail("{}: {}", name, e.what());
    }
    parts.weights = wb.size();
    if (a.latentSource == LatentSource::Stored) {
      int bits = int(r.getInt("latent_bits", 4, 8));
      if (bits != 4 && bits != 8) fail("{}: latent_bits = {} (supported: 8, 4)", name, bits);
      int64_t count = r.getInt("latent_count", 0, kCellFileMaxProbes);
      if (count != probeCount)
        fail("{}: latent_count = {}, but the file has {} probes", name, count, probeCount);
      std::vector<uint8_t> lb = r.blob("latents");
      try {
        g.latents = decodeLatents(lb, a.latentDim, bits, count, "latents");
      } catch (const Error& e) {
        fail("{}: {}", name, e.what());
      }
      parts.latents = lb.size();
    } else if (r.has("latents")) {
      fail("{}: a position-derived latent model stores no latents, but the file holds a 'latents' blob", name);
    }
    c.generator = std::move(g);
  } else if (model != "none") {
    fail("{}: model '{}' is unknown (network, none)", name, model);
  }

  std::string fk = r.get<std::string>("fallback_kind");
  if (fk == "sh_l1_per_cell") c.fallback.kind = CellFallback::Kind::PerCell;
  else if (fk == "sh_l1_per_probe") c.fallback.kind = CellFallback::Kind::PerProbe;
  else fail("{}: fallback_kind '{}' is unknown (sh_l1_per_cell, sh_l1_per_probe)", name, fk);
  // Lighting keys of the fallback: version 1 has none (one key, read as 12 h overcast 0).
  size_t keys = 1;
  if (version >= 2) {
    keys = size_t(r.getInt("fallback_key_count", 1, kCellFileMaxFallbackKeys));
    std::vector<uint8_t> hb = r.blob("fallback_key_hours"), ob = r.blob("fallback_key_overcast");
    if (hb.size() != keys * sizeof(float))
      fail("{}: fallback_key_hours holds {} bytes, {} expected ({} keys x float32)", name, hb.size(),
           keys * sizeof(float), keys);
    if (ob.size() != keys * sizeof(float))
      fail("{}: fallback_key_overcast holds {} bytes, {} expected ({} keys x float32)", name, ob.size(),
           keys * sizeof(float), keys);
    c.fallback.keyHours.resize(keys);
    c.fallback.keyOvercast.resize(keys);
    std::memcpy(c.fallback.keyHours.data(), hb.data(), hb.size());
    std::memcpy(c.fallback.keyOvercast.data(), ob.data(), ob.size());
    parts.fallback += hb.size() + ob.size();
  } else {
    for (const char* f : {"fallback_key_count", "fallback_key_hours", "fallback_key_overcast"})
      if (r.has(f)) fail("{}: a version-1 cell file holds field '{}' (version 2 and later only)", name, f);
  }
  std::vector<uint8_t> fb = r.blob("fallback_sh");
  size_t entries = c.fallback.kind == CellFallback::Kind::PerCell ? 1 : size_t(probeCount);
  if (fb.size() != keys * entries * kShHalves * 2)
    fail("{}: fallback_sh holds {} bytes, {} expected ({} keys x {} x 12 halves)", name, fb.size(),
         keys * entries * kShHalves * 2, keys, entries);
  c.fallback.shHalf.resize(keys * entries * kShHalves);
  if (!fb.empty()) std::memcpy(c.fallback.shHalf.data(), fb.data(), fb.size());
  parts.fallback += fb.size();

  c.stats.errorAchieved = r.getFiniteDouble("error_achieved");
  c.stats.errorTarget = r.getFiniteDouble("error_target");
  c.stats.trainingSeconds = r.getFiniteDouble("training_seconds");
  c.stats.model = r.get<std::string>("bake_model");

  c.validate(name);
  parts.total = bytes.size();
  if (bytesByPart) *bytesByPart = parts;
  return c;
}

void writeCellFile(const std::filesystem::path& path, const CellFile& cell) {
  std::vector<std::byte> bytes;
  try {
    bytes = encodeCellFile(cell);
  } catch (const Error& e) {
    fail("{}: {}", path.string(), e.what());
  }
  writeFileAtomic(path, bytes);
}

CellFile readCellFile(const std::filesystem::path& path, CellFileBytes* bytesByPart) {
  std::error_code ec;
  auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > kCellFileMaxBytes)
    fail("{}: {} bytes, more than the cell file limit {}", path.string(), size, kCellFileMaxBytes);
  std::vector<std::byte> bytes = readFileBytes(path);
  return decodeCellFile(bytes, path.string(), bytesByPart);
}

// ---- ContentHasher --------------------------------------------------------------------------------------

ContentHasher::ContentHasher() : state_(XXH3_createState()) {
  if (!state_) throw std::bad_alloc();
  XXH3_64bits_reset(static_cast<XXH3_state_t*>(state_));
}
ContentHasher::~ContentHasher() { XXH3_freeState(static_cast<XXH3_state_t*>(state_)); }
ContentHasher& ContentHasher::add(std::span<const std::byte> bytes) {
  XXH3_64bits_update(static_cast<XXH3_state_t*>(state_), bytes.data(), bytes.size());
  return *this;
}
ContentHasher& ContentHasher::add(const std::string& text) {
  uint64_t n = text.size();
  addValue(n);
  return add(std::as_bytes(std::span<const char>(text)));
}
uint64_t ContentHasher::digest() const { return XXH3_64bits_digest(static_cast<XXH3_state_t*>(state_)); }

}  // namespace lfgi
