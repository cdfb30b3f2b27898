#include "core/shared_model.h"

#include <cmath>

#include "core/error.h"
#include "core/file_util.h"
#include "core/vdb_container.h"

namespace lfgi {

using namespace vdbfile;  // this file is one of the container's two users

namespace {

constexpr char kMagic[] = "lfgi-shared-model";
constexpr char kTrailerMagic[9] = "LFGISHRD";

std::vector<std::byte> encode(const SharedModel& model, std::span<const detail::CellFileOverride> overrides) {
  model.validate("encodeSharedModel");
  initOpenVdb();
  openvdb::MetaMap m;
  m.insertMeta("lfgi_magic", openvdb::StringMetadata(kMagic));
  m.insertMeta("lfgi_format_version", openvdb::Int32Metadata(kSharedModelVersion));
  m.insertMeta("world_seed", openvdb::StringMetadata(hex64(model.worldSeed)));
  m.insertMeta("input_hash", openvdb::StringMetadata(hex64(model.inputHash)));
  m.insertMeta("weights_hash", openvdb::StringMetadata(hex64(model.weightsHash())));
  putArch(m, model.weights.arch, model.weights.precision);
  putBlob(m, "generator_weights", encodeWeights(model.weights));
  m.insertMeta("training_steps", openvdb::Int64Metadata(model.stats.steps));
  m.insertMeta("training_seconds", openvdb::DoubleMetadata(model.stats.seconds));
  m.insertMeta("error_achieved", openvdb::DoubleMetadata(model.stats.errorAchieved));
  m.insertMeta("training_cells", openvdb::StringMetadata(model.stats.cells));
  applyOverrides(m, overrides);
  return vdbfile::seal(openvdb::GridCPtrVec{}, m, kTrailerMagic, "encodeSharedModel");
}

}  // namespace

uint64_t SharedModel::weightsHash() const {
  return weightsContentHash(dequantizeWeights(weights));
}

void SharedModel::validate(const std::string& what) const {
  try {
    weights.validate();
  } catch (const Error& e) {
    fail("{}: shared generator weights: {}", what, e.what());
  }
  if (weights.arch.latentSource != LatentSource::Stored)
    fail("{}: a shared model needs stored latents (cells fit their own)", what);
  if (stats.steps < 0) fail("{}: training steps {} < 0", what, stats.steps);
  for (double v : {stats.seconds, stats.errorAchieved})
    if (!std::isfinite(v) || v < 0.0) fail("{}: training stat {} must be finite and >= 0", what, v);
  if (stats.cells.size() > 4096)
    fail("{}: training cell list is {} characters (limit 4096)", what, stats.cells.size());
}

std::filesystem::path sharedModelPath(const std::filesystem::path& outDir) {
  return outDir / "shared_model.vdb";
}

std::vector<std::byte> encodeSharedModel(const SharedModel& model) {
  return encode(model, {});
}

std::vector<std::byte> detail::encodeSharedModelWithOverrides(const SharedModel& model,
                                                              std::span<const CellFileOverride> overrides) {
  return encode(model, overrides);
}

SharedModel decodeSharedModel(std::span<const std::byte> bytes, const std::string& name,
                              uint64_t* weightsHash) {
  const OpenedStream opened =
      vdbfile::open(bytes, name, kTrailerMagic, kSharedModelMaxBytes, "shared model file");
  if (!opened.grids->empty())
    fail("{}: {} grids, a shared model file holds none", name, opened.grids->size());
  MetaReader r(*opened.meta, name);
  const std::string magic = r.get<std::string>("lfgi_magic");
  if (magic != kMagic)
    fail("{}: lfgi_magic is '{}', expected '{}' (not a shared model file)", name, magic, kMagic);
  const int64_t version = r.get<int32_t>("lfgi_format_version");
  if (version != kSharedModelVersion)
    fail("{}: shared model format version {}, this build reads version {} (rebake the world)", name, version,
         kSharedModelVersion);
  SharedModel s;
  s.worldSeed = parseHex64(r.get<std::string>("world_seed"), name + ": world_seed");
  s.inputHash = parseHex64(r.get<std::string>("input_hash"), name + ": input_hash");
  const uint64_t stored = parseHex64(r.get<std::string>("weights_hash"), name + ": weights_hash");
  const auto [arch, precision] = readArch(r);
  try {
    s.weights = decodeWeights(r.blob("generator_weights"), arch, precision, "generator_weights");
  } catch (const Error& e) {
    fail("{}: {}", name, e.what());
  }
  s.stats.steps = int(r.getInt("training_steps", 0, int64_t(1) << 30));
  s.stats.seconds = r.getFiniteDouble("training_seconds");
  s.stats.errorAchieved = r.getFiniteDouble("error_achieved");
  s.stats.cells = r.get<std::string>("training_cells");
  s.validate(name);
  const uint64_t actual = s.weightsHash();
  if (actual != stored)
    fail("{}: weights_hash is {:016x}, the stored weights hash to {:016x}", name, stored, actual);
  if (weightsHash) *weightsHash = actual;
  return s;
}

void writeSharedModel(const std::filesystem::path& path, const SharedModel& model) {
  std::vector<std::byte> bytes;
  try {
    bytes = encodeSharedModel(model);
  } catch (const Error& e) {
    fail("{}: {}", path.string(), e.what());
  }
  writeFileAtomic(path, bytes);
}

SharedModel readSharedModel(const std::filesystem::path& path, uint64_t* weightsHash) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > kSharedModelMaxBytes)
    fail("{}: {} bytes, more than the shared model file limit {}", path.string(), size, kSharedModelMaxBytes);
  return decodeSharedModel(readFileBytes(path), path.string(), weightsHash);
}

ResolvedSharedModel loadSharedModel(const std::filesystem::path& path) {
  ResolvedSharedModel r;
  r.weights = dequantizeWeights(readSharedModel(path, &r.hash).weights);
  r.name = path.string();
  return r;
}

void checkSharedReference(const CellGenerator& g, const ResolvedSharedModel* shared,
                          const std::string& cellName) {
  if (!g.shared) return;
  if (!shared)
    fail(
        "{}: refers to shared model {:016x}, but no shared model file is loaded (the bake writes it as "
        "shared_model.vdb next to cells/)",
        cellName, g.shared->modelHash);
  if (shared->hash != g.shared->modelHash)
    fail("{}: refers to shared model {:016x}, but {} holds {:016x} (rebake the cell or restore that model)",
         cellName, g.shared->modelHash, shared->name, shared->hash);
  const GeneratorArch &a = g.weights.arch, &b = shared->weights.arch;
  if (a.latentDim != b.latentDim || a.condDim != b.condDim || a.convChannels != b.convChannels ||
      a.latentSource != b.latentSource)
    fail("{}: its architecture differs from the one of shared model {}", cellName, shared->name);
}

GeneratorWeights resolveCellWeights(const CellGenerator& g, const ResolvedSharedModel* shared,
                                    const std::string& cellName) {
  if (!g.shared) return dequantizeWeights(g.weights);
  checkSharedReference(g, shared, cellName);
  try {
    return applyAdapter(shared->weights, dequantizeAdapter(g.shared->adapter));
  } catch (const Error& e) {
    fail("{}: adapter for {}: {}", cellName, shared->name, e.what());
  }
}

}  // namespace lfgi
