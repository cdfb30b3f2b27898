// Where a baked world's cells are stored, behind one interface the streaming source reads through:
//   cell files  BAKED/cells/cell_X_Z.vdb, one OpenVDB file per cell (core/cell_file.h): what `lfgi bake`
//               writes and rebakes incrementally (the edit format);
//   regions     BAKED/regions/regions.json + region_X_Z_<hash>.lfgr (core/region_file.h): the same cells
//               packed R x R to a file (packRegions), the shipping format; immutable files named by
//               their content, so a CDN or object store can cache them forever, and a small index that
//               names the current file of each region.
//
// regions.json: {"format": "lfgi-regions", "version": 1, "cells_per_side": R, "regions": [{"x", "z",
// "file", "bytes", "cells"}...]}, every field checked (file names must be plain names of this directory).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec2.hpp>

#include "core/cell_file.h"
#include "core/region_file.h"

namespace lfgi {

// "cell_X_Z.vdb"
std::string cellFileName(glm::ivec2 cell);

inline constexpr int kDefaultRegionCells = 8;  // cells per region side

struct RegionIndexEntry {
  glm::ivec2 region{0};
  std::string file;  // a plain file name in the regions directory
  uint64_t bytes = 0;
  int cells = 0;
};

struct RegionIndex {
  int cellsPerSide = kDefaultRegionCells;
  std::vector<RegionIndexEntry> regions;  // sorted by (z, x), no region twice
  const RegionIndexEntry* find(glm::ivec2 region) const;
};

class RegionSource;

// dir/regions.json (or a source's); throws lfgi::Error naming the file and the bad field.
RegionIndex readRegionIndex(const std::filesystem::path& dir);
RegionIndex readRegionIndex(const RegionSource& source);
RegionIndex parseRegionIndex(const std::string& text, const std::string& name);
// Atomic (temp file + rename).
void writeRegionIndex(const std::filesystem::path& dir, const RegionIndex& index);

// Where a regions directory's files come from: a local directory (directoryRegionSource), or an HTTP
// server with range requests (streaming/http_region_source.h). Thread-safe.
class RegionSource {
 public:
  virtual ~RegionSource() = default;
  // A whole small file (regions.json), at most maxBytes; throws lfgi::Error naming it.
  virtual std::vector<std::byte> readAll(const std::string& name, size_t maxBytes) const = 0;
  // Exactly `length` bytes at `offset` of the file; throws lfgi::Error naming it.
  virtual std::vector<std::byte> readRange(const std::string& name, uint64_t offset,
                                           uint64_t length) const = 0;
  // The file's path or URL, for messages.
  virtual std::string locate(const std::string& name) const = 0;
};
std::shared_ptr<const RegionSource> directoryRegionSource(const std::filesystem::path& dir);

// Reads a world's cells, every check of the format included. Thread-safe.
class CellStore {
 public:
  virtual ~CellStore() = default;
  // Whether the cell is stored at all (a missing cell is not an error: the streaming fallback covers it).
  virtual bool has(glm::ivec2 cell) const = 0;
  // The cell with every check; throws lfgi::Error starting with where(cell).
  virtual CellFile read(glm::ivec2 cell) const = 0;
  // Names the cell's storage in messages: the cell file, or "<region file>: cell (x, z)".
  virtual std::string where(glm::ivec2 cell) const = 0;
  // The directory or URL, and what it holds ("cell files" / "regions").
  virtual std::string location() const = 0;
  virtual const char* kind() const = 0;
  // What a cell that has() denies is, in messages ("no cell file", "in no region").
  virtual const char* missing() const = 0;
};

std::unique_ptr<CellStore> openCellFiles(const std::filesystem::path& cellsDir);
// Regions of dir/regions.json; a region's head is read on its first use and kept (a few KB per region).
// Throws lfgi::Error for a missing or bad index.
std::unique_ptr<CellStore> openRegions(const std::filesystem::path& regionsDir);
std::unique_ptr<CellStore> openRegions(std::shared_ptr<const RegionSource> source);

struct PackStats {
  int regions = 0;                   // regions in the index
  int written = 0;                   // region files written (content changed or new)
  int unchanged = 0;                 // region files already there with that content (same name)
  int removed = 0;                   // region files of an earlier pack no longer in the index, deleted
  int cells = 0;                     // cells packed
  uint64_t bytes = 0;                // all region files + regions.json
  uint64_t bytesWritten = 0;         // what this pack wrote (region files + regions.json)
  RegionFileBytes parts;             // summed over every region
  std::vector<std::string> skipped;  // cell files that failed their checks (left out, with the error)
};

// Packs the cell files of cellsDir for cells [0, worldCells) into regions of cellsPerSide x cellsPerSide
// cells in regionsDir: a region whose cells did not change keeps its file byte for byte (its name is its
// content hash); regions.json is rewritten last (atomically), then files no index names are deleted. A
// corrupt cell file is left out (streaming gives its cell the neighbours' fallback) and listed in skipped.
// Throws lfgi::Error when no cell file is readable.
PackStats packRegions(const std::filesystem::path& cellsDir, const std::filesystem::path& regionsDir,
                      glm::ivec2 worldCells, int cellsPerSide = kDefaultRegionCells);

}  // namespace lfgi
