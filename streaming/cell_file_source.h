// CellFileSource: the streaming manager's cells from a baked world (`lfgi bake`: WORLD/baked/cells/
// cell_X_Z.vdb, core/cell_file.h, packed into WORLD/baked/regions/, core/region_file.h) instead of an
// analytic field. The cells are read through a core/cell_store.h CellStore (options.storage: the regions
// when they exist, else the cell files); "cell file" below means the cell as stored either way, and
// errors name the file (and, in a region, the cell).
//
// Construction (game thread, once): the layout comes from the world manifest (worlds::readWorldManifest:
// cells of cellM metres from (0, 0)). Every cell file is read once through readCellFile (its checksum
// covers the whole stream, so a trusted fallback needs the whole file read; the weights are dropped at
// once) to keep only what must stay resident or sizes the slots: the cell's SH L1 fallback per lighting
// key at the source's weather (the per-cell entry, or the mean of the per-probe entries, as floats), its
// probe count and model resolution. A file must also
// name its own cell, the world's seed and a probe grid inside the cell's square, else it counts as
// corrupt. A cell with no file or a corrupt one is logged and gets the mean fallback of its nearest ring
// of valid cells (8 neighbours first, then wider rings), per key: a smooth guess, never a hole. No valid cell
// at all is an lfgi::Error naming the directory.
//
// load() (IO threads, concurrently): readCellFile again (every check: a file corrupted or deleted after
// construction throws lfgi::Error naming the file, the manager logs it and keeps the fallback) then a
// decode into the slot's ProbeField (decodeCellField below), reusing the slot's arrays (no allocation
// once a slot has held a cell of this size; reading and dequantizing a file still allocates).
//
// Decoder (options.decoder, streaming/generator_backend.h): the generator network runs on the CPU
// (GeneratorCpu) or on the Vulkan device (gpu::GeneratorDecodePass in batches, device buffers reused);
// Auto times both once at construction on the first generator cell's own model and latents and keeps the
// faster (selection() says which, and both rates). The post-processing after the network is one code path
// for both. Threading with the GPU backend: the source owns its gpu::Context (created at construction, so
// a missing device is known before the flight) and GPU decodes from several IO threads are serialised by
// the backend's mutex (one cell at a time on the device; reads and checks still run concurrently); nothing
// else may use that context.
//
// Lighting: generator cells decode under the conditioning of the time of day the manager last set
// (setTimeOfDay, called by StreamingManager::update) and options.weather; relight() re-decodes a resident
// cell when the time of day has moved. The fallback follows the time of day: core/cell_file.h (version 2)
// stores one SH L1 per bake lighting key; fallback(cell) interpolates linearly between the two keys
// bracketing the time of day last set (clamped outside the keys' range) among the keys at the overcast
// nearest to options.weather (the generator's conditioning weather; FrameInput::weather does not reach
// the fallback). Cells without a network decode from the same interpolated SH, so they follow the time
// of day too when their file has more than one key (and relight like generator cells). A version-1 file
// (one key) gives the same fallback at every time of day.
#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <memory>
#include <mutex>
#include <optional>

#include "core/cell_fallback.h"
#include "core/cell_file.h"
#include "core/cell_store.h"
#include "core/shared_model.h"
#include "streaming/cell_source.h"
#include "streaming/generator_backend.h"
#include "worlds/world_cells.h"

namespace lfgi::streaming {

// Where the cells come from (core/cell_store.h): Auto reads regions when regionsDir holds regions.json
// (what `lfgi bake` packs after baking), else the cell files.
enum class CellStorage : uint8_t { Auto, CellFiles, Regions };

struct CellFileSourceOptions {
  std::filesystem::path worldDir;  // holds world.json (the layout)
  // Instead of worldDir: a world served over HTTP (streaming/http_region_source.h): URL/world.json,
  // URL/baked/regions/ (regions only) and URL/baked/shared_model.vdb for a shared-codec world.
  std::string worldUrl;
  std::filesystem::path cellsDir;    // empty: worldDir / "baked" / "cells"
  std::filesystem::path regionsDir;  // empty: cellsDir's parent / "regions"
  CellStorage storage = CellStorage::Auto;
  // The world's shared model (core/shared_model.h) that version-3 cells refer to; empty: cellsDir's
  // parent / "shared_model.vdb" (where `lfgi bake --codec shared` writes it).
  std::filesystem::path sharedModel;
  int irradianceResolution = 0;  // m of the decoded irradiance maps; 0: max(2, n / 2)
  int shOnlyResolution = 0;      // n for cells without a network; 0: the largest generator n, else 8
  float weather = 0.0f;          // generator conditioning, [0, 1]
  // Generator decode backend. Gpu without a Vulkan device: the constructor throws lfgi::Error; Auto: logs
  // why and decodes on the CPU.
  DecoderChoice decoder = DecoderChoice::Cpu;
  GpuBackendOptions gpu;
  // Throws lfgi::Error naming the bad field.
  void validate() const;
};

enum class CellFileState : uint8_t { Valid, Missing, Corrupt };

struct CellFileInfo {
  CellFileState state = CellFileState::Missing;
  std::string error;     // Missing / Corrupt: why
  bool network = false;  // a generator is stored
  int64_t probes = 0;    // grid probe count
  ProbeGrid grid;        // the cell's probe lattice (Valid cells)
  int64_t activeProbes = 0;
  int resolution = 0;     // n the decoded field will have
  int fallbackKeys = 0;   // lighting keys of the fallback at the source's weather (Valid cells)
  size_t fieldBytes = 0;  // ProbeField::bytes() of the decoded cell
};

class CellFileSource final : public CellSource {
 public:
  // Throws lfgi::Error for a bad manifest or options, or when no cell file is readable.
  explicit CellFileSource(CellFileSourceOptions options);

  WorldLayout layout() const override { return layout_; }
  // The world's manifest (world.json, from the directory or the URL), read at construction.
  const worlds::WorldParams& world() const { return world_; }
  // The cell's fallback at the time of day last set (setTimeOfDay): per-key SH floats precomputed at
  // construction, interpolated here (a key scan and a lerp; no allocation). Game thread.
  ShL1 fallback(glm::ivec2 cell) const override;
  bool fallbackFollowsTimeOfDay() const override { return fallbackFollowsTimeOfDay_; }
  size_t maxCellBytes() const override { return maxCellBytes_; }
  void load(glm::ivec2 cell, ProbeField& out) override;
  void setTimeOfDay(float hours) override { timeOfDay_.store(hours); }
  // StreamingManager's relight (IO threads, or the game thread with ioThreads = 0): a generator cell is
  // re-read (every check) and decoded under timeOfDayHours into `out` (the manager's staging field), and
  // so is an SH-only cell with several fallback keys; a cell that does not depend on the time of day (no
  // network, one key): `out` = `current`. Throws lfgi::Error
  // naming the file (the manager logs it and keeps the old lighting).
  void relightInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                   float timeOfDayHours) override;
  // Synchronous in-place relight (tests, tools): a generator cell (or an SH-only one with several
  // fallback keys) is re-read and re-decoded under the new time of day into `field` (same size: no
  // allocation); a cell that does not depend on it is left as is. A file that fails now is logged and the
  // field kept (returns false). The re-read is IO inside the relight stage: caching the quantized model
  // of resident cells would remove it.
  bool relight(glm::ivec2 cell, ProbeField& field, float timeOfDayHours);

  // Names the cell's storage in messages: its cell file, or "<region file>: cell (x, z)".
  std::string where(glm::ivec2 cell) const;
  // The storage read (cell files or regions) and its directory.
  const CellStore& store() const { return *store_; }
  const CellFileInfo& info(glm::ivec2 cell) const { return info_[size_t(layout_.linear(cell))]; }
  int validCells() const { return validCells_; }
  int missingCells() const { return missingCells_; }
  int corruptCells() const { return corruptCells_; }
  // Totals over every load() so far (any thread): file read + checks, and decode.
  uint64_t loads() const { return loads_.load(); }
  double readMsTotal() const { return double(readUs_.load()) * 1e-3; }
  double decodeMsTotal() const { return double(decodeUs_.load()) * 1e-3; }
  // The decoder in use and, for Auto, both measured rates.
  const DecoderSelection& selection() const { return selection_; }
  // The GPU backend when the source decodes on the device (validation counts, device name), else null.
  GpuGeneratorBackend* gpuBackend() const { return gpuBackend_; }
  // One entry per successful decode (load / relightInto / relight) so far, in completion order (any thread).
  struct DecodeSample {
    float ms = 0.0f;     // decode time (after the file read), network + post-processing
    int64_t probes = 0;  // active probes through the network (0: SH-only cell)
  };
  std::vector<DecodeSample> decodeSamples() const;

 private:
  // Reads + validates cell's file and decodes it at timeOfDayHours into out (load and relightInto).
  void readAndDecode(glm::ivec2 cell, float timeOfDayHours, ProbeField& out);
  void recordDecode(std::chrono::steady_clock::time_point t0, const CellFile& file);
  bool dependsOnTimeOfDay(glm::ivec2 cell) const;
  // The shared model a shared-model cell decodes with (null for other cells); loaded once (std::call_once) on
  // first use, normally during construction, and immutable afterwards. Throws lfgi::Error naming the cell
  // file and the shared model file when it is missing or unreadable (a wrong hash is resolveCellWeights'
  // error).
  const ResolvedSharedModel* sharedFor(const CellFile& file, const std::string& path);
  ShL1 keyFallback(glm::ivec2 cell, float timeOfDayHours) const;
  // Stages of construction, in order.
  worlds::WorldParams readManifest() const;
  void openStore();
  std::string worldUrl(const std::string& file) const;
  int scanCellFiles(int cells, std::optional<GeneratorWeights>& probeWeights,
                    std::vector<float>& probeLatents);
  void sizeSlots(int maxGeneratorN);
  void fillMissingFallbacks(int cells);
  void chooseDecoder(const std::optional<GeneratorWeights>& probeWeights,
                     const std::vector<float>& probeLatents);

  CellFileSourceOptions options_;
  std::unique_ptr<CellStore> store_;
  worlds::WorldParams world_;
  WorldLayout layout_;
  uint64_t worldSeed_ = 0;
  // Fallback keys of every cell: cell i's are keyHours_ / keySh_ [first, first + count) of keyRange_[i],
  // ascending hours (a cell without a usable file: its ring's union of hours).
  std::vector<float> keyHours_;
  std::vector<ShL1> keySh_;
  std::vector<std::pair<uint32_t, uint32_t>> keyRange_;
  bool fallbackFollowsTimeOfDay_ = false;
  std::vector<CellFileInfo> info_;
  size_t maxCellBytes_ = 0;
  int validCells_ = 0, missingCells_ = 0, corruptCells_ = 0;
  std::atomic<float> timeOfDay_{12.0f};
  std::atomic<uint64_t> loads_{0}, readUs_{0}, decodeUs_{0};
  std::once_flag sharedOnce_;
  std::optional<ResolvedSharedModel> shared_;
  std::string sharedError_;
  std::unique_ptr<GeneratorBackend> backend_;
  GpuGeneratorBackend* gpuBackend_ = nullptr;  // backend_ when it is the GPU one
  DecoderSelection selection_;
  mutable std::mutex samplesMutex_;
  std::vector<DecodeSample> samples_;
};

// The keys cellFileFallback interpolates at `weather`: their hours (ascending) and cell SH.
void cellFileFallbackKeys(const CellFile& cell, float weather, std::vector<float>& hours,
                          std::vector<ShL1>& sh);
// Linear interpolation between the keys (hours ascending) bracketing timeOfDayHours, clamped outside.
ShL1 interpolateFallback(std::span<const float> hours, std::span<const ShL1> sh, float timeOfDayHours);

// The resolution n a decoded cell has: the generator's output resolution, else shOnlyResolution.
int decodedResolution(const CellFile& cell, int shOnlyResolution);

// Decodes a read cell file into `out` (grid, resolutions, active, radiance, distance, irradiance; no
// normal / albedo / offsets), reusing out's capacity:
//   generator cells: the active probes (latent order) through the network (backend) with
//     conditioningVector(timeOfDayHours, weather), then decodeChannels (core/generator.h); position latents
//     from the probe's lattice position (the cell file keeps no relocation offsets, so a relocated probe's
//     latent differs from the bake's by its offset); irradiance = convolveIrradiance of the decoded radiance;
//   cells without a network, and the inactive probes of any cell: the probe's SH L1 (its per-probe
//     entry, else the cell's) at timeOfDayHours and weather (the keys blended as cellFileFallback) evaluated:
//     radiance max(0, shEvaluate) at texel centres, irradiance shIrradiance at texel-centre normals, distance
//     moments (range, range^2) (nothing occludes).
// Throws lfgi::Error (starting with `name`) if the model cannot decode to a probe field.
// backend: the generator network's backend (null: CpuGeneratorBackend); everything else is the same code
// for every backend.
// shared: the world's shared model for a shared-model (version 3) cell, whose weights are the shared
// model's with the cell's adapter folded in (core/shared_model.h resolveCellWeights: a missing or other
// model is an lfgi::Error naming the cell and the model file); null for other cells.
void decodeCellField(const CellFile& cell, float timeOfDayHours, float weather, int irradianceResolution,
                     int shOnlyResolution, ProbeField& out, const std::string& name = "cell",
                     GeneratorBackend* backend = nullptr, const ResolvedSharedModel* shared = nullptr);

// The network inputs of a generator cell's active probes in latent order (active: the probe flags, empty =
// all): its stored latents dequantized, or position latents at the probes' lattice points (see above).
// Throws lfgi::Error (starting with `name`) for a cell without a generator or a latent count that
// disagrees with the active probes.
void cellLatents(const CellFile& cell, std::span<const uint8_t> active, std::vector<float>& latents,
                 const std::string& name = "cell");

// field.irradiance from field.radiance for probes [first, first + count): the texel sum of
// bruteForceIrradiance (core/sh.h: E(n) = sum L(w) max(0, n.w) omega, exact texel solid angles), with the
// m^2 x n^2 kernel precomputed once per (n, m) in float. Same values as core's deriveIrradiance up to
// float rounding; field.irradiance must already have its full size.
void convolveIrradiance(ProbeField& field, int64_t first, int64_t count);

}  // namespace lfgi::streaming
