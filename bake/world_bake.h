// Baking one world cell into a cell file (DESIGN.md §3-4), shared by `lfgi bake`, `lfgi bake-status`,
// the Slurm scripts' tests and the incremental-rebake tests.
//
// Per cell: build the cell (probes placed as `lfgi world` places them), capture its active probes under
// the lighting keys with Embree (the cell's mesh + its 8 neighbours'), choose the smallest model that
// meets the error target (generator_training.h chooseCellModel: no network when SH L1 suffices, else the
// cheapest generator), quantize (int8 weights per channel, int8 latents), measure the quantized model's
// error. The caller writes the CellFile (core/cell_file.h writeCellFile, atomic).
//
// Input hash: everything a cell's file depends on — bake code version, world seed, cell, the mesh hash of
// the cell AND of each of its 8 neighbours (their geometry is in the capture scene, so editing a
// neighbour makes the cell stale), probe grid, flags and offsets, every bake setting. A cell whose file
// holds the same input hash is up to date.
//
// Invalidation after a world edit (worlds/world_edits.h; issue 11 incremental rebake): an edit changes
// the meshes of the cells it overlaps (SyntheticWorld::editCells; usually one), and a cell's bake reads
// geometry only through (a) its capture scene, exactly its 3 x 3 block, and (b) probe placement, which
// sees its own mesh and the 8 neighbours' solid boxes (part of their meshes). Every other input of the
// bake is the cell's own. So the stale cells are exactly the changed cells and their in-world neighbours:
// 9 for an interior cell, 6 on an edge, 4 in a corner. The rule is neighbour MESH hashes, not neighbour
// input hashes, so staleness never cascades further than one ring. It is not tightened further on
// purpose: capture.maxDistance (4 cells) exceeds the 3 x 3 block, and with bounces > 0 a path can reach
// any triangle of the block, so no sub-region of a neighbour is provably unseen; proving a change
// invisible (e.g. inside a sealed room) would need a visibility analysis of both scenes, and even an
// unseen change rebuilds the Embree BVH, so the file is only guaranteed bit-identical when the scene is.
//
// Determinism: with threads = 1 (the default) the same inputs give a bit-identical file in any process on
// any machine of the same build (capture is per-texel seeded; training is bit-identical at 1 thread).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "bake/generator_training.h"
#include "core/cell_file.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {

struct WorldBakeSettings {
  double errorTarget = 0.05;          // irradiance relative RMS per cell
  std::string keys = "8,12,17.5";     // lighting keys: HOURS[:OVERCAST],...
  int resolution = 16;                // probe map side (8, 16, 32)
  int spp = 16;
  int bounces = 4;
  int maxSteps = 1500;                // training steps per candidate model
  int threads = 1;                    // training threads (1: bit-identical across processes)
  uint64_t seed = 1;
  // Restrict the generator search to these base widths C0 (of 8, 16, 32, 64) and stored latent sizes (of
  // 4, 8, 16); empty: all (12 candidates). A km-scale path bake fixes one model (--model-widths 32
  // --model-latents 4) to train one candidate per cell instead of up to 12. Both enter the input hash.
  std::vector<int> modelWidths, modelLatents;
  // Throws lfgi::Error naming the bad setting (keys are parsed here too).
  void validate() const;
};

// "8,12,17.5:0.3" -> keys; throws lfgi::Error naming the bad item.
std::vector<LightingKeySpec> parseLightingKeys(const std::string& text);

// Capture options the bake uses for this world (capture.maxDistance = 4 cells).
CaptureOptions worldBakeCaptureOptions(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings);

// out/cells/cell_X_Z.vdb
std::filesystem::path cellFilePath(const std::filesystem::path& outDir, worlds::CellCoord c);

// Contiguous share `index` of `size` of the cells (Slurm job arrays): shares differ by at most one cell.
std::vector<worlds::CellCoord> arrayShare(const std::vector<worlds::CellCoord>& cells, int index, int size);

// A cell ready to bake: the built cell, the capture scene's mesh (cell + 8 neighbours) and the input hash.
struct CellBakeInputs {
  worlds::CellCoord cell;
  worlds::BuiltCell built;
  worlds::TriangleMesh sceneMesh;
  uint64_t neighbourMeshHashes[9] = {};  // 3 x 3 row-major (dz, dx), 0 outside the world
  uint64_t inputHash = 0;
};
CellBakeInputs prepareCellBake(const worlds::SyntheticWorld& world, worlds::CellCoord c, const WorldBakeSettings& settings);

// The input hash alone (builds the cell, generates the neighbours' meshes: cheaper than a bake, not free).
uint64_t cellInputHash(const worlds::SyntheticWorld& world, worlds::CellCoord c, const WorldBakeSettings& settings);

struct CellBakeReport {
  size_t probes = 0;          // active probes captured
  bool network = false;       // a generator was stored
  double captureSeconds = 0.0, trainingSeconds = 0.0, totalSeconds = 0.0;
};

// Bakes the prepared cell (Embree capture + model choice + quantization). Throws lfgi::Error when the
// capture or training is interrupted (InterruptGuard) or fails.
CellFile bakeCell(const worlds::SyntheticWorld& world, CellBakeInputs inputs, const WorldBakeSettings& settings,
                  CellBakeReport* report = nullptr);

// State of a cell's file against its current input hash.
enum class CellBakeState : uint8_t { Done, Stale, Missing, Corrupt };
CellBakeState cellBakeState(const std::filesystem::path& file, uint64_t inputHash, std::string* error = nullptr);

}  // namespace lfgi::bake
