#include "core/cell_store.h"

#include <algorithm>
#include <cstring>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/progress.h"

namespace lfgi {

namespace fs = std::filesystem;

namespace {

constexpr char kIndexName[] = "regions.json";
constexpr char kIndexFormat[] = "lfgi-regions";
constexpr int kIndexVersion = 1;

int floorDiv(int a, int b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

glm::ivec2 regionOf(glm::ivec2 cell, int side) {
  return {floorDiv(cell.x, side), floorDiv(cell.y, side)};
}

bool plainRegionName(const std::string& f) {
  return !f.empty() && f.find('/') == std::string::npos && f.find('\\') == std::string::npos && f != "." &&
         f != ".." && fs::path(f).extension() == ".lfgr";
}

template <typename T>
T field(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key)) fail("{}: field '{}' is missing", where, key);
  try {
    return j.at(key).get<T>();
  } catch (const nlohmann::json::exception&) {
    fail("{}: field '{}' has the wrong type", where, key);
  }
}

RegionIndexEntry parseEntry(const nlohmann::json& r, int side, const std::string& where) {
  if (!r.is_object()) fail("{}: not an object", where);
  RegionIndexEntry e;
  const int64_t x = field<int64_t>(r, "x", where), z = field<int64_t>(r, "z", where);
  const int64_t bound = int64_t(1) << 24;
  if (std::abs(x) > bound || std::abs(z) > bound) fail("{}: region ({}, {}) is out of range", where, x, z);
  e.region = {int(x), int(z)};
  e.file = field<std::string>(r, "file", where);
  if (!plainRegionName(e.file)) fail("{}: file '{}' is not a plain .lfgr file name", where, e.file);
  e.bytes = field<uint64_t>(r, "bytes", where);
  if (e.bytes < kRegionHeadFixedBytes || e.bytes > kRegionMaxFileBytes)
    fail("{}: bytes {} is out of range", where, e.bytes);
  const int64_t cells = field<int64_t>(r, "cells", where);
  if (cells < 1 || cells > int64_t(side) * side)
    fail("{}: cells {} is outside 1 .. {}", where, cells, side * side);
  e.cells = int(cells);
  return e;
}

// ---- cell files -----------------------------------------------------------------------------------------

class CellFilesStore final : public CellStore {
 public:
  explicit CellFilesStore(fs::path dir) : dir_(std::move(dir)) {}
  bool has(glm::ivec2 cell) const override {
    std::error_code ec;
    return fs::exists(path(cell), ec);
  }
  CellFile read(glm::ivec2 cell) const override {
    if (!has(cell)) fail("{}: no cell file", path(cell).string());
    return readCellFile(path(cell));
  }
  std::string where(glm::ivec2 cell) const override { return path(cell).string(); }
  std::string location() const override { return dir_.string(); }
  const char* kind() const override { return "cell files"; }
  const char* missing() const override { return "no cell file"; }

 private:
  fs::path path(glm::ivec2 cell) const { return dir_ / cellFileName(cell); }
  fs::path dir_;
};

// ---- regions --------------------------------------------------------------------------------------------

class DirectorySource final : public RegionSource {
 public:
  explicit DirectorySource(fs::path dir) : dir_(std::move(dir)) {}
  std::vector<std::byte> readAll(const std::string& name, size_t maxBytes) const override {
    const fs::path path = dir_ / name;
    std::error_code ec;
    if (!fs::exists(path, ec)) fail("{}: no such file", path.string());
    const uint64_t size = fs::file_size(path, ec);
    if (!ec && size > maxBytes) fail("{}: {} bytes, more than the limit {}", path.string(), size, maxBytes);
    return readFileBytes(path);
  }
  std::vector<std::byte> readRange(const std::string& name, uint64_t offset, uint64_t length) const override {
    return readFileRange(dir_ / name, offset, length);
  }
  std::string locate(const std::string& name) const override { return (dir_ / name).string(); }

 private:
  fs::path dir_;
};

class RegionStore final : public CellStore {
 public:
  explicit RegionStore(std::shared_ptr<const RegionSource> source)
      : source_(std::move(source)), index_(readRegionIndex(*source_)) {}

  bool has(glm::ivec2 cell) const override {
    const RegionIndexEntry* e = index_.find(regionOf(cell, index_.cellsPerSide));
    if (!e) return false;
    try {
      return region(*e)->find(cell.x, cell.y) >= 0;
    } catch (const Error&) {
      return true;  // stored, but unreadable: read() reports why
    }
  }
  CellFile read(glm::ivec2 cell) const override {
    const RegionIndexEntry* e = index_.find(regionOf(cell, index_.cellsPerSide));
    if (!e) fail("{}: no region holds cell ({}, {})", source_->locate(kIndexName), cell.x, cell.y);
    const std::shared_ptr<const RegionFile> f = region(*e);
    const int i = f->find(cell.x, cell.y);
    if (i < 0) fail("{}: cell ({}, {}) is not in the region", f->name(), cell.x, cell.y);
    return f->readCell(size_t(i));
  }
  std::string where(glm::ivec2 cell) const override {
    const RegionIndexEntry* e = index_.find(regionOf(cell, index_.cellsPerSide));
    return fmt::format("{}: cell ({}, {})", source_->locate(e ? e->file : kIndexName), cell.x, cell.y);
  }
  std::string location() const override {
    const std::string index = source_->locate(kIndexName);
    return index.substr(0, index.size() - std::strlen(kIndexName) - 1);
  }
  const char* kind() const override { return "regions"; }
  const char* missing() const override { return "in no region"; }

 private:
  // The region's opened head, cached (a failed open is not cached: the next read retries and reports).
  // The index's byte count stands for the file size (one request fewer over HTTP); the head's index must
  // tile exactly that many bytes.
  std::shared_ptr<const RegionFile> region(const RegionIndexEntry& e) const {
    {
      const std::lock_guard lock(mutex_);
      auto it = open_.find({e.region.x, e.region.y});
      if (it != open_.end()) return it->second;
    }
    const std::string where = source_->locate(e.file);
    std::shared_ptr<const RegionSource> src = source_;
    const std::string file = e.file;
    auto f = std::make_shared<const RegionFile>(RegionFile::open(
        [src, file](uint64_t offset, uint64_t length) { return src->readRange(file, offset, length); },
        e.bytes, where));
    if (f->region() != e.region || f->cellsPerSide() != index_.cellsPerSide)
      fail("{}: holds region ({}, {}) of {} cells per side; {} names region ({}, {}) of {}", where,
           f->region().x, f->region().y, f->cellsPerSide(), kIndexName, e.region.x, e.region.y,
           index_.cellsPerSide);
    const std::lock_guard lock(mutex_);
    return open_.emplace(std::pair(e.region.x, e.region.y), f).first->second;
  }

  std::shared_ptr<const RegionSource> source_;
  RegionIndex index_;
  mutable std::mutex mutex_;
  mutable std::map<std::pair<int, int>, std::shared_ptr<const RegionFile>> open_;
};

// One region's cells packed into its file in regionsDir (written unless that content is there already).
void packOneRegion(glm::ivec2 region, std::vector<CellFile>& cells, int side, const fs::path& regionsDir,
                   RegionIndex& index, PackStats& stats) {
  const std::vector<std::byte> bytes = encodeRegionFile(region, side, cells);
  const std::string name = regionFileName(region, bytes);
  const fs::path path = regionsDir / name;
  fs::create_directories(regionsDir);
  std::error_code ec;
  if (fs::exists(path, ec) && fs::file_size(path, ec) == bytes.size() && readFileBytes(path) == bytes) {
    ++stats.unchanged;
  } else {
    writeFileAtomic(path, bytes);
    ++stats.written;
    stats.bytesWritten += bytes.size();
  }
  const RegionFileBytes parts = RegionFile::open(bytes, path.string()).bytesByPart();
  stats.parts.head += parts.head;
  stats.parts.records += parts.records;
  stats.parts.payload += parts.payload;
  stats.parts.topology += parts.topology;
  stats.bytes += bytes.size();
  stats.cells += int(cells.size());
  index.regions.push_back({region, name, bytes.size(), int(cells.size())});
}

}  // namespace

std::string cellFileName(glm::ivec2 cell) {
  return fmt::format("cell_{}_{}.vdb", cell.x, cell.y);
}

const RegionIndexEntry* RegionIndex::find(glm::ivec2 region) const {
  auto it = std::lower_bound(
      regions.begin(), regions.end(), std::pair(region.y, region.x),
      [](const RegionIndexEntry& e, auto key) { return std::pair(e.region.y, e.region.x) < key; });
  return it != regions.end() && it->region == region ? &*it : nullptr;
}

RegionIndex parseRegionIndex(const std::string& text, const std::string& name) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    fail("{}: not valid JSON: {}", name, e.what());
  }
  if (!j.is_object()) fail("{}: not a JSON object", name);
  if (field<std::string>(j, "format", name) != kIndexFormat)
    fail("{}: format is not '{}'", name, kIndexFormat);
  const int64_t version = field<int64_t>(j, "version", name);
  if (version != kIndexVersion) fail("{}: version {}, this build reads {}", name, version, kIndexVersion);
  RegionIndex index;
  const int64_t side = field<int64_t>(j, "cells_per_side", name);
  if (side < 1 || side > kRegionMaxCellsPerSide)
    fail("{}: cells_per_side {} is outside 1 .. {}", name, side, kRegionMaxCellsPerSide);
  index.cellsPerSide = int(side);
  const nlohmann::json regions = field<nlohmann::json>(j, "regions", name);
  if (!regions.is_array()) fail("{}: field 'regions' is not an array", name);
  for (size_t i = 0; i < regions.size(); ++i) {
    const RegionIndexEntry e =
        parseEntry(regions[i], index.cellsPerSide, fmt::format("{}: regions[{}]", name, i));
    if (!index.regions.empty() && std::pair(e.region.y, e.region.x) <=
                                      std::pair(index.regions.back().region.y, index.regions.back().region.x))
      fail("{}: regions[{}] ({}, {}) is out of order or repeated", name, i, e.region.x, e.region.y);
    index.regions.push_back(e);
  }
  return index;
}

RegionIndex readRegionIndex(const RegionSource& source) {
  const std::vector<std::byte> bytes = source.readAll(kIndexName, size_t(64) << 20);
  return parseRegionIndex(std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                          source.locate(kIndexName));
}

void checkIndexExists(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir / kIndexName, ec))
    fail("{}: no region index (pack the world's cells with `lfgi pack`)", (dir / kIndexName).string());
}

RegionIndex readRegionIndex(const fs::path& dir) {
  checkIndexExists(dir);
  return readRegionIndex(DirectorySource(dir));
}

void writeRegionIndex(const fs::path& dir, const RegionIndex& index) {
  nlohmann::json regions = nlohmann::json::array();
  for (const RegionIndexEntry& e : index.regions)
    regions.push_back(
        {{"x", e.region.x}, {"z", e.region.y}, {"file", e.file}, {"bytes", e.bytes}, {"cells", e.cells}});
  const nlohmann::json j = {{"format", kIndexFormat},
                            {"version", kIndexVersion},
                            {"cells_per_side", index.cellsPerSide},
                            {"regions", regions}};
  writeFileAtomic(dir / kIndexName, j.dump(1) + "\n");
}

std::unique_ptr<CellStore> openCellFiles(const fs::path& cellsDir) {
  return std::make_unique<CellFilesStore>(cellsDir);
}

std::shared_ptr<const RegionSource> directoryRegionSource(const fs::path& dir) {
  return std::make_shared<DirectorySource>(dir);
}

std::unique_ptr<CellStore> openRegions(const fs::path& regionsDir) {
  checkIndexExists(regionsDir);
  return openRegions(directoryRegionSource(regionsDir));
}

std::unique_ptr<CellStore> openRegions(std::shared_ptr<const RegionSource> source) {
  return std::make_unique<RegionStore>(std::move(source));
}

PackStats packRegions(const fs::path& cellsDir, const fs::path& regionsDir, glm::ivec2 worldCells, int side) {
  if (side < 1 || side > kRegionMaxCellsPerSide)
    fail("packRegions: {} cells per region side, 1 to {} allowed", side, kRegionMaxCellsPerSide);
  RegionIndex index;
  index.cellsPerSide = side;
  PackStats stats;
  const glm::ivec2 regions = (worldCells + side - 1) / side;
  Progress progress("pack", size_t(regions.x) * size_t(regions.y), "regions");
  for (int rz = 0; rz < regions.y; ++rz)
    for (int rx = 0; rx < regions.x; ++rx) {
      std::vector<CellFile> cells;
      for (int z = rz * side; z < std::min(worldCells.y, (rz + 1) * side); ++z)
        for (int x = rx * side; x < std::min(worldCells.x, (rx + 1) * side); ++x) {
          const fs::path path = cellsDir / cellFileName({x, z});
          std::error_code ec;
          if (!fs::exists(path, ec)) continue;
          try {
            cells.push_back(readCellFile(path));
          } catch (const Error& e) {
            stats.skipped.push_back(e.what());
          }
        }
      if (!cells.empty()) packOneRegion({rx, rz}, cells, side, regionsDir, index, stats);
      progress.update(size_t(rz * regions.x + rx + 1));
    }
  progress.finish();
  if (index.regions.empty()) fail("{}: no readable cell file to pack", cellsDir.string());
  writeRegionIndex(regionsDir, index);
  std::error_code ec;
  const uint64_t indexBytes = fs::file_size(regionsDir / kIndexName, ec);
  stats.bytes += indexBytes;
  stats.bytesWritten += indexBytes;
  stats.regions = int(index.regions.size());
  std::set<std::string> named;
  for (const RegionIndexEntry& e : index.regions) named.insert(e.file);
  for (const fs::directory_entry& f : fs::directory_iterator(regionsDir))
    if (f.path().extension() == ".lfgr" && !named.count(f.path().filename().string()) &&
        fs::remove(f.path(), ec))
      ++stats.removed;
  return stats;
}

}  // namespace lfgi
