// RegionFile: the cells of one square of the world (a region, cellsPerSide x cellsPerSide cells) in one
// immutable file, so the fixed cost a cell file pays for its container (~9.3 KB of OpenVDB internal-node
// masks, core/cell_file.h) is not paid per cell, and a reader fetches one cell with one byte range.
//
// Layout (little-endian; "var" = unsigned LEB128, "zig" = zigzag LEB128):
//   head    [24 B]  "LFGIREGN", u32 format version, u32 head bytes H, u64 XXH3-64 of the head with these
//                   8 bytes zeroed
//           [body]  zig regionX, zig regionZ, var cellsPerSide;
//                   field table: var count, per field var name length + name, u8 type;
//                   common fields: var count, per field var table index + value;
//                   cell index: var count, per cell zig cellX, zig cellZ, var record bytes, u64 XXH3-64
//   records         cell i's record at H + sum of the lengths before it (index order, no gaps, the last
//                   one ends the file): var count, per field var table index + value
// A cell's fields are exactly the metadata map its cell file holds (core/cell_file_meta.h), the same
// names, types and blobs, plus "probe_mask" (a blob; absent when every probe of the grid exists: run
// lengths as var, alternately absent and present probes in ProbeGrid linear order, starting with an
// absent run that may be 0) in place of the cell file's MaskGrid. A field whose value is the same in
// every cell of the region (format version, world seed, architecture, lighting keys ...) is stored once,
// in the common fields. Values by type: string / blob var length + bytes; int32 / int64 zig; float /
// double / vec3s their bytes; vec3i three zig. So a cell read from a region is field for field the cell
// written alone: encodeCellFile of it gives the cell file's bytes.
//
// Reader contract (as the cell reader's): the head's size is bounded and its checksum verified before a
// byte of it is parsed; every count and length is checked against what is left; the index must tile the
// file exactly; a record's XXH3-64 is checked before it is parsed; then the cell goes through every check
// of core/cell_file.h and must lie inside the region's square. Every failure is an lfgi::Error "<name>:
// <problem>", for a record "<name>: cell (x, z): <problem>". Writing is deterministic: the same cells
// give the same bytes, so a file can be named by its content hash (regionFileName) and served from any
// static store (a CDN, an object store, `RangeReader` over HTTP).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec2.hpp>

#include "core/cell_file.h"

namespace lfgi {

inline constexpr int kRegionFileVersion = 1;
inline constexpr int kRegionMaxCellsPerSide = 64;
inline constexpr size_t kRegionHeadFixedBytes = 24;
inline constexpr size_t kRegionMaxHeadBytes = size_t(16) << 20;
inline constexpr uint64_t kRegionMaxFileBytes = uint64_t(1) << 36;  // 64 GiB

struct RegionCellEntry {
  int cellX = 0, cellZ = 0;
  uint64_t offset = 0;  // from the start of the file
  uint64_t length = 0;  // record bytes
  uint64_t hash = 0;    // XXH3-64 of the record
};

// Encodes the cells (each inside the region's square, no cell twice, at least one) as a region file;
// cells are stored sorted by (z, x). Throws lfgi::Error naming the bad cell.
std::vector<std::byte> encodeRegionFile(glm::ivec2 region, int cellsPerSide, std::span<const CellFile> cells);

// Reads `length` bytes at `offset` of a region file (exactly that many, or throws lfgi::Error). May be
// called from several threads at once.
using RangeReader = std::function<std::vector<std::byte>(uint64_t offset, uint64_t length)>;

// Where the bytes of a region file go (what `lfgi inspect` prints for it).
struct RegionFileBytes {
  uint64_t head = 0;     // header + field table + common fields + index
  uint64_t records = 0;  // every cell record
  // As stored (a field common to every cell counts once): the weights, adapters, latents and fallbacks
  // (CellFileBytes parts) and the probe_mask blobs, their data bytes.
  uint64_t payload = 0;
  uint64_t topology = 0;
  uint64_t total() const { return head + records; }
  // Everything that is not light field or topology, per cell: the container cost.
  double containerPerCell(size_t cells) const {
    return cells ? (double(total()) - double(payload + topology)) / double(cells) : 0.0;
  }
};

class RegionFile {
 public:
  // Reads and checks the head and the index (two reads: the fixed 24 B, then the rest of the head).
  // fileSize: the region file's size (the index must end exactly there).
  static RegionFile open(RangeReader read, uint64_t fileSize, std::string name);
  // A region file on disk (its size from the file system; reads by positioned reads).
  static RegionFile open(const std::filesystem::path& path);
  // A whole region file in memory (tests, the fuzz target); the bytes are copied.
  static RegionFile open(std::span<const std::byte> bytes, std::string name);

  const std::string& name() const;
  glm::ivec2 region() const;
  int cellsPerSide() const;
  uint64_t headBytes() const;
  uint64_t fileBytes() const;
  const std::vector<RegionCellEntry>& cells() const;
  // The index of cell (x, z), or -1 when the region does not hold it.
  int find(int cellX, int cellZ) const;
  // Reads cell i's record (one range read), checks it, decodes it with every cell-file check. parts (if
  // given): the cell's bytes by part, total = its record's bytes. Thread-safe.
  CellFile readCell(size_t i, CellFileBytes* parts = nullptr) const;
  // Reads every cell and totals the bytes by part.
  RegionFileBytes bytesByPart() const;

  struct Head;  // the parsed head (opaque)

 private:
  // stored: adds the record's payload and topology bytes as stored (common fields count in the head).
  CellFile decodeRecord(size_t i, CellFileBytes* parts, RegionFileBytes* stored) const;
  std::shared_ptr<const Head> head_;
  RangeReader read_;
};

// The content-addressed file name of a region file: region_X_Z_<XXH3-64 of the bytes, 16 hex>.lfgr.
std::string regionFileName(glm::ivec2 region, std::span<const std::byte> bytes);

namespace detail {
// Test seam: encodes like encodeRegionFile with the cells' fields overridden (core/cell_file.h
// CellFileOverride) before the region is sealed, for regions that are intact but semantically wrong.
std::vector<std::byte> encodeRegionFileWithOverrides(glm::ivec2 region, int cellsPerSide,
                                                     std::span<const CellFile> cells,
                                                     std::span<const CellFileOverride> overrides);
}  // namespace detail

}  // namespace lfgi
