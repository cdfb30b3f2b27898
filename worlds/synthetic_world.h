// SyntheticWorld: a seeded, km-scale procedural city/countryside, generated one streaming cell at a time.
//
// Conventions: metres, right-handed, +Y up. The world spans [0, sizeM) in X and Z; cell (x, z) covers
// [x * cellM, (x + 1) * cellM) × [z * cellM, (z + 1) * cellM). Urban ground and roads lie at y = 0;
// hills rise from that plain only away from roads and urban cells.
//
// Contracts:
// - Cheap construction: the constructor validates parameters and generates nothing.
// - Per cell on demand: generateCell / describeCell read only pure functions of (seed, cell index) of the
//   cell and its 8 neighbours (their kinds decide the road edges and the terrain's flattening), so any
//   cell can be generated alone, in any order, in any process, by any instance, with bit-identical
//   output (TriangleMesh::contentHash() equal).
// - Edits (world_edits.h): a cell also reads the edits whose XZ extent overlaps it (editCells), nothing
//   else, so an edit changes only the cells it overlaps; with no edits the world is the pure one.
// - Randomness: every random number is a splitmix64-style hash of (seed, purpose, cell x, cell z,
//   object indices, counter); there is no global RNG stream.
// - Containment: every vertex of cell (x, z) lies in its closed XZ range. Nothing crosses a cell border
//   except roads and terrain, which are cut exactly on it.
// - Seams: terrain is a height field sampled on one global lattice (terrainStepM(), cellM / n with
//   n = round(cellM / 4)); the vertices of a shared cell edge come from the same integer lattice indices
//   through the same function, so both cells hold bit-identical vertices at identical positions (no cracks,
//   no T-junctions).
// - Showcase district: in every world with at least 4×4 cells and cellM >= 32, the first 4×4 cells have a
//   fixed layout of cell kinds and block types, so that every GI failure-mode feature is in the 256 m
//   default world for every seed (sizes, storeys, colours, positions and lit windows still come from the
//   seed). Elsewhere the layout comes from a low-frequency "urbanness" noise plus per-cell hashes.
//       z=3:  field   field      suburb   field        (rows: cell z; columns: cell x = 0..3)
//       z=2:  field   courtyard  towers*  suburb       * its first building has saturated walls
//       z=1:  suburb  leak test  arcade   park         leak house faces -Z, arcade faces -X (main road)
//       z=0:  field   suburb     suburb   field
//   With 64 m cells main roads run along x = 128 and z = 128, streets along every urban cell's edges.
// - Roads: main roads (12 m) on every mainRoadSpacingCells()-th cell border line inside the world,
//   streets (8 m) on every edge of an urban cell, inner streets in urban cells of >= 96 m (one block per
//   ~64 m). Strips are kRoadRaiseM above flat ground, with 8 cm skirts towards non-road ground.
// - Surface categories: terrain kTerrain; road strips kRoad; exterior walls kWall (their room-facing face
//   is interior plaster, kInterior); interior walls, floors and ceiling slabs kInterior; roof slabs kRoof;
//   glass panes kGlass (double-sided quads in the wall's mid-plane); lit windows and lamp heads kEmissive;
//   arcade pillars and roofs, lamp poles and caps, trees, benches, hay bales, rocks kProp.
// - Sizes: storeys ~3 m (2.8-3.4), exterior walls 0.3 m, interior walls 0.15 m, slabs 0.25 m, the
//   ground-floor slab top 0.15 m above ground; foundations reach 0.1 m below ground. A typical 64 m city
//   cell has 10-20k triangles (at most ~22k for seed 1 of the 4 km world); cells larger than 64 m hold
//   proportionally more blocks.
// - Not modelled: stairs (storeys are not connected), pitched roofs, terrain under buildings is left in
//   place (hidden inside the ground slab), no roads on the world boundary. Vertices are absolute world
//   floats, so precision degrades for worlds much larger than ~50 km.
//
// Thread safety: all const member functions may be called concurrently.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "worlds/mesh.h"
#include "worlds/world_edits.h"

namespace lfgi::worlds {

struct WorldParams {
  uint64_t seed = 1;
  double sizeM = 4096;  // world extent in X and Z; a whole multiple of cellM
  double cellM = 64;    // streaming cell size, in [16, 512]
  // Hand edits applied on top of the generated world, in order (world_edits.h); empty: the pure world.
  std::vector<WorldEdit> edits{};

  // Throws lfgi::Error unless sizeM is finite and a positive whole multiple of cellM (relative tolerance
  // 1e-9), cellM is in [16, 512], there are at most 65536 cells per axis, and every edit is valid
  // (validateWorldEdits: "edit I (KIND): ...").
  void validate() const;
  // The 256 m × 256 m (4×4 cells) world of the README demo.
  static WorldParams smallDefault(uint64_t seed = 1) { return WorldParams{seed, 256.0, 64.0}; }
};

struct CellCoord {
  int x = 0;
  int z = 0;
  friend bool operator==(const CellCoord&, const CellCoord&) = default;
};

// What a cell holds. Cells smaller than 32 m are always kField (a city block needs room).
enum class CellKind : uint8_t {
  kField,   // open country: hilly terrain, at most a few low props (<= 1.6 m), lamps only along main roads
  kSuburb,  // flat; streets on every edge; 2-4 small houses (1-2 storeys, overhanging roofs) per block
  kCity,    // flat; streets on every edge; blocks of 1-8 storey buildings, arcades, courtyards, leak tests
  kPark,    // flat; streets on every edge; trees, benches and lamps, no buildings
};
std::string_view cellKindName(CellKind k);

// How a city block is laid out (suburb and park blocks have their own fixed type).
enum class BlockType : uint8_t {
  kTowers,     // 1-4 buildings of 2-8 storeys with alleys between them
  kCourtyard,  // a closed ring of four wings around an open yard; yard facades red, green, blue, white
  kArcade,     // a long building with a colonnade (arcade) along its street facade, plus buildings behind
  kLeakTest,   // a one-storey leak-test house (lit room | thin wall | sealed room) plus buildings behind
  kHouses,     // suburb
  kPark,       // park
  kNone,       // field
};
std::string_view blockTypeName(BlockType t);

// Road strips are raised this much above the (flat, y = 0) ground under them.
inline constexpr float kRoadRaiseM = 0.08f;

// A closed axis-aligned box of the cell mesh (12 outward triangles). Boxes may touch but never overlap
// in volume (except where noted: terrain passes through foundations and slabs that sit 0.1 m below
// ground). Probe placement tests "inside solid" against these; terrain is separate (terrainHeight()).
struct SolidBox {
  Aabb box;
  SurfaceCategory category = SurfaceCategory::kWall;
};

enum class RoofKind : uint8_t {
  kFlatParapet,   // flat roof slab inside the walls, walls rise 0.6-1.0 m above it
  kFlatOverhang,  // flat roof slab on top of the walls, overhanging them by overhangM on every side
};

struct Building {
  Aabb footprint;  // outer faces of the exterior walls (XZ), y from foundation bottom to wall/roof top
  Aabb bounds;     // everything of this building (roof overhang, arcade included)
  int storeys = 1;
  float storeyHeightM = 3.0f;
  float groundFloorY = 0.15f;  // top of the ground-floor slab
  float wallThicknessM = 0.3f;
  RoofKind roof = RoofKind::kFlatParapet;
  float overhangM = 0.0f;
  int firstRoom = 0;  // rooms [firstRoom, firstRoom + roomCount) of CellLayout::rooms
  int roomCount = 0;
  bool hasArcade = false;
  bool isLeakTest = false;
  bool isCourtyardWing = false;
};

struct Room {
  Aabb air;  // air volume: inner wall faces, floor top to ceiling underside
  int building = -1;
  int storey = 0;
  int openings = 0;       // through-openings in its walls/ceiling: doors, unglazed windows, skylights
  int glazedWindows = 0;  // window openings closed by a glass or lit-window pane (zero-thickness quad)
  bool corridor = false;
  bool sealed = false;  // openings == 0 && glazedWindows == 0: solid boxes close all six sides
};

enum class EmitterKind : uint8_t { kStreetLamp, kLitWindow };

struct Emitter {
  EmitterKind kind = EmitterKind::kStreetLamp;
  Aabb box;               // lamp: the emissive head box; window: the pane (zero extent along `normal`)
  glm::vec3 normal{0};    // lit window: outward facade normal; lamp: (0, -1, 0), its main direction
  glm::vec3 radiance{0};  // emitted radiance, scene units (= the emissive material's emission)
  float areaM2 = 0.0f;    // emitting area (lamp: all six faces; window: one side of the pane)
};

// Leak test (NVIDIA DDGI/LFP-style): a sunlit room and a sealed dark room share one thin wall.
struct LeakTestSite {
  int building = -1;
  int litRoom = -1;     // index into CellLayout::rooms; has a big unglazed facade opening and a skylight
  int sealedRoom = -1;  // index into CellLayout::rooms; Room::sealed is true
  Aabb thinWall;        // the partition between them
  float thinWallThicknessM = 0.15f;  // <= 0.2
  Aabb opening;                      // the big facade opening of the lit room (zero extent along normal)
  glm::vec3 openingNormal{0};        // outward normal of that opening (towards the street)
  Aabb skylight;                     // roof opening above the lit room, next to the thin wall
};

struct Arcade {
  int building = -1;
  Aabb walkway;  // covered air volume between the facade and the colonnade
  Aabb roof;     // the arcade roof slab (kProp)
  int pillars = 0;
  glm::vec3 outwardNormal{0};  // from the facade towards the street
};

struct Courtyard {
  Aabb yard;  // open yard: XZ inside the ring's inner facades, y from ground to the lowest wing's roof
  std::vector<int> wings;  // indices into CellLayout::buildings
};

struct ColouredWall {
  Aabb box;             // the facade's outer face extent (zero extent along normal)
  glm::vec3 albedo{0};  // saturated linear albedo
  glm::vec3 normal{0};  // outward
};

// Everything later stages need to know about a cell without parsing its mesh.
struct CellLayout {
  CellCoord cell;
  CellKind kind = CellKind::kField;
  BlockType block = BlockType::kNone;
  Aabb bounds;  // the cell's XZ range; y from the lowest terrain sample to the highest geometry
  std::vector<SolidBox> solids;
  std::vector<Building> buildings;
  std::vector<Room> rooms;
  std::vector<Emitter> emitters;
  std::vector<LeakTestSite> leakTests;
  std::vector<Arcade> arcades;
  std::vector<Courtyard> courtyards;
  std::vector<ColouredWall> colouredWalls;

  // True if p lies strictly inside (by more than `margin`) any solid box. Linear in solids.size().
  bool insideSolid(glm::vec3 p, float margin = 0.0f) const;
};

struct GeneratedCell {
  TriangleMesh mesh;
  CellLayout layout;
};

class SyntheticWorld {
 public:
  // Validates params (throws lfgi::Error); generates nothing.
  explicit SyntheticWorld(const WorldParams& params);

  const WorldParams& params() const { return params_; }
  int cellsX() const { return cells_; }
  int cellsZ() const { return cells_; }
  double cellSizeM() const { return params_.cellM; }
  bool contains(CellCoord c) const { return c.x >= 0 && c.z >= 0 && c.x < cells_ && c.z < cells_; }
  // XZ range of the cell (y = 0). Throws lfgi::Error for cells outside the world.
  Aabb cellBounds(CellCoord c) const;

  // Pure function of (seed, c); O(1). Throws lfgi::Error for cells outside the world.
  CellKind cellKind(CellCoord c) const;
  // Block layout of the cell (kNone for fields). Throws lfgi::Error for cells outside the world.
  BlockType blockType(CellCoord c) const;

  // Height of the terrain *mesh* surface at (x, z): the piecewise-linear interpolation of the global
  // lattice samples with the same triangulation as the mesh, so a point above it is above the rendered
  // terrain. Defined for any finite (x, z), also outside the world. Exactly 0 on urban cells and roads.
  float terrainHeight(float x, float z) const;
  // Lattice spacing of the terrain (metres) and lattice quads per cell edge.
  double terrainStepM() const { return params_.cellM / double(terrainQuads_); }
  int terrainQuadsPerCell() const { return terrainQuads_; }

  // True if (x, z) lies on a road strip (half-open tests, so a border point belongs to one cell).
  bool isRoad(float x, float z) const;
  // Main roads run along every mainRoadSpacingCells()-th cell border line in X and Z (not on the world
  // boundary); streets run along every edge of urban cells.
  int mainRoadSpacingCells() const { return mainSpacing_; }

  // Cells whose XZ range the edit overlaps with positive area (clipped to the world): the only cells whose
  // generation reads it, so the only ones whose content it can change (an edit that removes nothing there
  // or clips to nothing leaves a cell bit-identical).
  std::vector<CellCoord> editCells(const WorldEdit& edit) const;

  // The cell's mesh. Deterministic from (seed, edits, c); throws lfgi::Error for cells outside the world.
  TriangleMesh generateCell(CellCoord c) const;
  // The cell's descriptors alone, without building the mesh (about 2× faster); equal to generate(c).layout.
  CellLayout describeCell(CellCoord c) const;
  // Mesh and descriptors together.
  GeneratedCell generate(CellCoord c) const;

 private:
  void requireCell(CellCoord c) const;

  WorldParams params_;
  int cells_ = 0;
  int terrainQuads_ = 16;
  int mainSpacing_ = 2;
};

}  // namespace lfgi::worlds
