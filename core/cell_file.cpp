#include "core/cell_file.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include "core/cell_file_meta.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/sh_l1_q8.h"
#include "core/vdb_container.h"

namespace lfgi {

using namespace vdbfile;  // this file is one of the container's two users

namespace {

constexpr char kMagic[] = "lfgi-cell";
constexpr char kTrailerMagic[9] = "LFGICELL";
constexpr char kGridName[] = "probes";
constexpr size_t kShHalves = 12;  // SH L1: 4 coefficients x rgb
// Written for cells that refer to a world's shared model; other cells are still written as version 2
// (byte-identical to before, so readers of version 2 keep reading them).
constexpr int kSharedRefVersion = 3;
// Written for cells whose fallback is stored in the int8 layout (CellFallback::Precision::L1Int8).
constexpr int kInt8FallbackVersion = 4;

int writtenVersion(const CellFile& cell) {
  if (cell.fallback.precision == CellFallback::Precision::L1Int8) return kInt8FallbackVersion;
  return cell.generator && cell.generator->shared ? kSharedRefVersion : 2;
}

// fallback_sh: the halves as is (Fp16) or 15 B per entry (L1Int8, core/sh_l1_q8.h).
std::vector<uint8_t> encodeFallbackSh(const CellFallback& f) {
  std::vector<uint8_t> out;
  if (f.precision == CellFallback::Precision::Fp16) {
    appendPod<uint16_t>(out, f.shHalf);
    return out;
  }
  const size_t entries = f.shHalf.size() / kShHalves;
  out.resize(entries * kShL1Q8Bytes);
  for (size_t e = 0; e < entries; ++e)
    packShL1Q8(f.shHalf.data() + e * kShHalves, out.data() + e * kShL1Q8Bytes);
  return out;
}

std::vector<uint8_t> encodeLatents(const QuantizedLatents& l) {
  std::vector<uint8_t> out;
  appendPod<float>(out, l.scales);
  appendCodes(out, l.codes, l.bits);
  return out;
}

QuantizedLatents decodeLatents(const std::vector<uint8_t>& blob, int dim, int bits, int64_t count,
                               const std::string& what) {
  QuantizedLatents l;
  l.dim = dim;
  l.bits = bits;
  l.count = count;
  BlobReader r(blob, what);
  l.scales = r.read<float>(size_t(dim));
  l.codes = readCodes(r, size_t(count) * size_t(dim), bits);
  r.finish();
  l.validate(what);
  return l;
}

// Adapter blob: its scales (2 x f32, none with 0 channels), then 2 x channels codes packed at its bits.
std::vector<uint8_t> encodeAdapter(const QuantizedAdapter& a) {
  std::vector<uint8_t> out;
  appendPod<float>(out, a.scales);
  appendCodes(out, a.codes, a.bits);
  return out;
}

QuantizedAdapter decodeAdapter(const std::vector<uint8_t>& blob, const GeneratorArch& arch, int stages,
                               int bits, int64_t channels, const std::string& what) {
  QuantizedAdapter a;
  a.stages = stages;
  a.bits = bits;
  a.channels = channels;
  a.validateHeader(arch, what);
  BlobReader r(blob, what);
  a.scales = r.read<float>(channels > 0 ? 2 : 0);
  a.codes = readCodes(r, size_t(2 * channels), bits);
  r.finish();
  a.validate(arch, what);
  return a;
}

openvdb::Vec3s toVdb(glm::vec3 v) {
  return {v.x, v.y, v.z};
}

// ---- encode ---------------------------------------------------------------------------------------------

}  // namespace

openvdb::MetaMap cellmeta::fields(const CellFile& cell, std::span<const detail::CellFileOverride> overrides) {
  cell.validate("encodeCellFile");
  initOpenVdb();
  openvdb::MetaMap m;
  m.insertMeta("lfgi_magic", openvdb::StringMetadata(kMagic));
  const bool sharedRef = cell.generator && cell.generator->shared;
  m.insertMeta("lfgi_format_version", openvdb::Int32Metadata(writtenVersion(cell)));
  m.insertMeta("world_seed", openvdb::StringMetadata(hex64(cell.worldSeed)));
  m.insertMeta("cell_x", openvdb::Int32Metadata(cell.cellX));
  m.insertMeta("cell_z", openvdb::Int32Metadata(cell.cellZ));
  m.insertMeta("input_hash", openvdb::StringMetadata(hex64(cell.inputHash)));
  m.insertMeta("probe_origin", openvdb::Vec3SMetadata(toVdb(cell.grid.origin)));
  m.insertMeta("probe_spacing", openvdb::Vec3SMetadata(toVdb(cell.grid.spacing)));
  m.insertMeta("probe_dims",
               openvdb::Vec3IMetadata(openvdb::Vec3i(cell.grid.dims.x, cell.grid.dims.y, cell.grid.dims.z)));
  const int64_t active = cell.activeProbeCount();
  m.insertMeta("probe_count", openvdb::Int64Metadata(active));
  m.insertMeta("exposure", openvdb::FloatMetadata(cell.outputScale.exposure));
  m.insertMeta("range", openvdb::FloatMetadata(cell.outputScale.range));
  if (cell.generator) {
    const CellGenerator& g = *cell.generator;
    const GeneratorArch& a = g.weights.arch;
    m.insertMeta("model", openvdb::StringMetadata(sharedRef ? "shared" : "network"));
    putArch(m, a, g.weights.precision);
    if (sharedRef) {  // version 3: the world's shared model + this cell's adapter
      const QuantizedAdapter& ad = g.shared->adapter;
      m.insertMeta("shared_model_hash", openvdb::StringMetadata(hex64(g.shared->modelHash)));
      m.insertMeta("adapter_stages", openvdb::Int32Metadata(ad.stages));
      m.insertMeta("adapter_bits", openvdb::Int32Metadata(ad.bits));
      m.insertMeta("adapter_channels", openvdb::Int64Metadata(ad.channels));
      putBlob(m, "adapter", encodeAdapter(ad));
    } else {
      putBlob(m, "generator_weights", encodeWeights(g.weights));
    }
    if (a.latentSource == LatentSource::Stored) {
      m.insertMeta("latent_bits", openvdb::Int32Metadata(g.latents.bits));
      m.insertMeta("latent_count", openvdb::Int64Metadata(g.latents.count));
      putBlob(m, "latents", encodeLatents(g.latents));
    }
  } else {
    m.insertMeta("model", openvdb::StringMetadata("none"));
  }
  m.insertMeta("fallback_kind", openvdb::StringMetadata(cell.fallback.kind == CellFallback::Kind::PerCell
                                                            ? "sh_l1_per_cell"
                                                            : "sh_l1_per_probe"));
  if (cell.fallback.precision == CellFallback::Precision::L1Int8)
    m.insertMeta("fallback_precision", openvdb::StringMetadata("l1_int8"));
  {
    std::vector<uint8_t> hours, overcast;
    putBlob(m, "fallback_sh", encodeFallbackSh(cell.fallback));
    m.insertMeta("fallback_key_count", openvdb::Int32Metadata(int32_t(cell.fallback.keyCount())));
    appendPod<float>(hours, cell.fallback.keyHours);
    putBlob(m, "fallback_key_hours", std::move(hours));
    appendPod<float>(overcast, cell.fallback.keyOvercast);
    putBlob(m, "fallback_key_overcast", std::move(overcast));
  }
  m.insertMeta("error_achieved", openvdb::DoubleMetadata(cell.stats.errorAchieved));
  m.insertMeta("error_target", openvdb::DoubleMetadata(cell.stats.errorTarget));
  m.insertMeta("training_seconds", openvdb::DoubleMetadata(cell.stats.trainingSeconds));
  m.insertMeta("bake_model", openvdb::StringMetadata(cell.stats.model));

  applyOverrides(m, overrides);
  return m;
}

namespace {

std::vector<std::byte> encode(const CellFile& cell, std::span<const detail::CellFileOverride> overrides) {
  const openvdb::MetaMap m = cellmeta::fields(cell, overrides);
  openvdb::MaskGrid::Ptr grid = openvdb::MaskGrid::create();
  grid->setName(kGridName);
  {
    openvdb::math::Mat4d xf = openvdb::math::Mat4d::identity();
    xf.setToScale(openvdb::Vec3d(cell.grid.spacing.x, cell.grid.spacing.y, cell.grid.spacing.z));
    xf.setTranslation(openvdb::Vec3d(cell.grid.origin.x, cell.grid.origin.y, cell.grid.origin.z));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(xf));
    auto acc = grid->getAccessor();
    for (int64_t i = 0; i < cell.grid.probeCount(); ++i) {
      if (!cell.active.empty() && cell.active[size_t(i)] == 0) continue;
      glm::ivec3 c = cell.grid.probeCoord(i);
      acc.setValueOn(openvdb::Coord(c.x, c.y, c.z));
    }
  }

  return vdbfile::seal(openvdb::GridCPtrVec{grid}, m, kTrailerMagic, "encodeCellFile");
}

}  // namespace

// ---- CellFile -------------------------------------------------------------------------------------------

int64_t CellFile::activeProbeCount() const {
  if (active.empty()) return grid.probeCount();
  return int64_t(std::count_if(active.begin(), active.end(), [](uint8_t a) { return a != 0; }));
}

void CellFile::validate(const std::string& what) const {
  try {
    grid.validate();
  } catch (const Error& e) {
    fail("{}: probe grid: {}", what, e.what());
  }
  if (grid.probeCount() > kCellFileMaxProbes)
    fail("{}: probe grid {}x{}x{} has {} probes, more than the cell limit {}", what, grid.dims.x, grid.dims.y,
         grid.dims.z, grid.probeCount(), kCellFileMaxProbes);
  if (!active.empty() && int64_t(active.size()) != grid.probeCount())
    fail("{}: active mask holds {} entries for {} probes", what, active.size(), grid.probeCount());
  const int64_t n = activeProbeCount();
  if (!std::isfinite(outputScale.exposure) || outputScale.exposure <= 0.0f)
    fail("{}: exposure {} must be finite and > 0", what, outputScale.exposure);
  if (!std::isfinite(outputScale.range) || outputScale.range <= 0.0f)
    fail("{}: range {} must be finite and > 0", what, outputScale.range);
  if (generator) {
    const GeneratorArch& a = generator->weights.arch;
    if (generator->shared) {
      try {
        a.validate();
      } catch (const Error& e) {
        fail("{}: shared model architecture: {}", what, e.what());
      }
      if (generator->shared->modelHash == 0) fail("{}: shared model hash is 0 (no model has it)", what);
      if (!generator->weights.tensors.empty())
        fail("{}: a cell that refers to a shared model holds {} weight tensors of its own", what,
             generator->weights.tensors.size());
      if (a.latentSource != LatentSource::Stored) fail("{}: a shared-model cell needs stored latents", what);
      generator->shared->adapter.validate(a, what + ": adapter");
    } else {
      try {
        generator->weights.validate();
      } catch (const Error& e) {
        fail("{}: generator weights: {}", what, e.what());
      }
    }
    const QuantizedLatents& l = generator->latents;
    if (a.latentSource == LatentSource::Stored) {
      l.validate(what + ": latents");
      if (l.count != n) fail("{}: {} latents for {} active probes", what, l.count, n);
      if (l.dim != a.latentDim)
        fail("{}: latents have {} dimensions, the generator takes {}", what, l.dim, a.latentDim);
    } else if (l.count != 0 || !l.codes.empty() || !l.scales.empty()) {
      fail("{}: a position-derived latent model stores no latents, this one holds {}", what, l.count);
    }
  }
  size_t entries = fallback.kind == CellFallback::Kind::PerCell ? 1 : size_t(n);
  if (fallback.kind != CellFallback::Kind::PerCell && fallback.kind != CellFallback::Kind::PerProbe)
    fail("{}: unknown fallback kind {}", what, int(fallback.kind));
  const size_t keys = fallback.keyCount();
  if (keys < 1 || keys > size_t(kCellFileMaxFallbackKeys))
    fail("{}: {} fallback lighting keys (1 to {} allowed)", what, keys, kCellFileMaxFallbackKeys);
  if (fallback.keyOvercast.size() != keys)
    fail("{}: {} fallback key overcast values for {} key hours", what, fallback.keyOvercast.size(), keys);
  for (size_t k = 0; k < keys; ++k) {
    const float h = fallback.keyHours[k], w = fallback.keyOvercast[k];
    if (!(std::isfinite(h) && h >= 0.0f && h <= 24.0f))
      fail("{}: fallback key {} hours = {} (must be finite, in [0, 24])", what, k, h);
    if (!(std::isfinite(w) && w >= 0.0f && w <= 1.0f))
      fail("{}: fallback key {} overcast = {} (must be finite, in [0, 1])", what, k, w);
    if (k > 0) {
      const float ph = fallback.keyHours[k - 1], pw = fallback.keyOvercast[k - 1];
      if (!(ph < h || (ph == h && pw < w)))
        fail(
            "{}: fallback keys not sorted strictly ascending by (hours, overcast): key {} ({} h, overcast "
            "{}) after "
            "key {} ({} h, overcast {})",
            what, k, h, w, k - 1, ph, pw);
    }
  }
  if (fallback.shHalf.size() != keys * entries * kShHalves)
    fail("{}: fallback holds {} halves, {} expected ({} keys x {} x 12)", what, fallback.shHalf.size(),
         keys * entries * kShHalves, keys, entries);
  for (size_t i = 0; i < fallback.shHalf.size(); ++i)
    if ((fallback.shHalf[i] & 0x7c00u) == 0x7c00u) fail("{}: fallback SH half {} is Inf or NaN", what, i);
  if (fallback.precision == CellFallback::Precision::L1Int8) {
    for (size_t e = 0; e < keys * entries; ++e)
      if (!shL1HalvesAreQ8(fallback.shHalf.data() + e * kShHalves))
        fail("{}: fallback entry {} is not in the int8 layout (quantizeFallbackToInt8)", what, e);
  } else if (fallback.precision != CellFallback::Precision::Fp16) {
    fail("{}: unknown fallback precision {}", what, int(fallback.precision));
  }
  auto nonNegative = [&](double v, const char* field) {
    if (!std::isfinite(v) || v < 0.0) fail("{}: {} = {} must be finite and >= 0", what, field, v);
  };
  nonNegative(stats.errorAchieved, "errorAchieved");
  nonNegative(stats.errorTarget, "errorTarget");
  nonNegative(stats.trainingSeconds, "trainingSeconds");
  if (stats.model.size() > 4096)
    fail("{}: model description is {} characters (limit 4096)", what, stats.model.size());
}

size_t CellFallback::storedShBytes() const {
  const size_t entries = shHalf.size() / kShHalves;
  return entries * (precision == Precision::L1Int8 ? size_t(kShL1Q8Bytes) : kShHalves * 2);
}

void quantizeFallbackToInt8(CellFallback& fallback) {
  for (size_t e = 0; e + kShHalves <= fallback.shHalf.size(); e += kShHalves)
    quantizeShL1HalvesQ8(fallback.shHalf.data() + e);
  fallback.precision = CellFallback::Precision::L1Int8;
}

std::vector<std::byte> encodeCellFile(const CellFile& cell) {
  return encode(cell, {});
}

std::vector<std::byte> detail::encodeCellFileWithOverrides(const CellFile& cell,
                                                           std::span<const CellFileOverride> overrides) {
  return encode(cell, overrides);
}

// ---- decode ---------------------------------------------------------------------------------------------

namespace {

// Every read below checks its field on its own and against those read before it; the order of the checks
// (and so which error a broken file reports) is the reader's contract.

// The magic and the format version.
int64_t readVersion(const MetaReader& r, const std::string& name) {
  std::string magic = r.get<std::string>("lfgi_magic");
  if (magic != kMagic) fail("{}: lfgi_magic is '{}', expected '{}' (not a cell file)", name, magic, kMagic);
  int64_t version = r.get<int32_t>("lfgi_format_version");
  if (version < 1 || version > kCellFileVersion)
    fail("{}: cell file format version {}, this build reads versions 1 to {} (rebake the cell)", name,
         version, kCellFileVersion);
  return version;
}

// Identity, probe grid and output scale into c; returns probe_count (the active probes).
int64_t readGridFields(const MetaReader& r, const std::string& name, CellFile& c) {
  c.worldSeed = parseHex64(r.get<std::string>("world_seed"), name + ": world_seed");
  c.cellX = r.get<int32_t>("cell_x");
  c.cellZ = r.get<int32_t>("cell_z");
  c.inputHash = parseHex64(r.get<std::string>("input_hash"), name + ": input_hash");
  openvdb::Vec3s o = r.get<openvdb::Vec3s>("probe_origin"), sp = r.get<openvdb::Vec3s>("probe_spacing");
  openvdb::Vec3i d = r.get<openvdb::Vec3i>("probe_dims");
  c.grid.origin = {o.x(), o.y(), o.z()};
  c.grid.spacing = {sp.x(), sp.y(), sp.z()};
  c.grid.dims = {d.x(), d.y(), d.z()};
  try {
    c.grid.validate();
  } catch (const Error& e) {
    fail("{}: probe grid: {}", name, e.what());
  }
  if (c.grid.probeCount() > kCellFileMaxProbes)
    fail("{}: probe_dims {}x{}x{} = {} probes, more than the cell limit {}", name, d.x(), d.y(), d.z(),
         c.grid.probeCount(), kCellFileMaxProbes);
  const int64_t probeCount = r.getInt("probe_count", 0, c.grid.probeCount());
  c.outputScale.exposure = r.getFinite("exposure");
  c.outputScale.range = r.getFinite("range");
  return probeCount;
}

// The probe topology: the one mask grid, its voxels the active probes (c.active unless all are).
void readTopology(const openvdb::GridPtrVecPtr& grids, const std::string& name, int64_t probeCount,
                  CellFile& c) {
  if (grids->size() != 1)
    fail("{}: {} grids, a cell file holds exactly one ('{}')", name, grids->size(), kGridName);
  openvdb::MaskGrid::Ptr mask = openvdb::gridPtrCast<openvdb::MaskGrid>((*grids)[0]);
  if (!mask || mask->getName() != kGridName)
    fail("{}: the grid is '{}' of type {}, expected '{}' of type {}", name, (*grids)[0]->getName(),
         (*grids)[0]->type(), kGridName, openvdb::MaskGrid::gridType());
  if (mask->tree().activeTileCount() != 0)
    fail("{}: grid '{}' has active tiles (probes are voxels)", name, kGridName);
  const openvdb::Index64 voxels = mask->activeVoxelCount();
  if (int64_t(voxels) != probeCount)
    fail("{}: probe_count = {}, but grid '{}' has {} active voxels", name, probeCount, kGridName, voxels);
  {
    const openvdb::math::Transform& xf = mask->transform();
    openvdb::Vec3d w0 = xf.indexToWorld(openvdb::Coord(0, 0, 0)),
                   w1 = xf.indexToWorld(openvdb::Coord(1, 1, 1));
    for (int k = 0; k < 3; ++k) {
      double so = double(c.grid.origin[k]), ss = double(c.grid.spacing[k]);
      if (std::fabs(w0[k] - so) > 1e-5 * (1.0 + std::fabs(so)) || std::fabs((w1[k] - w0[k]) - ss) > 1e-5 * ss)
        fail("{}: grid '{}' transform disagrees with probe_origin/probe_spacing on axis {}", name, kGridName,
             k);
    }
  }
  std::vector<uint8_t> active(size_t(c.grid.probeCount()), 0);
  for (auto it = mask->cbeginValueOn(); it; ++it) {
    openvdb::Coord q = it.getCoord();
    glm::ivec3 g(q.x(), q.y(), q.z());
    if (glm::any(glm::lessThan(g, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(g, c.grid.dims)))
      fail("{}: probe voxel ({}, {}, {}) lies outside the probe grid {}x{}x{}", name, g.x, g.y, g.z,
           c.grid.dims.x, c.grid.dims.y, c.grid.dims.z);
    active[size_t(c.grid.linearIndex(g))] = 1;
  }
  if (probeCount != c.grid.probeCount()) c.active = std::move(active);
}

// The model: none, the cell's own network, or a reference to the world's shared model.
void readModel(const MetaReader& r, const std::string& name, int64_t version, int64_t probeCount, CellFile& c,
               CellFileBytes& parts) {
  std::string model = r.get<std::string>("model");
  if (model == "network" || model == "shared") {
    if (model == "shared" && version < kSharedRefVersion)
      fail("{}: a version-{} cell file refers to a shared model (version {} and later only)", name, version,
           kSharedRefVersion);
    const auto [a, p] = readArch(r);
    CellGenerator g;
    if (model == "shared") {
      if (r.has("generator_weights")) fail("{}: a shared-model cell holds its own 'generator_weights'", name);
      CellSharedModelRef ref;
      ref.modelHash = parseHex64(r.get<std::string>("shared_model_hash"), name + ": shared_model_hash");
      if (ref.modelHash == 0) fail("{}: shared_model_hash is 0 (no model has it)", name);
      const int stages = int(r.getInt("adapter_stages", 0, a.layers() + 1));
      const int bits = int(r.getInt("adapter_bits", 4, 8));
      const int64_t channels = r.getInt("adapter_channels", 0, 1 << 16);
      std::vector<uint8_t> ab = r.blob("adapter");
      try {
        ref.adapter = decodeAdapter(ab, a, stages, bits, channels, "adapter");
      } catch (const Error& e) {
        fail("{}: {}", name, e.what());
      }
      parts.adapter = ab.size();
      g.weights.arch = a;
      g.weights.precision = p;
      g.shared = std::move(ref);
    } else {
      for (const char* f : {"shared_model_hash", "adapter"})
        if (r.has(f))
          fail("{}: a cell with its own weights holds field '{}' (shared-model cells only)", name, f);
      std::vector<uint8_t> wb = r.blob("generator_weights");
      try {
        g.weights = decodeWeights(wb, a, p, "generator_weights");
      } catch (const Error& e) {
        fail("{}: {}", name, e.what());
      }
      parts.weights = wb.size();
    }
    if (a.latentSource == LatentSource::Stored) {
      int bits = int(r.getInt("latent_bits", 4, 8));
      if (bits != 4 && bits != 8) fail("{}: latent_bits = {} (supported: 8, 4)", name, bits);
      int64_t count = r.getInt("latent_count", 0, kCellFileMaxProbes);
      if (count != probeCount)
        fail("{}: latent_count = {}, but the file has {} probes", name, count, probeCount);
      std::vector<uint8_t> lb = r.blob("latents");
      try {
        g.latents = decodeLatents(lb, a.latentDim, bits, count, "latents");
      } catch (const Error& e) {
        fail("{}: {}", name, e.what());
      }
      parts.latents = lb.size();
    } else if (r.has("latents")) {
      fail("{}: a position-derived latent model stores no latents, but the file holds a 'latents' blob",
           name);
    }
    c.generator = std::move(g);
  } else if (model != "none") {
    fail("{}: model '{}' is unknown (network, shared, none)", name, model);
  }
}

// fallback_precision: version 4 only, where it must be present.
void readFallbackPrecision(const MetaReader& r, const std::string& name, int64_t version, CellFallback& f) {
  if (version < kInt8FallbackVersion) {
    if (r.has("fallback_precision"))
      fail("{}: a version-{} cell file holds field 'fallback_precision' (version {} and later only)", name,
           version, kInt8FallbackVersion);
    return;
  }
  const std::string p = r.get<std::string>("fallback_precision");
  if (p == "l1_int8")
    f.precision = CellFallback::Precision::L1Int8;
  else if (p == "fp16")
    f.precision = CellFallback::Precision::Fp16;
  else
    fail("{}: fallback_precision '{}' is unknown (fp16, l1_int8)", name, p);
}

// The SH L1 fallback and its lighting keys.
void readFallback(const MetaReader& r, const std::string& name, int64_t version, int64_t probeCount,
                  CellFile& c, CellFileBytes& parts) {
  std::string fk = r.get<std::string>("fallback_kind");
  if (fk == "sh_l1_per_cell")
    c.fallback.kind = CellFallback::Kind::PerCell;
  else if (fk == "sh_l1_per_probe")
    c.fallback.kind = CellFallback::Kind::PerProbe;
  else
    fail("{}: fallback_kind '{}' is unknown (sh_l1_per_cell, sh_l1_per_probe)", name, fk);
  // Lighting keys of the fallback: version 1 has none (one key, read as 12 h overcast 0).
  size_t keys = 1;
  if (version >= 2) {
    keys = size_t(r.getInt("fallback_key_count", 1, kCellFileMaxFallbackKeys));
    std::vector<uint8_t> hb = r.blob("fallback_key_hours"), ob = r.blob("fallback_key_overcast");
    if (hb.size() != keys * sizeof(float))
      fail("{}: fallback_key_hours holds {} bytes, {} expected ({} keys x float32)", name, hb.size(),
           keys * sizeof(float), keys);
    if (ob.size() != keys * sizeof(float))
      fail("{}: fallback_key_overcast holds {} bytes, {} expected ({} keys x float32)", name, ob.size(),
           keys * sizeof(float), keys);
    c.fallback.keyHours.resize(keys);
    c.fallback.keyOvercast.resize(keys);
    std::memcpy(c.fallback.keyHours.data(), hb.data(), hb.size());
    std::memcpy(c.fallback.keyOvercast.data(), ob.data(), ob.size());
    parts.fallback += hb.size() + ob.size();
  } else {
    for (const char* f : {"fallback_key_count", "fallback_key_hours", "fallback_key_overcast"})
      if (r.has(f)) fail("{}: a version-1 cell file holds field '{}' (version 2 and later only)", name, f);
  }
  readFallbackPrecision(r, name, version, c.fallback);
  std::vector<uint8_t> fb = r.blob("fallback_sh");
  const size_t entries = c.fallback.kind == CellFallback::Kind::PerCell ? 1 : size_t(probeCount);
  const bool int8 = c.fallback.precision == CellFallback::Precision::L1Int8;
  const size_t perEntry = int8 ? size_t(kShL1Q8Bytes) : kShHalves * 2;
  if (fb.size() != keys * entries * perEntry)
    fail("{}: fallback_sh holds {} bytes, {} expected ({} keys x {} x {})", name, fb.size(),
         keys * entries * perEntry, keys, entries, int8 ? "15 B (int8 layout)" : "12 halves");
  c.fallback.shHalf.resize(keys * entries * kShHalves);
  if (!int8 && !fb.empty()) std::memcpy(c.fallback.shHalf.data(), fb.data(), fb.size());
  for (size_t e = 0; int8 && e < keys * entries; ++e)
    if (!unpackShL1Q8(fb.data() + e * perEntry, c.fallback.shHalf.data() + e * kShHalves))
      fail(
          "{}: fallback_sh entry {} holds an L1 code the int8 layout never writes (-128, or nonzero "
          "against a zero L0)",
          name, e);
  parts.fallback += fb.size();
}

}  // namespace

CellFile decodeCellFile(std::span<const std::byte> bytes, const std::string& name,
                        CellFileBytes* bytesByPart) {
  // 1. Envelope (size, trailer, checksum), then 2. the OpenVDB parse of bytes our writer produced.
  const OpenedStream opened = vdbfile::open(bytes, name, kTrailerMagic, kCellFileMaxBytes, "cell file");
  const openvdb::GridPtrVecPtr& grids = opened.grids;
  // 3. Fields, each checked on its own and against the others.
  CellFileBytes parts;
  CellFile c = cellmeta::decode(
      *opened.meta, name,
      [&](int64_t probeCount, CellFile& cell) { readTopology(grids, name, probeCount, cell); }, parts);
  parts.total = bytes.size();
  if (bytesByPart) *bytesByPart = parts;
  return c;
}

CellFile cellmeta::decode(const openvdb::MetaMap& meta, const std::string& name,
                          const TopologyReader& topology, CellFileBytes& parts) {
  MetaReader r(meta, name);
  const int64_t version = readVersion(r, name);
  CellFile c;
  const int64_t probeCount = readGridFields(r, name, c);
  topology(probeCount, c);
  readModel(r, name, version, probeCount, c, parts);
  readFallback(r, name, version, probeCount, c, parts);

  c.stats.errorAchieved = r.getFiniteDouble("error_achieved");
  c.stats.errorTarget = r.getFiniteDouble("error_target");
  c.stats.trainingSeconds = r.getFiniteDouble("training_seconds");
  c.stats.model = r.get<std::string>("bake_model");

  c.validate(name);
  parts.version = int(version);
  return c;
}

void writeCellFile(const std::filesystem::path& path, const CellFile& cell) {
  std::vector<std::byte> bytes;
  try {
    bytes = encodeCellFile(cell);
  } catch (const Error& e) {
    fail("{}: {}", path.string(), e.what());
  }
  writeFileAtomic(path, bytes);
}

CellFile readCellFile(const std::filesystem::path& path, CellFileBytes* bytesByPart) {
  std::error_code ec;
  auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > kCellFileMaxBytes)
    fail("{}: {} bytes, more than the cell file limit {}", path.string(), size, kCellFileMaxBytes);
  std::vector<std::byte> bytes = readFileBytes(path);
  return decodeCellFile(bytes, path.string(), bytesByPart);
}

// ---- ContentHasher --------------------------------------------------------------------------------------

ContentHasher::ContentHasher() : state_(XXH3_createState()) {
  if (!state_) throw std::bad_alloc();
  XXH3_64bits_reset(static_cast<XXH3_state_t*>(state_));
}
ContentHasher::~ContentHasher() {
  XXH3_freeState(static_cast<XXH3_state_t*>(state_));
}
ContentHasher& ContentHasher::add(std::span<const std::byte> bytes) {
  XXH3_64bits_update(static_cast<XXH3_state_t*>(state_), bytes.data(), bytes.size());
  return *this;
}
ContentHasher& ContentHasher::add(const std::string& text) {
  uint64_t n = text.size();
  addValue(n);
  return add(std::as_bytes(std::span<const char>(text)));
}
uint64_t ContentHasher::digest() const {
  return XXH3_64bits_digest(static_cast<XXH3_state_t*>(state_));
}

}  // namespace lfgi
