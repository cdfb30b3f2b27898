// CellFile: one streaming cell's light field on disk (docs/DESIGN.md §3), an OpenVDB file that `vdb_print`
// lists, plus a trailer that protects the reader. OpenVDB is an implementation detail of cell_file.cpp;
// this header is plain C++ so the many users of core never compile OpenVDB's headers.
//
// Layout:
//   [OpenVDB stream]  file metadata  lfgi_magic "lfgi-cell", lfgi_format_version, world seed, cell (x, z),
//                                    input hash, probe grid, model (arch or "none"), output scale, bake
//                                    statistics, and binary blobs (OpenVDB metadata of the unregistered
//                                    type "lfgi_bytes", which any OpenVDB reader keeps as raw bytes):
//                                    generator weights, latents, fallback SH; fallback lighting keys
//                                    (version 2: fallback_key_count + fallback_key_hours and
//                                    fallback_key_overcast blobs of float32)
//                     grid "probes"  a MaskGrid in probe index space: active voxel (x, y, z) = probe
//                                    (x, y, z) exists; its transform is index -> world of the ProbeGrid
//   [trailer, 24 B]   "LFGICELL", u64 length of the OpenVDB stream, u64 XXH3-64 of the OpenVDB stream
//
// Why one MaskGrid + a latent blob rather than ceil(L/4) Int32 grids of packed int8 latents: the probes'
// topology is stored once (1 bit per voxel in the leaves), while every extra OpenVDB grid repeats it plus
// ~9 KB of fixed internal-node masks (a 5-4-3 tree writes 2 x 4 KB + 2 x 512 B of masks even for 8
// voxels); the latents stay packed at any bit width (4-bit latents have no natural voxel type); and the
// decoder consumes a dense [count][L] matrix (a GEMM operand) in exactly the blob's order. Latent row k
// belongs to the k-th active probe in ProbeGrid linear order (x fastest, then y, then z).
//
// Reader contract: before OpenVDB parses a byte, the file size is bounded, the trailer's magic and
// length must match and the XXH3-64 of the stream must match the trailer, so truncated or bit-flipped
// files never reach OpenVDB's parser (which trusts its input). After parsing, every field is checked
// against the others (version, counts vs the grid, blob lengths vs the architecture, finite floats,
// voxels inside the grid dims). Every failure is an lfgi::Error "<file>: <problem>". The checksum
// guards against corruption, not against a forger who recomputes it; the semantic checks still bound
// what such a file can do (sizes are capped before anything is allocated from them).
//
// Files are deterministic: the same CellFile gives the same bytes (OpenVDB's random archive UUID is
// replaced by one derived from the content).
//
// Versions: 3 (written for cells that refer to a world's shared model, core/shared_model.h) stores,
// instead of generator_weights, model "shared" with the shared model's architecture fields, its weights
// hash (shared_model_hash, 16 hex digits, nonzero), the cell's quantized FiLM adapter (adapter_stages,
// adapter_bits, adapter_channels and an "adapter" blob: 2 f32 scales, then the scale and shift codes
// packed like the latents) and the cell's latents as before. Cells with their own weights (or none) are
// still written as version 2, byte-identical to what earlier builds wrote. 4 (written for cells whose
// fallback is CellFallback::Precision::L1Int8) adds fallback_precision "l1_int8", the fallback_sh blob then
// holding 15 B per entry (3 L0 halves, 9 L1 codes); a version-4 file without the field is an error. 2 stores
// one fallback SH L1 per bake lighting key; 1 (read only) stored one, the bake's first key, and has no key
// fields: it reads as one key at 12 h, overcast 0 (its true hour is not recorded; with one key the fallback
// is the same at every time of day). Fields of a later version in an earlier version's file are errors.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "core/generator.h"
#include "core/probe_grid.h"
#include "core/quantize.h"

namespace lfgi {

inline constexpr int kCellFileVersion = 4;  // newest written; versions 1 .. kCellFileVersion are read
inline constexpr int kCellFileMaxFallbackKeys = 64;
inline constexpr int64_t kCellFileMaxProbes = int64_t(1) << 22;  // per cell (~4 M)
inline constexpr size_t kCellFileMaxBytes = size_t(1) << 30;     // 1 GiB

// SH L1 radiance (core/sh.h ShL1 order: coefficient k = l(l+1)+m, then rgb) in FP16: 12 halves per entry,
// one set of entries per lighting key of the bake (time of day, overcast). Entries per key: PerCell 1,
// PerProbe the active probe count (latent order). Layout of shHalf, key-major:
//   shHalf[(key * entries + entry) * 12 + k * 3 + rgb]
// Keys are sorted strictly ascending by (hours, overcast), hours finite in [0, 24], overcast in [0, 1],
// 1 .. kCellFileMaxFallbackKeys of them. The radiance is what the bake's captures hold at that key (sky,
// bounces and the sun / moon disc deposits, the generator's training targets), so a fallback and a
// decoded cell agree at a key. The default is one key at 12 h, overcast 0.
//
// Precision: how the file stores the entries. Fp16: the 12 halves (24 B). L1Int8 (version 4): Unity APV's
// split, L0 as 3 halves and each L1 coefficient as an int8 code of L1 / (sqrt(3) L0) (core/sh_l1_q8.h),
// 15 B per entry; shHalf then holds what the codes decode to (every entry a fixed point of
// quantizeShL1HalvesQ8; quantizeFallbackToInt8 makes one), so the file round-trips bit-exact.
struct CellFallback {
  enum class Kind : uint8_t { PerCell = 0, PerProbe = 1 };
  enum class Precision : uint8_t { Fp16 = 0, L1Int8 = 1 };
  Kind kind = Kind::PerCell;
  Precision precision = Precision::Fp16;
  std::vector<float> keyHours{12.0f};    // time of day of each key
  std::vector<float> keyOvercast{0.0f};  // weather of each key (same size as keyHours)
  std::vector<uint16_t> shHalf;          // keys x entries x 12 (layout above)

  size_t keyCount() const { return keyHours.size(); }
  // Bytes the entries take in the file (24 or 15 per entry).
  size_t storedShBytes() const;
};

// Converts the entries to the int8 layout in place (core/sh_l1_q8.h quantizeShL1HalvesQ8 on each) and
// sets precision = L1Int8.
void quantizeFallbackToInt8(CellFallback& fallback);

struct CellBakeStats {
  double errorAchieved = 0.0;    // irradiance relative RMS vs ground truth (metrics.h), >= 0
  double errorTarget = 0.0;      // what the model search aimed for, >= 0 (0: none)
  double trainingSeconds = 0.0;  // >= 0
  std::string model;             // the chosen model in words, e.g. "L16 C32-16 int8" or "no network: SH L1"
};

// The network part; absent in a "no network" cell (simple light fields: sky-only, uniform), whose
// probes decode from the fallback alone.
// Version 3: the cell's network is the world's shared model (core/shared_model.h, found by its weights
// hash) with this cell's FiLM adapter folded in (core/generator.h applyAdapter).
struct CellSharedModelRef {
  uint64_t modelHash = 0;    // SharedModel::weightsHash() of the model the cell was fitted to; nonzero
  QuantizedAdapter adapter;  // sizes checked against the cell's (= the shared model's) architecture
};

struct CellGenerator {
  // The architecture and precision always; the tensors only for a cell with its own weights (empty when
  // `shared` is set: the decoder weights come from resolveCellWeights, core/shared_model.h).
  QuantizedWeights weights;
  // LatentSource::Stored: one row per active probe (count = active probes, dim = arch.latentDim).
  // LatentSource::PositionFourier: empty (count 0). Shared-model cells always store latents.
  QuantizedLatents latents;
  std::optional<CellSharedModelRef> shared;
};

struct CellFile {
  uint64_t worldSeed = 0;
  int cellX = 0, cellZ = 0;  // streaming cell index
  uint64_t inputHash = 0;    // XXH3-64 of the bake inputs (incremental rebake compares it)
  ProbeGrid grid;
  std::vector<uint8_t> active;  // probeCount(): 1 probe exists; empty = all exist
  std::optional<CellGenerator> generator;
  GeneratorOutputScale outputScale;
  CellFallback fallback;
  CellBakeStats stats;

  int64_t activeProbeCount() const;
  // Throws lfgi::Error("<what>: ...") unless every field is valid and consistent (what the writer checks
  // before writing and the reader after reading).
  void validate(const std::string& what) const;
};

// Stored bytes by part (the numbers `lfgi inspect` prints).
struct CellFileBytes {
  size_t weights = 0;   // quantized weights + scales (0 for a shared-model cell: stored once per world)
  size_t adapter = 0;   // a shared-model cell's adapter blob (scales + codes)
  size_t latents = 0;   // quantized latents + scales
  size_t fallback = 0;  // SH halves + the keys' hours and overcast
  size_t total = 0;     // whole file
  int version = 0;      // the file's format version
  size_t metadata() const {
    return total - weights - adapter - latents - fallback;
  }  // header, topology, fields
};

// Encodes / decodes the file bytes. decodeCellFile's errors start with `name` (the path, usually).
std::vector<std::byte> encodeCellFile(const CellFile& cell);
CellFile decodeCellFile(std::span<const std::byte> bytes, const std::string& name,
                        CellFileBytes* bytesByPart = nullptr);

// Atomic write (temp file + rename); read with every check above.
void writeCellFile(const std::filesystem::path& path, const CellFile& cell);
CellFile readCellFile(const std::filesystem::path& path, CellFileBytes* bytesByPart = nullptr);

// XXH3-64 content hash for CellFile::inputHash: feed the bake inputs (mesh hash, probe grid, capture
// settings, ...) in a fixed order.
class ContentHasher {
 public:
  ContentHasher();
  ~ContentHasher();
  ContentHasher(const ContentHasher&) = delete;
  ContentHasher& operator=(const ContentHasher&) = delete;
  ContentHasher& add(std::span<const std::byte> bytes);
  ContentHasher& add(const std::string& text);  // length-prefixed, so ("ab","c") != ("a","bc")
  template <typename T>
  ContentHasher& addValue(const T& value) {
    return add(std::as_bytes(std::span<const T, 1>(&value, 1)));
  }
  uint64_t digest() const;

 private:
  void* state_;  // XXH3_state_t
};

namespace detail {
// Test seam: encodes like encodeCellFile, then replaces integer/string file metadata fields before the
// checksum is computed, to build files that are intact but semantically wrong (bad version, huge
// counts, NaN). Integer fields take `intValue`; string fields, vec3i fields ("X,Y,Z"), float/double
// fields ("nan", "inf", "-1"; empty text: the field becomes int64) and blobs (raw bytes) take `text`; an
// unknown field is added as int64. erase: the field is removed instead (e.g. a version-1 file: version 1
// and the fallback key fields erased).
struct CellFileOverride {
  std::string field;
  int64_t intValue = 0;
  std::string text;
  bool erase = false;
};
std::vector<std::byte> encodeCellFileWithOverrides(const CellFile& cell,
                                                   std::span<const CellFileOverride> overrides);
}  // namespace detail

}  // namespace lfgi
