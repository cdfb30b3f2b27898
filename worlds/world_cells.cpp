#include "worlds/world_cells.h"

#include "worlds/cell_probe_file.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <span>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::worlds {
namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

std::string cellName(CellCoord c) {
  return fmt::format("cell_{}_{}", c.x, c.z);
}

// Solid boxes binned over XZ (cell's own and its 8 neighbours'), for the buried-surface tests below.
class SolidIndex {
 public:
  SolidIndex(std::vector<Aabb> boxes, float binM) : boxes_(std::move(boxes)), bin_(binM) {
    for (const Aabb& b : boxes_) {
      lo_ = glm::min(lo_, glm::vec2(b.min.x, b.min.z));
      hi_ = glm::max(hi_, glm::vec2(b.max.x, b.max.z));
    }
    if (boxes_.empty()) return;
    dims_ = glm::max(glm::ivec2(1), glm::ivec2(glm::ceil((hi_ - lo_) / bin_)));
    bins_.resize(size_t(dims_.x) * size_t(dims_.y));
    for (uint32_t i = 0; i < boxes_.size(); ++i) {
      const glm::ivec2 a = binOf({boxes_[i].min.x, boxes_[i].min.z}),
                       b = binOf({boxes_[i].max.x, boxes_[i].max.z});
      for (int z = a.y; z <= b.y; ++z)
        for (int x = a.x; x <= b.x; ++x) bins_[size_t(z) * size_t(dims_.x) + size_t(x)].push_back(i);
    }
  }
  // Index of a box that holds every point strictly (open box), or -1.
  template <size_t K>
  int holder(const std::array<glm::vec3, K>& pts) const {
    if (boxes_.empty()) return -1;
    for (const glm::vec3& p : pts)
      if (p.x <= lo_.x || p.z <= lo_.y || p.x >= hi_.x || p.z >= hi_.y) return -1;
    const glm::ivec2 c = binOf({pts[0].x, pts[0].z});
    for (const uint32_t i : bins_[size_t(c.y) * size_t(dims_.x) + size_t(c.x)]) {
      const Aabb& b = boxes_[i];
      bool all = true;
      for (const glm::vec3& p : pts)
        all = all && glm::all(glm::greaterThan(p, b.min)) && glm::all(glm::lessThan(p, b.max));
      if (all) return int(i);
    }
    return -1;
  }

 private:
  glm::ivec2 binOf(glm::vec2 p) const {
    return glm::clamp(glm::ivec2(glm::floor((p - lo_) / bin_)), glm::ivec2(0), dims_ - 1);
  }
  std::vector<Aabb> boxes_;
  float bin_;
  glm::vec2 lo_{1e30f}, hi_{-1e30f};
  glm::ivec2 dims_{0};
  std::vector<std::vector<uint32_t>> bins_;
};

// A surface is buried when the space right in front of it is inside a closed solid box (terrain through
// a city's ground slab; a wall's bottom face on a floor slab), under the terrain (slab undersides 0.1 m
// below ground) or under a road strip (the terrain beneath it): no probe, camera or shadow ray reaches
// it, so it is dropped before surfels are sampled (whole triangles) and after (surfels of triangles only
// partly inside). The offset is 1 cm along the normal; a point counts as under the terrain only when 2 cm
// or more below it, so the terrain's own surfels in concave creases are never taken for buried.
constexpr float kBuriedProbeM = 0.01f;
constexpr float kBuriedTerrainM = 0.02f;

size_t dropBuriedTriangles(TriangleMesh& mesh, const SolidIndex& solids) {
  std::vector<uint32_t> indices;
  std::vector<uint32_t> materials;
  indices.reserve(mesh.indices.size());
  materials.reserve(mesh.triangleMaterial.size());
  size_t dropped = 0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const glm::vec3 d = mesh.faceNormal(t) * kBuriedProbeM;
    // Boxes are convex: a triangle whose three offset corners lie inside one box lies inside it entirely.
    if (solids.holder(std::array{mesh.vertex(t, 0) + d, mesh.vertex(t, 1) + d, mesh.vertex(t, 2) + d}) >= 0) {
      ++dropped;
      continue;
    }
    indices.insert(indices.end(), mesh.indices.begin() + std::ptrdiff_t(3 * t),
                   mesh.indices.begin() + std::ptrdiff_t(3 * t + 3));
    materials.push_back(mesh.triangleMaterial[t]);
  }
  // Compact the vertices the dropped triangles alone used (uploads and bounds see only what is drawn).
  std::vector<uint32_t> remap(mesh.positions.size(), ~0u);
  std::vector<glm::vec3> positions;
  std::vector<glm::vec2> uvs;
  for (uint32_t& i : indices) {
    if (remap[i] == ~0u) {
      remap[i] = uint32_t(positions.size());
      positions.push_back(mesh.positions[i]);
      if (!mesh.uvs.empty()) uvs.push_back(mesh.uvs[i]);
    }
    i = remap[i];
  }
  mesh.positions = std::move(positions);
  mesh.uvs = std::move(uvs);
  mesh.indices = std::move(indices);
  mesh.triangleMaterial = std::move(materials);
  return dropped;
}

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

  // Probe placement against the cell mesh + neighbours' solid boxes.
  t0 = Clock::now();
  const double cellM = world.cellSizeM();
  // Spacing from the generated mesh's area (buried surfaces included, as before they were dropped below,
  // so probe layouts did not move).
  s.probeSpacingM = chooseProbeSpacing(out.mesh.totalArea(), cellM * cellM);
  TriangleMesh context = out.mesh;
  Material proxy;
  proxy.category = SurfaceCategory::kWall;
  const uint32_t proxyMat = context.addMaterial(proxy);
  std::vector<Aabb> solidBoxes;  // the cell's and its neighbours', for the buried-surface tests
  for (const SolidBox& b : out.layout.solids) solidBoxes.push_back(b.box);
  for (int dz = -1; dz <= 1; ++dz)
    for (int dx = -1; dx <= 1; ++dx) {
      CellCoord n{c.x + dx, c.z + dz};
      if ((dx == 0 && dz == 0) || !world.contains(n)) continue;
      for (const SolidBox& b : world.describeCell(n).solids) {
        context.addBox(b.box.min, b.box.max, proxyMat);
        solidBoxes.push_back(b.box);
      }
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

  // Buried surfaces go before surfels are sampled (placement above saw the whole mesh; it gives the same
  // answer without them, since no probe ray from outside the solids reaches one).
  t0 = Clock::now();
  const SolidIndex solids(std::move(solidBoxes), 4.0f);
  if (options.dropBuried) s.trianglesBuried = dropBuriedTriangles(out.mesh, solids);
  s.meshHash = out.mesh.contentHash();
  s.triangles = out.mesh.triangleCount();
  s.surfaceAreaM2 = out.mesh.totalArea();
  s.categoryTriangles = out.mesh.categoryTriangleCounts();

  SurfelOptions so;
  so.spacing = surfelSpacingForProbeSpacing(s.probeSpacingM);
  so.seed = options.surfelSeed ^ (uint64_t(uint32_t(c.x)) << 32 | uint32_t(c.z));
  out.surfels = sampleSurfels(out.mesh, so);
  if (options.dropBuried) {
    const auto buried = std::stable_partition(out.surfels.begin(), out.surfels.end(), [&](const Surfel& sf) {
      const glm::vec3 q = glm::vec3(sf.positionRadius) + glm::vec3(sf.normal) * kBuriedProbeM;
      // Under a road strip: the terrain (y = 0 on roads) between it and the strip raised kRoadRaiseM
      // above, closed by kerbs wherever the neighbour is not road.
      return !(solids.holder(std::array{q}) >= 0 || q.y < world.terrainHeight(q.x, q.z) - kBuriedTerrainM ||
               (q.y < kRoadRaiseM && world.isRoad(q.x, q.z)));
    });
    s.surfelsBuried = size_t(out.surfels.end() - buried);
    s.surfelBuriedAreaM2 = surfelArea(std::span(buried, out.surfels.end()));
    out.surfels.erase(buried, out.surfels.end());
  }
  SurfelCodecStats cs;
  out.surfelBytes = encodeSurfels(out.surfels, options.surfelPositionBits, &cs);
  s.surfelMs = msSince(t0);  // buried-surface culling included
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
  j["probes"] = {{"total", s.probes},
                 {"active", s.probesActive},
                 {"relocated", s.probesRelocated},
                 {"disabled", s.probesDisabled},
                 {"sky_only", s.probesSkyOnly},
                 {"disabled_by_layout_check", s.probesDisabledByLayout}};
  j["buried"] = {{"triangles", s.trianglesBuried},
                 {"surfels", s.surfelsBuried},
                 {"surfel_area_m2", s.surfelBuriedAreaM2}};
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

bool cellDone(const std::filesystem::path& dir, CellCoord c) {
  return std::filesystem::exists(cellJsonPath(dir, c));
}

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
      fail("{}: holds a different world (seed {}, size {} m, cell {} m); use another directory",
           file.string(), old.seed, old.sizeM, old.cellM);
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
  return parseWorldManifest(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                            file.string());
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
    fail("{}: world format version {} (this build reads {})", name,
         version == j.end() ? "missing" : version->dump(), kWorldFormatVersion);
  auto field = [&](const char* key) -> const nlohmann::json& {
    const auto it = j.find(key);
    if (it == j.end()) fail("{}: missing field '{}'", name, key);
    return *it;
  };
  WorldParams p;
  const nlohmann::json& seed = field("seed");
  if (!seed.is_number_unsigned())
    fail("{}: field 'seed' is {}, expected an integer in [0, 2^64)", name, seed.dump());
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
  j["probe_grid"] = {
      {"origin", {cell.probes.grid.origin.x, cell.probes.grid.origin.y, cell.probes.grid.origin.z}},
      {"spacing_m", cell.probes.grid.spacing.x}};
  writeFileAtomic(cellJsonPath(dir, c), j.dump(2) + "\n");  // last: marks the cell finished
}

std::optional<CellProbeFile> readCellProbes(const std::filesystem::path& dir, CellCoord c) {
  const std::filesystem::path file = dir / "cells" / (cellName(c) + ".probes");
  if (!std::filesystem::exists(file)) return std::nullopt;
  const std::vector<std::byte> bytes = readFileBytes(file);
  uint32_t header[3] = {};
  if (bytes.size() < sizeof(header))
    fail("{}: truncated ({} bytes, header needs {})", file.string(), bytes.size(), sizeof(header));
  std::memcpy(header, bytes.data(), sizeof(header));
  if (header[0] != 0x5250464cu || header[1] != 1u)
    fail("{}: not a version-1 probe file (magic {:#x}, version {})", file.string(), header[0], header[1]);
  const size_t count = header[2];
  if (bytes.size() != sizeof(header) + count * (1 + sizeof(glm::vec3)))
    fail("{}: {} bytes, {} probes need {}", file.string(), bytes.size(), count,
         sizeof(header) + count * (1 + sizeof(glm::vec3)));
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
  auto j = nlohmann::ordered_json::parse(
      std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size()), nullptr, false);
  if (j.is_discarded() || !j.is_object()) fail("{}: not valid JSON", file.string());
  return j;
}

}  // namespace lfgi::worlds
