// World edits: an ordered list of hand edits applied on top of the seeded synthetic world (worlds/OVERVIEW.md
// "World edits", incremental rebake). The list lives in the world manifest (world.json "edits",
// world_cells.h) and in WorldParams::edits, so every tool that opens a world directory sees the edited world.
//
// Kinds (coordinates in metres, world space, doubles; y up):
// - add-building X0,Z0,X1,Z1[,STOREYS]: a building (walls, rooms, windows, slabs, parapet roof; the same
//   generator as the world's own buildings, seeded by (world seed, edit index)) on that XZ footprint.
//   Its ground floor sits 0.15 m above the highest terrain under the footprint; on sloped ground a plinth
//   fills down to 0.3 m below the lowest terrain. It first clears its footprint like clear-region.
// - add-box X0,Y0,Z0,X1,Y1,Z1[,CATEGORY]: a solid axis-aligned box (grey albedo 0.5) of a surface
//   category (terrain, road, wall, interior, roof or prop; default prop). It may overlap other geometry
//   (the synthetic world's no-overlap rule for solid boxes holds for generated content only).
// - clear-region X0,Z0,X1,Z1: removes every building (whole, with its rooms, windows, arcade) and every
//   prop (lamp, tree, bench, rock, hay bale; whole) whose XZ extent overlaps the region with positive
//   area. Terrain and roads stay.
//
// Order: edits apply in list order. Generated content is removed by any clear-region or add-building
// that overlaps it; an edit's own building or box is removed only by a LATER clear-region/add-building.
//
// Ownership and containment (synthetic_world.h: a cell's mesh stays inside its closed XZ range): an edit
// belongs to every cell whose XZ range it overlaps with positive area, and only those cells' generation
// reads it. A building may not cross a cell border: such an edit is REJECTED (a building cut in two
// would have open walls). A box crossing borders is CLIPPED into one closed box per cell (the pieces
// touch on the border). A clear region may span cells: it removes whole objects, each of which belongs to
// one cell, so it never breaks containment.
//
// Validation (validateWorldEdits, called by WorldParams::validate): every number finite, the edit inside
// the world, positive size (boxes also in y, at most 1 km tall), buildings at least 4 m × 4 m with 1..40
// storeys, box categories as above. Errors name the edit: "edit 3 (add-building): ...";
// readWorldManifest prefixes the manifest's path.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json_fwd.hpp>

#include "worlds/mesh.h"

namespace lfgi::worlds {

enum class WorldEditKind : uint8_t { kAddBuilding, kAddBox, kClearRegion };
// "add-building", "add-box", "clear-region" (the CLI flags and the manifest's "type").
std::string_view worldEditKindName(WorldEditKind k);

struct WorldEdit {
  WorldEditKind kind = WorldEditKind::kAddBox;
  // add-box: the box. add-building / clear-region: the XZ footprint (min.y = max.y = 0, unused).
  glm::dvec3 min{0.0};
  glm::dvec3 max{0.0};
  int storeys = 2;                                    // add-building
  SurfaceCategory category = SurfaceCategory::kProp;  // add-box
  friend bool operator==(const WorldEdit&, const WorldEdit&) = default;
};

// Throws lfgi::Error "edit I (KIND): ..." for the first bad edit of a world of sizeM with cells of cellM.
void validateWorldEdits(const std::vector<WorldEdit>& edits, double sizeM, double cellM);

// Manifest form: [{"type": "add-building", "footprint": [x0, z0, x1, z1], "storeys": 3},
//                 {"type": "add-box", "min": [x, y, z], "max": [x, y, z], "category": "prop"},
//                 {"type": "clear-region", "region": [x0, z0, x1, z1]}]
// fromJson throws lfgi::Error "edit I: ..." for an unknown type or a missing/wrong field (it does not
// check ranges: validateWorldEdits does).
nlohmann::ordered_json worldEditsToJson(const std::vector<WorldEdit>& edits);
std::vector<WorldEdit> worldEditsFromJson(const nlohmann::json& array);

// Command-line form (the text after the flag, see the kinds above). Throws lfgi::Error
// "--add-box '<text>': ..." naming the flag; ranges are checked by validateWorldEdits.
WorldEdit parseWorldEdit(WorldEditKind kind, std::string_view text);

// Surface categories an add-box may take, by name; throws lfgi::Error listing them.
SurfaceCategory parseEditBoxCategory(std::string_view name);

}  // namespace lfgi::worlds
