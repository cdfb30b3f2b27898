#include "worlds/world_cells.h"

#include "worlds/cell_probe_file.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::worlds {
namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

std::string cellName(CellCoord c) { return fmt::format("cell_{}_{}", c.x, c.z); }

}  // namespace

BuiltCell buildCell(const SyntheticWorld& world, CellCoord c, const CellBuildOptions& options) {
  using Clock = std::chrono::steady_clock;
  BuiltCell out;
  CellStats& s = out.stats;
  s.cell = c;

  auto t0 = Clock::now();
  GeneratedCell gen = world.generate(c);
  out.mesh = std::move(gen.mesh);
  out.layout = std::move(gen.layout);
  s.generateMs = msSince(t0);
  s.kind = out.layout.kind;
  s.meshHash = out.mesh.contentHash();
  s.triangles = out.mesh.triangleCount();
  s.surfaceAreaM2 = out.mesh.totalArea();
  s.categoryTriangles = out.mesh.categoryTriangleCounts();

  // Probe placement against the cell mesh + neighbours' solid boxes.
  t0 = Clock::now();
  const double cellM = world.cellSizeM();
  s.probeSpacingM = chooseProbeSpacing(s.surfaceAreaM2, cellM * cellM);
  TriangleMesh context = out.mesh;
  Material proxy;
  proxy.category = SurfaceCategory::kWall;
  const uint32_t proxyMat = context.addMaterial(proxy);
  for (int dz = -1; dz <= 1; ++dz)
    for (int dx = -1; dx <= 1; ++dx) {
      CellCoord n{c.x + dx, c.z + dz};
      if ((dx == 0 && dz == 0) || !world.contains(n)) continue;
      for (const SolidBox& b : world.describeCell(n).solids) context.addBox(b.box.min, b.box.max, proxyMat);
    }
  TriangleBvh bvh(context);
  const Aabb cellBox = world.cellBounds(c);
  ProbeGrid grid = cellProbeGrid({cellBox.min.x, cellBox.min.z}, float(cellM), s.probeSpacingM,
                                 out.layout.bounds.min.y, out.layout.bounds.max.y);
  out.probes = placeProbes(context, bvh, grid, options.placement);
  // Analytic check (the layout knows its solids and terrain exactly).
  for (int64_t i = 0; i < grid.probeCount(); ++i) {
    uint8_t& f = out.probes.flags[size_t(i)];
    if (f & kProbeDisabledSolid) continue;
    glm::vec3 p = out.probes.position(i);
    if (out.layout.insideSolid(p) || p.y < world.terrainHeight(p.x, p.z)) {
      if (f & kProbeRelocated) --out.probes.relocated;
      if (f & kProbeSkyOnly) --out.probes.skyOnly;
      f = kProbeDisabledSolid;
      out.probes.offsets[size_t(i)] = glm::vec3(0.0f);
      --out.probes.active;
      ++out.probes.disabled;
      ++s.probesDisabledByLayout;
    }
  }
  s.placeMs = msSince(t0);
  s.probeDims = grid.dims;
  s.probes = size_t(grid.probeCount());
  s.probesActive = out.probes.active;
  s.probesRelocated = out.probes.relocated;
  s.probesDisabled = out.probes.disabled;
  s.probesSkyOnly = out.probes.skyOnly;

  t0 = Clock::now();
  SurfelOptions so;
  so.spacing = surfelSpacingForProbeSpacing(s.probeSpacingM);
  so.seed = options.surfelSeed ^ (uint64_t(uint32_t(c.x)) << 32 | uint32_t(c.z));
  out.surfels = sampleSurfels(out.mesh, so);
  SurfelCodecStats cs;
  out.surfelBytes = encodeSurfels(out.surfels, options.surfelPositionBits, &cs);
  s.surfelMs = msSince(t0);
  s.surfels = out.surfels.size();
  s.surfelSpacingM = so.spacing;
  s.surfelRawBytes = cs.rawBytes;
  s.surfelEncodedBytes = cs.encodedBytes;
  return out;
}

nlohmann::ordered_json cellStatsJson(const CellStats& s) {
  nlohmann::ordered_json j;
  j["cell"] = {s.cell.x, s.cell.z};
  j["kind"] = std::string(cellKindName(s.kind));
  j["mesh_hash"] = fmt::format("{:016x}", s.meshHash);
  j["triangles"] = s.triangles;
  j["surface_area_m2"] = s.surfaceAreaM2;
  nlohmann::ordered_json cats;
  for (size_t i = 0; i < s.categoryTriangles.size(); ++i)
    cats[std::string(categoryName(SurfaceCategory(i)))] = s.categoryTriangles[i];
  j["category_triangles"] = cats;
  j["probe_spacing_m"] = s.probeSpacingM;
  j["probe_dims"] = {s.probeDims.x, s.probeDims.y, s.probeDims.z};
  j["probes"] = {{"total", s.probes},       {"active", s.probesActive},     {"relocated", s.probesRelocated},
                 {"disabled", s.probesDisabled}, {"sky_only", s.probesSkyOnly},
                 {"disabled_by_layout_check", s.probesDisabledByLayout}};
  j["surfels"] = {{"count", s.surfels},
                  {"spacing_m", s.surfelSpacingM},
                  {"raw_bytes", s.surfelRawBytes},
                  {"draco_bytes", s.surfelEncodedBytes}};
  j["timing_ms"] = {{"generate", s.generateMs}, {"place_probes", s.placeMs}, {"surfels", s.surfelMs}};
  return j;
}

std::filesystem::path cellJsonPath(const std::filesystem::path& dir, CellCoord c) {
  return dir / "cells" / (cellName(c) + ".json");
}

bool cellDone(const std::filesystem::path& dir, CellCoord c) { return std::filesystem::exists(cellJsonPath(dir, c)); }

namespace {

void writeManifestFile(const std::filesystem::path& file, const WorldParams& p) {
  nlohmann::ordered_json j;
  j["format"] = "lfgi-world";
  j["version"] = kWorldFormatVersion;
  j["generator"] = "synthetic";
  j["seed"] = p.seed;
  j["size_m"] = p.sizeM;
  j["cell_m"] = p.cellM;
  j["cells_x"] = SyntheticWorld(p).cellsX();
  j["cells_z"] = SyntheticWorld(p).cellsZ();
  if (!p.edits.empty()) j["edits"] = worldEditsToJson(p.edits);
  writeFileAtomic(file, j.dump(2) + "\n");
}

}  // namespace

void writeWorldManifest(const std::filesystem::path& dir, const WorldParams& p) {
  p.validate();
  const std::filesystem::path file = dir / "world.json";
  if (std::filesystem::exists(file)) {
    WorldParams old = readWorldManifest(dir);
    if (old.seed != p.seed || old.sizeM != p.sizeM || old.cellM != p.cellM)
      fail("{}: holds a different world (seed {}, size {} m, cell {} m); use another directory", file.string(),
           old.seed, old.sizeM, old.cellM);
    if (!p.edits.empty() && p.edits != old.edits)
      fail("{}: holds other edits ({}); add edits with `lfgi world edit`", file.string(), old.edits.size());
    return;
  }
  writeManifestFile(file, p);
}

WorldParams appendWorldEdits(const std::filesystem::path& dir, const std::vector<WorldEdit>& edits) {
  WorldParams p = readWorldManifest(dir);
  const std::filesystem::path file = dir / "world.json";
  p.edits.insert(p.edits.end(), edits.begin(), edits.end());
  try {
    p.validate();
  } catch (const Error& e) {
    fail("{}: {}", file.string(), e.what());
  }
  writeManifestFile(file, p);
  return p;
}

WorldParams readWorldManifest(const std::filesystem::path& dir) {
  const std::filesystem::path file = dir / "world.json";
  if (!std::filesystem::exists(file))
    fail("{}: no world here (create one with `lfgi world generate --out {}`)", file.string(), dir.string());
  std::vector<std::byte> bytes = readFileBytes(file);
  return parseWorldManifest(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), file.string());
}

WorldParams parseWorldManifest(std::string_view text, const std::string& name) {
  // Every lookup is typed by hand: nlohmann's value()/get() throw their own exception types on a field of
  // the wrong type, and the contract is an lfgi::Error naming the file.
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) fail("{}: not valid JSON", name);
  const auto format = j.find("format");
  if (format == j.end() || !format->is_string() || *format != "lfgi-world")
    fail("{}: not an lfgi world manifest (format field)", name);
  const auto version = j.find("version");
  if (version == j.end() || !version->is_number_integer() || *version != kWorldFormatVersion)
    fail("{}: world format version {} (this build reads {})", name, version == j.end() ? "missing" : version->dump(),
         kWorldFormatVersion);
  auto field = [&](const char* key) -> const nlohmann::json& {
    const auto it = j.find(key);
    if (it == j.end()) fail("{}: missing field '{}'", name, key);
    return *it;
  };
  WorldParams p;
  const nlohmann::json& seed = field("seed");
  if (!seed.is_number_unsigned()) fail("{}: field 'seed' is {}, expected an integer in [0, 2^64)", name, seed.dump());
  p.seed = seed.get<uint64_t>();
  for (auto [key, out] : {std::pair{"size_m", &p.sizeM}, std::pair{"cell_m", &p.cellM}}) {
    const nlohmann::json& v = field(key);
    if (!v.is_number()) fail("{}: field '{}' is {}, expected a number", name, key, v.dump());
    *out = v.get<double>();
    if (!std::isfinite(*out)) fail("{}: field '{}' is not finite", name, key);
  }
  if (const auto edits = j.find("edits"); edits != j.end()) {
    try {
      p.edits = worldEditsFromJson(*edits);
    } catch (const Error& e) {
      fail("{}: {}", name, e.what());
    }
  }
  try {
    p.validate();
  } catch (const Error& e) {
    fail("{}: {}", name, e.what());
  }
  return p;
}

void writeCell(const std::filesystem::path& dir, const BuiltCell& cell) {
  const CellCoord c = cell.stats.cell;
  const std::filesystem::path base = dir / "cells" / cellName(c);
  writeFileAtomic(std::filesystem::path(base.string() + ".surfels"), cell.surfelBytes);
  // Probes: "LFPR", version 1, count, then count flag bytes, then count * 3 float offsets.
  const uint32_t header[3] = {0x5250464cu, 1u, uint32_t(cell.probes.flags.size())};
  std::vector<std::byte> probes(sizeof(header) + cell.probes.flags.size() * (1 + sizeof(glm::vec3)));
  std::memcpy(probes.data(), header, sizeof(header));
  std::memcpy(probes.data() + sizeof(header), cell.probes.flags.data(), cell.probes.flags.size());
  std::memcpy(probes.data() + sizeof(header) + cell.probes.flags.size(), cell.probes.offsets.data(),
              cell.probes.offsets.size() * sizeof(glm::vec3));
  writeFileAtomic(std::filesystem::path(base.string() + ".probes"), probes);
  nlohmann::ordered_json j = cellStatsJson(cell.stats);
  j["probe_grid"] = {{"origin", {cell.probes.grid.origin.x, cell.probes.grid.origin.y, cell.probes.grid.origin.z}},
                     {"spacing_m", cell.probes.grid.spacing.x}};
  writeFileAtomic(cellJsonPath(dir, c), j.dump(2) + "\n");  // last: marks the cell finished
}

std::optional<CellProbeFile> readCellProbes(const std::filesystem::path& dir, CellCoord c) {
  const std::filesystem::path file = dir / "cells" / (cellName(c) + ".probes");
  if (!std::filesystem::exists(file)) return std::nullopt;
  const std::vector<std::byte> bytes = readFileBytes(file);
  uint32_t header[3] = {};
  if (bytes.size() < sizeof(header)) fail("{}: truncated ({} bytes, header needs {})", file.string(), bytes.size(), sizeof(header));
  std::memcpy(header, bytes.data(), sizeof(header));
  if (header[0] != 0x5250464cu || header[1] != 1u)
    fail("{}: not a version-1 probe file (magic {:#x}, version {})", file.string(), header[0], header[1]);
  const size_t count = header[2];
  if (bytes.size() != sizeof(header) + count * (1 + sizeof(glm::vec3)))
    fail("{}: {} bytes, {} probes need {}", file.string(), bytes.size(), count, sizeof(header) + count * (1 + sizeof(glm::vec3)));
  CellProbeFile out;
  out.flags.resize(count);
  out.offsets.resize(count);
  std::memcpy(out.flags.data(), bytes.data() + sizeof(header), count);
  std::memcpy(out.offsets.data(), bytes.data() + sizeof(header) + count, count * sizeof(glm::vec3));
  for (const glm::vec3& o : out.offsets)
    if (!std::isfinite(o.x + o.y + o.z)) fail("{}: non-finite probe offset", file.string());
  return out;
}

nlohmann::ordered_json readCellJson(const std::filesystem::path& dir, CellCoord c) {
  const std::filesystem::path file = cellJsonPath(dir, c);
  std::vector<std::byte> bytes = readFileBytes(file);
  auto j = nlohmann::ordered_json::parse(std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                                         nullptr, false);
  if (j.is_discarded() || !j.is_object()) fail("{}: not valid JSON", file.string());
  return j;
}

}  // namespace lfgi::worlds
