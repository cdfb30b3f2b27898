#include "core/region_file.h"

#include <algorithm>
#include <cstring>
#include <map>
#include <utility>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include "core/cell_file_meta.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/vdb_container.h"

namespace lfgi {

namespace {

constexpr char kMagic[8] = {'L', 'F', 'G', 'I', 'R', 'E', 'G', 'N'};
constexpr char kMaskField[] = "probe_mask";
constexpr size_t kMaxFields = 256;
constexpr size_t kMaxNameBytes = 256;

// ---- var / zig codes ------------------------------------------------------------------------------------

struct VarWriter {
  std::vector<std::byte> bytes;
  void u8(uint8_t v) { bytes.push_back(std::byte{v}); }
  void var(uint64_t v) {
    while (v >= 0x80) {
      u8(uint8_t(v | 0x80));
      v >>= 7;
    }
    u8(uint8_t(v));
  }
  void zig(int64_t v) { var((uint64_t(v) << 1) ^ uint64_t(v >> 63)); }
  void raw(const void* p, size_t n) {
    const auto* b = static_cast<const std::byte*>(p);
    bytes.insert(bytes.end(), b, b + n);
  }
  void u64(uint64_t v) { raw(&v, 8); }
  void text(std::span<const std::byte> t) {
    var(t.size());
    raw(t.data(), t.size());
  }
};

// Every read checks what is left first; errors are "<where>: <what> ...".
class VarReader {
 public:
  VarReader(std::span<const std::byte> data, const std::string& where) : data_(data), where_(where) {}
  std::span<const std::byte> take(size_t n, const char* what) {
    if (n > data_.size() - pos_)
      fail("{}: {} needs {} bytes, {} are left", where_, what, n, data_.size() - pos_);
    std::span<const std::byte> s = data_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  uint8_t u8(const char* what) { return uint8_t(take(1, what)[0]); }
  uint64_t var(const char* what) {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const uint8_t b = u8(what);
      if (shift == 63 && b > 1) break;
      v |= uint64_t(b & 0x7f) << shift;
      if (!(b & 0x80)) return v;
    }
    fail("{}: {} is not a valid variable-length integer", where_, what);
  }
  uint64_t var(const char* what, uint64_t hi) {
    const uint64_t v = var(what);
    if (v > hi) fail("{}: {} is {}, at most {} allowed", where_, what, v, hi);
    return v;
  }
  int64_t zig(const char* what) {
    const uint64_t v = var(what);
    return int64_t(v >> 1) ^ -int64_t(v & 1);
  }
  uint64_t u64(const char* what) {
    uint64_t v;
    std::memcpy(&v, take(8, what).data(), 8);
    return v;
  }
  std::span<const std::byte> text(const char* what) { return take(size_t(var(what, data_.size())), what); }
  void expectEnd(const char* what) const {
    if (pos_ != data_.size()) fail("{}: {} bytes after the end of the {}", where_, data_.size() - pos_, what);
  }
  const std::string& where() const { return where_; }

 private:
  std::span<const std::byte> data_;
  const std::string& where_;
  size_t pos_ = 0;
};

uint64_t xxh3(std::span<const std::byte> b) {
  return XXH3_64bits(b.data(), b.size());
}

// ---- metadata values ------------------------------------------------------------------------------------

enum class Type : uint8_t { String, Int32, Int64, Float, Double, Vec3s, Vec3i, Blob, Count };

Type typeOf(const openvdb::Metadata& m, const std::string& field) {
  const std::string t = m.typeName();
  if (t == openvdb::StringMetadata::staticTypeName()) return Type::String;
  if (t == openvdb::Int32Metadata::staticTypeName()) return Type::Int32;
  if (t == openvdb::Int64Metadata::staticTypeName()) return Type::Int64;
  if (t == openvdb::FloatMetadata::staticTypeName()) return Type::Float;
  if (t == openvdb::DoubleMetadata::staticTypeName()) return Type::Double;
  if (t == openvdb::Vec3SMetadata::staticTypeName()) return Type::Vec3s;
  if (t == openvdb::Vec3IMetadata::staticTypeName()) return Type::Vec3i;
  if (t == vdbfile::kBlobType) return Type::Blob;
  fail("encodeRegionFile: field '{}' has type {}, which a region file does not store", field, t);
}

template <typename M>
const auto& valueOf(const openvdb::Metadata& m) {
  return static_cast<const M&>(m).value();
}

std::vector<std::byte> encodeValue(Type type, const openvdb::Metadata& m) {
  VarWriter w;
  switch (type) {
    case Type::String: {
      const std::string& s = valueOf<openvdb::StringMetadata>(m);
      w.text(std::as_bytes(std::span(s.data(), s.size())));
      break;
    }
    case Type::Int32:
      w.zig(valueOf<openvdb::Int32Metadata>(m));
      break;
    case Type::Int64:
      w.zig(valueOf<openvdb::Int64Metadata>(m));
      break;
    case Type::Float:
      w.raw(&valueOf<openvdb::FloatMetadata>(m), 4);
      break;
    case Type::Double:
      w.raw(&valueOf<openvdb::DoubleMetadata>(m), 8);
      break;
    case Type::Vec3s:
      w.raw(valueOf<openvdb::Vec3SMetadata>(m).asPointer(), 12);
      break;
    case Type::Vec3i:
      for (int k = 0; k < 3; ++k) w.zig(valueOf<openvdb::Vec3IMetadata>(m)[k]);
      break;
    case Type::Blob: {
      const std::vector<uint8_t>& b = static_cast<const openvdb::UnknownMetadata&>(m).value();
      w.text(std::as_bytes(std::span(b.data(), b.size())));
      break;
    }
    case Type::Count:
      break;
  }
  return std::move(w.bytes);
}

int32_t int32Of(VarReader& r, const char* field) {
  const int64_t v = r.zig(field);
  if (v < INT32_MIN || v > INT32_MAX) fail("{}: field '{}' = {} does not fit int32", r.where(), field, v);
  return int32_t(v);
}

template <typename T>
T podOf(VarReader& r, const char* field) {
  T v;
  std::memcpy(&v, r.take(sizeof(T), field).data(), sizeof(T));
  return v;
}

openvdb::Metadata::Ptr decodeValue(Type type, VarReader& r, const char* field) {
  switch (type) {
    case Type::String: {
      const std::span<const std::byte> s = r.text(field);
      return openvdb::StringMetadata(std::string(reinterpret_cast<const char*>(s.data()), s.size())).copy();
    }
    case Type::Int32:
      return openvdb::Int32Metadata(int32Of(r, field)).copy();
    case Type::Int64:
      return openvdb::Int64Metadata(r.zig(field)).copy();
    case Type::Float:
      return openvdb::FloatMetadata(podOf<float>(r, field)).copy();
    case Type::Double:
      return openvdb::DoubleMetadata(podOf<double>(r, field)).copy();
    case Type::Vec3s: {
      const std::array<float, 3> v = podOf<std::array<float, 3>>(r, field);
      return openvdb::Vec3SMetadata(openvdb::Vec3s(v[0], v[1], v[2])).copy();
    }
    case Type::Vec3i: {
      const int32_t x = int32Of(r, field), y = int32Of(r, field), z = int32Of(r, field);
      return openvdb::Vec3IMetadata(openvdb::Vec3i(x, y, z)).copy();
    }
    case Type::Blob: {
      const std::span<const std::byte> s = r.text(field);
      const auto* p = reinterpret_cast<const uint8_t*>(s.data());
      openvdb::UnknownMetadata u(vdbfile::kBlobType);
      u.setValue(std::vector<uint8_t>(p, p + s.size()));
      return u.copy();
    }
    case Type::Count:
      break;
  }
  fail("{}: field '{}' has an unknown type", r.where(), field);
}

// Where a field's bytes count in RegionFileBytes: light field payload (the CellFileBytes parts), probe
// topology, or container (everything else, length prefixes included).
enum class Part { Container, Payload, Topology };

Part partOf(const std::string& field) {
  static const char* const payload[] = {
      "generator_weights",    "adapter", "latents", "fallback_sh", "fallback_key_hours",
      "fallback_key_overcast"};
  if (field == "probe_mask") return Part::Topology;
  for (const char* p : payload)
    if (field == p) return Part::Payload;
  return Part::Container;
}

// A blob field's data bytes in its part (0 for the container and for other types).
void countStored(const std::string& field, const openvdb::Metadata& m, uint64_t& payload,
                 uint64_t& topology) {
  if (m.typeName() != vdbfile::kBlobType) return;
  const uint64_t n = static_cast<const openvdb::UnknownMetadata&>(m).value().size();
  const Part part = partOf(field);
  if (part == Part::Payload) payload += n;
  if (part == Part::Topology) topology += n;
}

// ---- probe mask -----------------------------------------------------------------------------------------

std::vector<uint8_t> encodeMask(const std::vector<uint8_t>& active) {
  VarWriter w;
  uint8_t state = 0;
  size_t run = 0;
  for (uint8_t a : active) {
    if ((a != 0) == (state != 0)) {
      ++run;
      continue;
    }
    w.var(run);
    state ^= 1;
    run = 1;
  }
  w.var(run);
  const auto* p = reinterpret_cast<const uint8_t*>(w.bytes.data());
  return {p, p + w.bytes.size()};
}

// Probe mask -> c.active; holds exactly probeCount present probes of c.grid.
void decodeMask(const std::vector<uint8_t>* mask, const std::string& where, int64_t probeCount, CellFile& c) {
  const int64_t total = c.grid.probeCount();
  if (!mask) {
    if (probeCount != total)
      fail("{}: probe_count = {}, but there is no probe_mask (all {} probes)", where, probeCount, total);
    return;
  }
  VarReader r(std::as_bytes(std::span(mask->data(), mask->size())), where);
  std::vector<uint8_t> active(size_t(total), 0);
  int64_t at = 0, present = 0;
  for (bool state = false, first = true; at < total; state = !state, first = false) {
    const int64_t run = int64_t(r.var("probe_mask run", uint64_t(total - at)));
    if (run == 0 && !first) fail("{}: probe_mask has an empty run", where);
    if (state) std::fill_n(active.begin() + at, run, uint8_t(1));
    if (state) present += run;
    at += run;
  }
  r.expectEnd("probe_mask");
  if (present != probeCount)
    fail("{}: probe_count = {}, but probe_mask holds {} probes", where, probeCount, present);
  if (present == total) fail("{}: probe_mask is present although every probe exists", where);
  c.active = std::move(active);
}

// ---- encode ---------------------------------------------------------------------------------------------

struct EncodedCell {
  int x = 0, z = 0;
  std::map<std::string, std::pair<Type, std::vector<std::byte>>> fields;
};

EncodedCell encodeCellFields(const CellFile& cell, std::span<const detail::CellFileOverride> overrides) {
  openvdb::MetaMap m = cellmeta::fields(cell);
  const bool all = std::all_of(cell.active.begin(), cell.active.end(), [](uint8_t a) { return a != 0; });
  if (!all) vdbfile::putBlob(m, kMaskField, encodeMask(cell.active));
  vdbfile::applyOverrides(m, overrides);
  EncodedCell e{cell.cellX, cell.cellZ, {}};
  for (auto it = m.beginMeta(); it != m.endMeta(); ++it) {
    const Type t = typeOf(*it->second, it->first);
    e.fields[it->first] = {t, encodeValue(t, *it->second)};
  }
  return e;
}

void checkCells(glm::ivec2 region, int side, std::span<const CellFile> cells) {
  if (side < 1 || side > kRegionMaxCellsPerSide)
    fail("encodeRegionFile: {} cells per side, 1 to {} allowed", side, kRegionMaxCellsPerSide);
  if (cells.empty()) fail("encodeRegionFile: region ({}, {}) has no cells", region.x, region.y);
  for (const CellFile& c : cells) {
    const glm::ivec2 local = glm::ivec2(c.cellX, c.cellZ) - region * side;
    if (local.x < 0 || local.y < 0 || local.x >= side || local.y >= side)
      fail("encodeRegionFile: cell ({}, {}) lies outside region ({}, {}) of {}x{} cells", c.cellX, c.cellZ,
           region.x, region.y, side, side);
  }
}

std::vector<std::byte> encodeRegion(glm::ivec2 region, int side, std::span<const CellFile> cells,
                                    std::span<const detail::CellFileOverride> overrides) {
  checkCells(region, side, cells);
  std::vector<EncodedCell> enc;
  for (const CellFile& c : cells) enc.push_back(encodeCellFields(c, overrides));
  std::sort(enc.begin(), enc.end(), [](const EncodedCell& a, const EncodedCell& b) {
    return std::pair(a.z, a.x) < std::pair(b.z, b.x);
  });
  for (size_t i = 1; i < enc.size(); ++i)
    if (enc[i].x == enc[i - 1].x && enc[i].z == enc[i - 1].z)
      fail("encodeRegionFile: cell ({}, {}) given twice", enc[i].x, enc[i].z);

  // Field table (every name, sorted) and the common fields (same type and bytes in every cell).
  std::map<std::string, Type> table;
  for (const EncodedCell& e : enc)
    for (const auto& [name, value] : e.fields)
      if (!table.emplace(name, value.first).second && table[name] != value.first)
        fail("encodeRegionFile: field '{}' has different types in different cells", name);
  std::map<std::string, size_t> index;
  std::vector<std::string> common;
  for (const auto& entry : table) {
    const std::string& name = entry.first;
    const size_t next = index.size();
    index[name] = next;
    const auto& first = enc[0].fields;
    const bool same = std::all_of(enc.begin(), enc.end(), [&](const EncodedCell& e) {
      auto it = e.fields.find(name);
      return first.count(name) && it != e.fields.end() && it->second == first.at(name);
    });
    if (same) common.push_back(name);
  }

  std::vector<std::vector<std::byte>> commonValues;
  for (const std::string& name : common) commonValues.push_back(enc[0].fields.at(name).second);
  std::vector<std::vector<std::byte>> records;
  for (EncodedCell& e : enc) {
    for (const std::string& name : common) e.fields.erase(name);
    VarWriter w;
    w.var(e.fields.size());
    for (const auto& [name, value] : e.fields) {
      w.var(index.at(name));
      w.raw(value.second.data(), value.second.size());
    }
    records.push_back(std::move(w.bytes));
  }

  VarWriter head;
  head.raw(kMagic, 8);
  head.raw(&kRegionFileVersion, 4);
  head.raw("\0\0\0\0\0\0\0\0\0\0\0\0", 12);  // head bytes + hash, filled in below
  head.zig(region.x);
  head.zig(region.y);
  head.var(uint64_t(side));
  head.var(table.size());
  for (const auto& [name, type] : table) {
    head.text(std::as_bytes(std::span(name.data(), name.size())));
    head.u8(uint8_t(type));
  }
  head.var(common.size());
  for (size_t k = 0; k < common.size(); ++k) {
    head.var(index.at(common[k]));
    head.raw(commonValues[k].data(), commonValues[k].size());
  }
  head.var(enc.size());
  for (size_t i = 0; i < enc.size(); ++i) {
    head.zig(enc[i].x);
    head.zig(enc[i].z);
    head.var(records[i].size());
    head.u64(xxh3(records[i]));
  }
  std::vector<std::byte>& out = head.bytes;
  if (out.size() > kRegionMaxHeadBytes)
    fail("encodeRegionFile: the head is {} bytes, more than the limit {}", out.size(), kRegionMaxHeadBytes);
  const uint32_t headBytes = uint32_t(out.size());
  std::memcpy(out.data() + 12, &headBytes, 4);
  const uint64_t sum = xxh3(out);  // hash field still zero
  std::memcpy(out.data() + 16, &sum, 8);
  for (const auto& r : records) out.insert(out.end(), r.begin(), r.end());
  return std::move(out);
}

}  // namespace

// ---- read -----------------------------------------------------------------------------------------------

struct RegionFile::Head {
  std::string name;
  glm::ivec2 region{0};
  int side = 0;
  uint64_t headBytes = 0, fileBytes = 0;
  std::vector<std::pair<std::string, Type>> table;
  std::vector<bool> isCommon;
  openvdb::MetaMap common;
  uint64_t commonPayload = 0, commonTopology = 0;  // stored bytes of the common fields by part
  std::vector<RegionCellEntry> cells;
};

namespace {

// The fixed 24 bytes: magic, version, head size (bounded by the file and the limit).
uint32_t readFixedHead(std::span<const std::byte> fixed, uint64_t fileSize, const std::string& name) {
  if (std::memcmp(fixed.data(), kMagic, 8) != 0) fail("{}: not a region file (no LFGIREGN magic)", name);
  uint32_t version = 0, headBytes = 0;
  std::memcpy(&version, fixed.data() + 8, 4);
  std::memcpy(&headBytes, fixed.data() + 12, 4);
  if (version < 1 || version > uint32_t(kRegionFileVersion))
    fail("{}: region file format version {}, this build reads version {} (repack the world)", name, version,
         kRegionFileVersion);
  if (headBytes < kRegionHeadFixedBytes || headBytes > kRegionMaxHeadBytes)
    fail("{}: corrupt: head size {} is outside {} .. {}", name, headBytes, kRegionHeadFixedBytes,
         kRegionMaxHeadBytes);
  if (headBytes > fileSize)
    fail("{}: truncated: the head is {} bytes, the file holds {}", name, headBytes, fileSize);
  return headBytes;
}

void checkHeadHash(std::vector<std::byte> head, const std::string& name) {
  uint64_t recorded = 0;
  std::memcpy(&recorded, head.data() + 16, 8);
  std::memset(head.data() + 16, 0, 8);
  const uint64_t actual = xxh3(head);
  if (actual != recorded)
    fail("{}: corrupt: checksum of the head is {:016x}, the file records {:016x}", name, actual, recorded);
}

void readFieldTable(VarReader& r, RegionFile::Head& h) {
  const size_t count = size_t(r.var("field count", kMaxFields));
  for (size_t i = 0; i < count; ++i) {
    const std::span<const std::byte> n =
        r.take(size_t(r.var("field name length", kMaxNameBytes)), "field name");
    std::string name(reinterpret_cast<const char*>(n.data()), n.size());
    const uint8_t type = r.u8("field type");
    if (name.empty() || type >= uint8_t(Type::Count))
      fail("{}: field {} ('{}') has no name or an unknown type {}", r.where(), i, name, type);
    if (i > 0 && !(h.table.back().first < name))
      fail("{}: field '{}' is out of order or repeated in the field table", r.where(), name);
    h.table.emplace_back(std::move(name), Type(type));
  }
  h.isCommon.assign(count, false);
  const size_t commons = size_t(r.var("common field count", count));
  for (size_t i = 0; i < commons; ++i) {
    const size_t f = size_t(r.var("common field index", count - 1));
    if (h.isCommon[f]) fail("{}: common field '{}' is repeated", r.where(), h.table[f].first);
    h.isCommon[f] = true;
    const char* field = h.table[f].first.c_str();
    const openvdb::Metadata::Ptr value = decodeValue(h.table[f].second, r, field);
    countStored(field, *value, h.commonPayload, h.commonTopology);
    h.common.insertMeta(field, *value);
  }
}

void readIndex(VarReader& r, RegionFile::Head& h) {
  const glm::ivec2 lo = h.region * h.side;
  const size_t count = size_t(r.var("cell count", uint64_t(h.side) * uint64_t(h.side)));
  if (count == 0) fail("{}: the region holds no cells", r.where());
  uint64_t offset = h.headBytes;
  for (size_t i = 0; i < count; ++i) {
    RegionCellEntry e;
    e.cellX = int32Of(r, "cell x");
    e.cellZ = int32Of(r, "cell z");
    e.length = r.var("record bytes", kCellFileMaxBytes);
    e.hash = r.u64("record checksum");
    const glm::ivec2 local = glm::ivec2(e.cellX, e.cellZ) - lo;
    if (local.x < 0 || local.y < 0 || local.x >= h.side || local.y >= h.side)
      fail("{}: cell ({}, {}) lies outside the region's {}x{} cells from ({}, {})", r.where(), e.cellX,
           e.cellZ, h.side, h.side, lo.x, lo.y);
    if (i > 0 && std::pair(e.cellZ, e.cellX) <= std::pair(h.cells.back().cellZ, h.cells.back().cellX))
      fail("{}: cell ({}, {}) is out of order or repeated in the index", r.where(), e.cellX, e.cellZ);
    if (e.length == 0) fail("{}: cell ({}, {}) has an empty record", r.where(), e.cellX, e.cellZ);
    e.offset = offset;
    offset += e.length;
    h.cells.push_back(e);
  }
  r.expectEnd("head");
  if (offset != h.fileBytes)
    fail("{}: truncated or padded: the index ends at byte {}, the file holds {}", h.name, offset,
         h.fileBytes);
}

}  // namespace

RegionFile RegionFile::open(RangeReader read, uint64_t fileSize, std::string name) {
  auto h = std::make_shared<Head>();
  h->name = std::move(name);
  h->fileBytes = fileSize;
  if (fileSize > kRegionMaxFileBytes)
    fail("{}: {} bytes, more than the region file limit {}", h->name, fileSize, kRegionMaxFileBytes);
  if (fileSize < kRegionHeadFixedBytes)
    fail("{}: truncated or not a region file ({} bytes, too short for the head)", h->name, fileSize);
  h->headBytes = readFixedHead(read(0, kRegionHeadFixedBytes), fileSize, h->name);
  std::vector<std::byte> head = read(0, h->headBytes);
  checkHeadHash(head, h->name);
  const std::string where = h->name + ": head";
  VarReader r(std::span<const std::byte>(head).subspan(kRegionHeadFixedBytes), where);
  glm::ivec2 region;
  region.x = int32Of(r, "region x");
  region.y = int32Of(r, "region z");
  h->region = region;
  h->side = int(r.var("cells per side", kRegionMaxCellsPerSide));
  if (h->side < 1) fail("{}: 0 cells per side", where);
  if (std::abs(int64_t(region.x) * h->side) > INT32_MAX / 2 ||
      std::abs(int64_t(region.y) * h->side) > INT32_MAX / 2)
    fail("{}: region ({}, {}) is outside the range of cell indices", where, region.x, region.y);
  vdbfile::initOpenVdb();
  readFieldTable(r, *h);
  readIndex(r, *h);
  RegionFile f;
  f.head_ = std::move(h);
  f.read_ = std::move(read);
  return f;
}

RegionFile RegionFile::open(const std::filesystem::path& path) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) fail("{}: cannot read the region file: {}", path.string(), ec.message());
  return open([path](uint64_t offset, uint64_t length) { return readFileRange(path, offset, length); }, size,
              path.string());
}

RegionFile RegionFile::open(std::span<const std::byte> bytes, std::string name) {
  auto data = std::make_shared<std::vector<std::byte>>(bytes.begin(), bytes.end());
  return open(
      [data](uint64_t offset, uint64_t length) {
        return std::vector<std::byte>(data->begin() + std::ptrdiff_t(offset),
                                      data->begin() + std::ptrdiff_t(offset + length));
      },
      bytes.size(), std::move(name));
}

const std::string& RegionFile::name() const {
  return head_->name;
}
glm::ivec2 RegionFile::region() const {
  return head_->region;
}
int RegionFile::cellsPerSide() const {
  return head_->side;
}
uint64_t RegionFile::headBytes() const {
  return head_->headBytes;
}
uint64_t RegionFile::fileBytes() const {
  return head_->fileBytes;
}
const std::vector<RegionCellEntry>& RegionFile::cells() const {
  return head_->cells;
}

int RegionFile::find(int cellX, int cellZ) const {
  const auto& c = head_->cells;
  auto it =
      std::lower_bound(c.begin(), c.end(), std::pair(cellZ, cellX),
                       [](const RegionCellEntry& e, auto key) { return std::pair(e.cellZ, e.cellX) < key; });
  return it != c.end() && it->cellX == cellX && it->cellZ == cellZ ? int(it - c.begin()) : -1;
}

CellFile RegionFile::decodeRecord(size_t i, CellFileBytes* parts, RegionFileBytes* stored) const {
  const Head& h = *head_;
  const RegionCellEntry& e = h.cells.at(i);
  const std::string where = fmt::format("{}: cell ({}, {})", h.name, e.cellX, e.cellZ);
  std::vector<std::byte> record;
  try {
    record = read_(e.offset, e.length);
  } catch (const Error& err) {  // the reader's message names the file; add the cell
    fail("{} (reading cell ({}, {}))", err.what(), e.cellX, e.cellZ);
  }
  if (record.size() != e.length)
    fail("{}: read {} bytes of a {}-byte record", where, record.size(), e.length);
  const uint64_t actual = xxh3(record);
  if (actual != e.hash)
    fail("{}: corrupt: checksum of the record is {:016x}, the index records {:016x}", where, actual, e.hash);

  openvdb::MetaMap meta(h.common);
  VarReader r(record, where);
  const size_t count = size_t(r.var("field count", h.table.size()));
  std::vector<bool> seen(h.table.size(), false);
  for (size_t k = 0; k < count; ++k) {
    const size_t f = size_t(r.var("field index", h.table.size() - 1));
    if (h.isCommon[f] || seen[f]) fail("{}: field '{}' is given twice", where, h.table[f].first);
    seen[f] = true;
    const char* field = h.table[f].first.c_str();
    const openvdb::Metadata::Ptr value = decodeValue(h.table[f].second, r, field);
    if (stored) countStored(field, *value, stored->payload, stored->topology);
    meta.insertMeta(field, *value);
  }
  r.expectEnd("record");

  std::optional<std::vector<uint8_t>> mask;
  if (meta[kMaskField]) {
    mask = vdbfile::MetaReader(meta, where).blob(kMaskField);
    meta.removeMeta(kMaskField);
  }
  CellFileBytes p;
  CellFile c = cellmeta::decode(
      meta, where,
      [&](int64_t probeCount, CellFile& cell) {
        decodeMask(mask ? &*mask : nullptr, where, probeCount, cell);
      },
      p);
  if (c.cellX != e.cellX || c.cellZ != e.cellZ)
    fail("{}: the record holds cell ({}, {})", where, c.cellX, c.cellZ);
  p.total = e.length;
  if (parts) *parts = p;
  return c;
}

CellFile RegionFile::readCell(size_t i, CellFileBytes* parts) const {
  return decodeRecord(i, parts, nullptr);
}

RegionFileBytes RegionFile::bytesByPart() const {
  RegionFileBytes b;
  b.head = head_->headBytes;
  b.payload = head_->commonPayload;
  b.topology = head_->commonTopology;
  for (size_t i = 0; i < head_->cells.size(); ++i) {
    decodeRecord(i, nullptr, &b);
    b.records += head_->cells[i].length;
  }
  return b;
}

std::vector<std::byte> encodeRegionFile(glm::ivec2 region, int cellsPerSide,
                                        std::span<const CellFile> cells) {
  return encodeRegion(region, cellsPerSide, cells, {});
}

std::vector<std::byte> detail::encodeRegionFileWithOverrides(glm::ivec2 region, int cellsPerSide,
                                                             std::span<const CellFile> cells,
                                                             std::span<const CellFileOverride> overrides) {
  return encodeRegion(region, cellsPerSide, cells, overrides);
}

std::string regionFileName(glm::ivec2 region, std::span<const std::byte> bytes) {
  return fmt::format("region_{}_{}_{:016x}.lfgr", region.x, region.y, xxh3(bytes));
}

}  // namespace lfgi
