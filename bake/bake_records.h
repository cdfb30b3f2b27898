// Bookkeeping of a world bake (worlds/OVERVIEW.md "World edits"): what each cell's bake cost and how it
// ended, the state of every cell of a world against its current inputs, and the cost model that projects a
// bake to larger worlds. Shared by `lfgi bake` (writes the records), `lfgi bake-status` (reads them) and
// bench/bake.
//
// Beside each cell file OUT/cells/cell_X_Z.vdb:
// - cell_X_Z.json: the cell's bake record (cell, cell kind, input hash, seconds by stage, bytes, host,
//   finish time in UTC), written atomically after the cell file;
// - cell_X_Z.failed: written when the cell's bake failed (first line: the error; then host and time),
//   removed when a later bake of the cell succeeds.
// The records are advisory: the cell file and its input hash alone decide whether a cell is done.
//
// Cost model: the mean measured seconds per cell for each cell kind (worlds/synthetic_world.h CellKind:
// field, suburb, city, park), times the kind mix of a world of the requested size (SyntheticWorld::cellKind
// is O(1) per cell, no mesh is generated), divided by the node count. Assumes nodes like the one measured,
// each baking one cell at a time as `lfgi bake` does, and perfect packing (thousands of cells per node).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "bake/world_bake.h"
#include "worlds/synthetic_world.h"

namespace lfgi::bake {

std::filesystem::path cellRecordPath(const std::filesystem::path& outDir, worlds::CellCoord c);
std::filesystem::path cellFailurePath(const std::filesystem::path& outDir, worlds::CellCoord c);

struct CellBakeRecord {
  worlds::CellCoord cell;
  worlds::CellKind kind = worlds::CellKind::kField;
  uint64_t inputHash = 0;
  size_t probes = 0;
  bool network = false;
  std::string model;
  // Seconds by stage: prepare (build the cell, neighbours' meshes, input hash), capture (Embree), training
  // (model choice), total (prepare + bakeCell + write and read-back of the file).
  double prepareSeconds = 0.0, captureSeconds = 0.0, trainingSeconds = 0.0, totalSeconds = 0.0;
  uint64_t bytes = 0;       // the cell file
  std::string host;         // gethostname()
  std::string finishedUtc;  // ISO 8601, e.g. 2026-11-26T22:30:00Z
};

// Atomic write of cell_X_Z.json (creates OUT/cells).
void writeCellBakeRecord(const std::filesystem::path& outDir, const CellBakeRecord& record);
// nullopt when there is no record; throws lfgi::Error naming the file when it is malformed.
std::optional<CellBakeRecord> readCellBakeRecord(const std::filesystem::path& outDir, worlds::CellCoord c);
// Every well-formed record under OUT/cells (malformed ones are skipped with a warning).
std::vector<CellBakeRecord> readAllCellBakeRecords(const std::filesystem::path& outDir);

// cell_X_Z.failed: written atomically; cleared (no error when absent) on a successful bake.
void writeCellBakeFailure(const std::filesystem::path& outDir, worlds::CellCoord c, const std::string& error);
void clearCellBakeFailure(const std::filesystem::path& outDir, worlds::CellCoord c);
// The recorded error (first line of the marker), nullopt when the cell has no failure marker.
std::optional<std::string> readCellBakeFailure(const std::filesystem::path& outDir, worlds::CellCoord c);

// "host" of this machine and the current time as ISO 8601 UTC.
std::string hostName();
std::string utcNow();

// A cell's status against its current inputs. Failed: a failure marker and no up-to-date file (the
// marker wins over missing, corrupt and stale: the last bake of the cell did not succeed).
enum class CellStatus : uint8_t { Done, Stale, Missing, Failed, Corrupt };
const char* cellStatusName(CellStatus s);
struct CellStatusEntry {
  worlds::CellCoord cell;
  worlds::CellKind kind = worlds::CellKind::kField;
  CellStatus status = CellStatus::Missing;
  std::string detail;  // the failure or corruption message
};
// Status of each cell. The input hash (cellInputHash: builds the cell and its neighbours' meshes) is only
// computed where a readable cell file exists, in parallel over all cores, with progress on stderr when
// showProgress. Interruptible: throws lfgi::Error on Ctrl-C (the caller installs the InterruptGuard).
std::vector<CellStatusEntry> worldBakeStatus(const worlds::SyntheticWorld& world,
                                             const std::vector<worlds::CellCoord>& cells,
                                             const WorldBakeSettings& settings,
                                             const std::filesystem::path& outDir, bool showProgress);

inline constexpr size_t kCellKindCount = 4;

struct BakeCostModel {
  std::array<double, kCellKindCount> meanSeconds{};  // measured mean total seconds per cell, by kind
  std::array<size_t, kCellKindCount> samples{};      // records behind each mean
  double overallMeanSeconds = 0.0;                   // all records: stands in for a kind never measured
  size_t totalSamples = 0;
  // Seconds per cell of this kind: its own mean when measured, else the overall mean.
  double secondsPerCell(worlds::CellKind kind) const;
};
// Throws lfgi::Error when there are no records.
BakeCostModel costModelFromRecords(const std::vector<CellBakeRecord>& records);

struct KindMix {
  double sizeM = 0.0, cellM = 0.0, km2 = 0.0;
  size_t cells = 0;
  std::array<size_t, kCellKindCount> cellsByKind{};
};
// The kind of every cell of a world (pure per-cell function: no meshes).
KindMix worldKindMix(const worlds::WorldParams& params);
// The world of about `km2` square kilometres with the given seed and cell size: side rounded to a whole
// number of cells (at least one).
worlds::WorldParams worldParamsForArea(double km2, double cellM, uint64_t seed);

struct BakeProjection {
  KindMix mix;
  double cellSeconds = 0.0;  // sum over the cells of the model's seconds per cell (one node)
  double hours(int nodes) const { return cellSeconds / double(nodes) / 3600.0; }
};
BakeProjection projectBake(const BakeCostModel& model, const worlds::WorldParams& params);

}  // namespace lfgi::bake
