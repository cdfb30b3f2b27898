// SharedModel: a world's shared generator on disk (docs/DESIGN.md §4 "world-shared pre-trained generator"),
// OUT/shared_model.vdb next to OUT/cells/. Cells baked with `lfgi bake --codec shared` store only their
// latents + a FiLM adapter and refer to this model by its weights hash (core/cell_file.h version 3).
//
// Layout: the cell file's container (core/vdb_container.h): an OpenVDB stream with no grids whose file
// metadata holds lfgi_magic "lfgi-shared-model", lfgi_format_version 1, world seed, input hash (of the
// pre-training inputs: resume compares it), weights_hash, the architecture fields of a cell file, the
// weights blob (int8 per output channel as core/quantize.h stores them, or FP16), and the training stats
// (steps, seconds, mean irradiance relative RMS over the pre-training cells, the cells in words); then the
// 24-byte trailer "LFGISHRD", u64 length, u64 XXH3-64. `vdb_print -m` lists it.
//
// weights_hash = weightsContentHash(dequantizeWeights(weights)): the identity of the floats every decoder
// runs, so a cell fitted against them refers to exactly them. The reader recomputes it and rejects a file
// whose stored hash disagrees. Reader contract as the cell file's: size bounded, trailer and checksum
// before OpenVDB parses, then every field checked; errors "<file>: <problem>". Writes are atomic.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "core/cell_file.h"
#include "core/generator.h"
#include "core/quantize.h"

namespace lfgi {

inline constexpr int kSharedModelVersion = 1;
inline constexpr size_t kSharedModelMaxBytes = size_t(64) << 20;

struct SharedModelStats {
  int steps = 0;               // pre-training steps, >= 0
  double seconds = 0.0;        // pre-training wall time, >= 0
  double errorAchieved = 0.0;  // mean irradiance relative RMS over the pre-training cells (float weights)
  std::string cells;           // the pre-training cells in words, e.g. "0,1 field; 2,0 city"
};

struct SharedModel {
  uint64_t worldSeed = 0;
  uint64_t inputHash = 0;    // of the pre-training inputs (cells, capture and training settings)
  QuantizedWeights weights;  // includes the architecture
  SharedModelStats stats;

  // weightsContentHash(dequantizeWeights(weights)).
  uint64_t weightsHash() const;
  // Throws lfgi::Error("<what>: ...") unless the weights are valid with stored latents and the stats
  // finite and >= 0.
  void validate(const std::string& what) const;
};

// OUT/shared_model.vdb for a bake output directory OUT (the parent of cells/).
std::filesystem::path sharedModelPath(const std::filesystem::path& outDir);

std::vector<std::byte> encodeSharedModel(const SharedModel& model);
// Errors start with `name`. weightsHash: if not null, receives the (checked) stored weights hash.
SharedModel decodeSharedModel(std::span<const std::byte> bytes, const std::string& name,
                              uint64_t* weightsHash = nullptr);
void writeSharedModel(const std::filesystem::path& path, const SharedModel& model);
SharedModel readSharedModel(const std::filesystem::path& path, uint64_t* weightsHash = nullptr);

// The float weights a generator cell decodes with: its own (dequantized), or for a shared-model cell the
// shared model's dequantized weights with the cell's adapter folded in (applyAdapter). shared: the world's
// shared model as dequantized floats with its weightsContentHash (may be null for cells with their own
// weights). Throws lfgi::Error naming cellName and sharedName when the cell needs a shared model and none
// is given, or it is another one (hash or architecture differ).
struct ResolvedSharedModel {
  GeneratorWeights weights;  // dequantized
  uint64_t hash = 0;         // weightsContentHash(weights)
  std::string name;          // where it came from (its file), for errors
};
// readSharedModel(path) dequantized, with its hash and name = path.
ResolvedSharedModel loadSharedModel(const std::filesystem::path& path);
GeneratorWeights resolveCellWeights(const CellGenerator& generator, const ResolvedSharedModel* shared,
                                    const std::string& cellName);
// resolveCellWeights' checks without the fold (no weights built): for validating many cells at once.
void checkSharedReference(const CellGenerator& generator, const ResolvedSharedModel* shared,
                          const std::string& cellName);

namespace detail {
// Test seam as detail::encodeCellFileWithOverrides (same override rules) for shared model files.
std::vector<std::byte> encodeSharedModelWithOverrides(const SharedModel& model,
                                                      std::span<const CellFileOverride> overrides);
}  // namespace detail

}  // namespace lfgi
