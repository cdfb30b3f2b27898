// One streaming cell of the synthetic world made ready for the bake: its mesh, probes placed and
// classified (probe_placement.h), and surfels sampled at a density tied to the probe spacing and
// Draco-encoded (surfels.h). Also the world directory written by `lfgi world generate`.
//
// World directory (format "lfgi-world", version 1):
//   world.json                 seed, size, cell size, generator version
//   cells/cell_X_Z.json        per-cell statistics, probe grid and counts, mesh hash
//   cells/cell_X_Z.probes      probe flags + relocation offsets (binary, see writeCell)
//   cells/cell_X_Z.surfels     Draco surfels (surfels.h)
// Every file is written atomically; cell_X_Z.json is written last, so its presence marks a finished
// cell and an interrupted generation resumes where it stopped.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "worlds/probe_placement.h"
#include "worlds/surfels.h"
#include "worlds/synthetic_world.h"

namespace lfgi::worlds {

inline constexpr int kWorldFormatVersion = 1;

struct CellStats {
  CellCoord cell;
  CellKind kind = CellKind::kField;
  uint64_t meshHash = 0;
  size_t triangles = 0;
  double surfaceAreaM2 = 0.0;
  std::vector<size_t> categoryTriangles;  // indexed by SurfaceCategory
  float probeSpacingM = 0.0f;
  glm::ivec3 probeDims{0};
  size_t probes = 0, probesActive = 0, probesRelocated = 0, probesDisabled = 0, probesSkyOnly = 0;
  size_t probesDisabledByLayout = 0;  // active after ray placement but inside a solid box / under terrain
  size_t surfels = 0;
  // Buried surfaces dropped (see buildCell): whole triangles before sampling, surfels of partly buried
  // triangles after; surfels + surfelsBuried is what sampling the whole remaining mesh gave.
  size_t trianglesBuried = 0, surfelsBuried = 0;
  double surfelBuriedAreaM2 = 0.0;
  float surfelSpacingM = 0.0f;
  size_t surfelRawBytes = 0, surfelEncodedBytes = 0;
  double generateMs = 0.0, placeMs = 0.0, surfelMs = 0.0;
};

struct BuiltCell {
  CellStats stats;
  TriangleMesh mesh;
  CellLayout layout;
  PlacedProbes probes;
  std::vector<Surfel> surfels;
  std::vector<std::byte> surfelBytes;  // Draco
};

struct CellBuildOptions {
  ProbePlacementOptions placement;
  int surfelPositionBits = 16;
  uint64_t surfelSeed = 1;
  bool dropBuried = true;  // false keeps buried triangles and surfels (to measure what dropping them saves)
};

// Generates cell c and everything the bake needs from it. Rays for probe placement see the cell's mesh
// plus its 8 neighbours' solid boxes (describeCell, cheap), so border probes are classified with what is
// next door. After ray placement, every probe is checked against the cell's analytic solids and the
// terrain height; any that ray placement left inside is disabled and counted (probesDisabledByLayout).
// Buried surfaces are then dropped: triangles lying wholly inside one solid box (offset 1 cm along their
// normal), and surfels whose point 1 cm in front lies inside a solid box or 2 cm under the terrain (terrain
// through a city's ground slab, wall bottoms on slabs, slab undersides below ground). Nothing outside the
// solids sees them, so probes, shading and shadows are unchanged while VIR splats, relights and stores
// fewer surfels (trianglesBuried, surfelsBuried). `mesh` is the mesh without the buried triangles.
BuiltCell buildCell(const SyntheticWorld& world, CellCoord c, const CellBuildOptions& options = {});

nlohmann::ordered_json cellStatsJson(const CellStats& s);

// World directory I/O. writeWorldManifest refuses (lfgi::Error) to overwrite a manifest with different
// parameters; readWorldManifest validates the format, version and parameters and names the file.
void writeWorldManifest(const std::filesystem::path& dir, const WorldParams& params);
WorldParams readWorldManifest(const std::filesystem::path& dir);
// Appends edits to the manifest's list (world_edits.h; validated together, errors name the file and the
// edit index) and rewrites it atomically; returns the new parameters. Generated cell files are left alone.
// writeWorldManifest keeps an existing manifest's edits (it refuses different non-empty ones), and
// readWorldManifest reads and validates them ("edits", optional).
WorldParams appendWorldEdits(const std::filesystem::path& dir, const std::vector<WorldEdit>& edits);
// The manifest's text -> parameters, with readWorldManifest's checks; errors start with `name`.
WorldParams parseWorldManifest(std::string_view text, const std::string& name);
std::filesystem::path cellJsonPath(const std::filesystem::path& dir, CellCoord c);
bool cellDone(const std::filesystem::path& dir, CellCoord c);
void writeCell(const std::filesystem::path& dir, const BuiltCell& cell);
// The parsed cell_X_Z.json of a finished cell (throws lfgi::Error naming the file if missing/corrupt).
nlohmann::ordered_json readCellJson(const std::filesystem::path& dir, CellCoord c);

}  // namespace lfgi::worlds
