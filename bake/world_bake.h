// Baking one world cell into a cell file (docs/DESIGN.md §3-4), shared by `lfgi bake`, `lfgi bake-status`,
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
// Invalidation after a world edit (worlds/world_edits.h; incremental rebake): an edit changes
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
#include <span>
#include <string>
#include <vector>

#include "bake/generator_training.h"
#include "core/cell_file.h"
#include "core/shared_model.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {

struct WorldBakeSettings {
  double errorTarget = 0.05;       // irradiance relative RMS per cell
  std::string keys = "8,12,17.5";  // lighting keys: HOURS[:OVERCAST],...
  int resolution = 16;             // probe map side (8, 16, 32)
  int spp = 16;
  int bounces = 4;
  int maxSteps = 1500;  // training steps per candidate model
  int threads = 1;      // training threads (1: bit-identical across processes)
  uint64_t seed = 1;
  // Restrict the generator search to these base widths C0 (of 8, 16, 32, 64) and stored latent sizes (of
  // 4, 8, 16); empty: all (12 candidates). A km-scale path bake fixes one model (--model-widths 32
  // --model-latents 4) to train one candidate per cell instead of up to 12. Both enter the input hash.
  std::vector<int> modelWidths, modelLatents;
  // Codec: "per-cell" (each cell's own smallest model, its weights in its file) or "shared" (one
  // generator pre-trained per world on a sample of its cells, OUT/shared_model.vdb; each cell stores
  // latents + a FiLM adapter fitted against it, cell file version 3). Enters the input hash (with the
  // shared model's weights hash), so switching codec rebakes.
  std::string codec = "per-cell";
  int sharedSteps = 3000;  // --codec shared: pre-training steps of the shared model
  bool sharedCodec() const { return codec == "shared"; }
  // Throws lfgi::Error naming the bad setting (keys are parsed here too).
  void validate() const;
};

// "8,12,17.5:0.3" -> keys; throws lfgi::Error naming the bad item.
std::vector<LightingKeySpec> parseLightingKeys(const std::string& text);

// Capture options the bake uses for these settings, a miss recorded at maxDistance (m).
CaptureOptions bakeCaptureOptions(const WorldBakeSettings& settings, float maxDistance);
// Capture options the bake uses for this world (capture.maxDistance = 4 cells).
CaptureOptions worldBakeCaptureOptions(const worlds::SyntheticWorld& world,
                                       const WorldBakeSettings& settings);

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
// sharedModelHash: with settings.codec "shared", the weights hash of the world's shared model (it enters
// the input hash; 0 when there is none yet, a hash no baked cell holds).
CellBakeInputs prepareCellBake(const worlds::SyntheticWorld& world, worlds::CellCoord c,
                               const WorldBakeSettings& settings, uint64_t sharedModelHash = 0);

// The input hash alone (builds the cell, generates the neighbours' meshes: cheaper than a bake, not free).
uint64_t cellInputHash(const worlds::SyntheticWorld& world, worlds::CellCoord c,
                       const WorldBakeSettings& settings, uint64_t sharedModelHash = 0);

struct CellBakeReport {
  size_t probes = 0;     // active probes captured
  bool network = false;  // a generator was stored
  double captureSeconds = 0.0, trainingSeconds = 0.0, totalSeconds = 0.0;
};

// Bakes the prepared cell (Embree capture + model choice + quantization). Throws lfgi::Error when the
// capture or training is interrupted (InterruptGuard) or fails. With settings.codec "shared", `shared` is
// the world's shared model (ensureSharedModel, dequantized): a cell that needs a network fits latents +
// a 1-stage FiLM adapter against it (fitCellToSharedGenerator, --max-steps, stopping at the error target,
// int8 latents and adapter quantized in the loop) and refers to it (cell file version 3); a simple cell
// still stores no network (chooseNoNetworkModel).
CellFile bakeCell(const worlds::SyntheticWorld& world, CellBakeInputs inputs,
                  const WorldBakeSettings& settings, CellBakeReport* report = nullptr,
                  const ResolvedSharedModel* shared = nullptr);

// The codec stage of bakeCell on a captured training set (probeFlags: worlds::ProbeFlag per training
// probe): the model choice (chooseCellModel at settings' error target and steps, or the shared model's fit)
// and its int8 quantization into cf's fallback, stats and generator. report: network and trainingSeconds
// are set. Throws as bakeCell does. The leak tests run the bake's codec through it on scenes that are not
// world cells.
void encodeCellCodec(worlds::CellCoord c, const GeneratorTrainingSet& set,
                     std::span<const uint8_t> probeFlags, const WorldBakeSettings& settings,
                     const ResolvedSharedModel* shared, CellFile& cf, CellBakeReport* report = nullptr);

// ---- the shared codec's world model (core/shared_model.h) ---------------------------------------------
// Pre-training cells: one of each kind (field, suburb, city, park) that has active probes, the first of
// its kind in the world's cells ordered by a hash of (seed, x, z): deterministic for a seed, spread over
// the world. The shared model's input hash covers them (their per-cell input hashes: meshes, probes,
// capture settings) plus the architecture and training settings.
std::vector<worlds::CellCoord> sharedModelCells(const worlds::SyntheticWorld& world,
                                                const WorldBakeSettings& settings);
uint64_t sharedModelInputHash(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings);
// The shared generator's architecture: C0 = the first --model-widths (default 32) halving per stage, z =
// the first --model-latents (default 8), depth from the resolution.
GeneratorArch sharedModelArch(const WorldBakeSettings& settings);

// The world's shared model at sharedModelPath(outDir): reused when the file reads and its input hash
// matches, else pre-trained (captures of sharedModelCells, pretrainSharedGenerator for
// settings.sharedSteps steps with a checkpoint at OUT/shared_model.ckpt that an interrupted run resumes
// from), quantized int8 per channel and written atomically. Progress on stderr. Throws lfgi::Error when
// interrupted (the checkpoint stays) or when training fails. reused: set to whether the file was reused.
SharedModel ensureSharedModel(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings,
                              const std::filesystem::path& outDir, bool* reused = nullptr);
// The weights hash of the world's current shared model: the file's when it reads and its input hash
// matches these settings, else 0 (no model yet: every shared-codec cell is stale). 0 for the per-cell codec.
uint64_t currentSharedModelHash(const worlds::SyntheticWorld& world, const WorldBakeSettings& settings,
                                const std::filesystem::path& outDir);

// State of a cell's file against its current input hash.
enum class CellBakeState : uint8_t { Done, Stale, Missing, Corrupt };
CellBakeState cellBakeState(const std::filesystem::path& file, uint64_t inputHash,
                            std::string* error = nullptr);

}  // namespace lfgi::bake
