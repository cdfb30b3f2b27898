#include "worlds/world_cells.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <random>
#include <set>
#include <utility>

#include "core/error.h"
#include "core/file_util.h"
#include "worlds/cell_probe_file.h"
#include "worlds/triangle_bvh.h"

namespace lfgi::worlds {
namespace {

std::filesystem::path tmpDir(const std::string& name) {
  std::filesystem::path d = std::filesystem::path(LFGI_TEST_TMP_DIR) / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

// The README demo world (256 m, 64 m cells).
const SyntheticWorld& smallWorld() {
  static SyntheticWorld w(WorldParams::smallDefault(1));
  return w;
}

CellCoord firstCellOfKind(CellKind kind) {
  const SyntheticWorld& w = smallWorld();
  for (int z = 0; z < w.cellsZ(); ++z)
    for (int x = 0; x < w.cellsX(); ++x)
      if (w.cellKind({x, z}) == kind) return {x, z};
  ADD_FAILURE() << "no cell of kind " << cellKindName(kind);
  return {0, 0};
}

TEST(WorldCells, CityCellHasNoActiveProbeInsideSolidAndSurfelsCoverTheMesh) {
  const SyntheticWorld& w = smallWorld();
  BuiltCell cell = buildCell(w, firstCellOfKind(CellKind::kCity));
  const CellStats& s = cell.stats;
  EXPECT_GT(s.triangles, 1000u);
  EXPECT_LE(s.probeSpacingM, 4.0f);  // dense geometry gets dense probes
  EXPECT_EQ(s.probesActive + s.probesDisabled, s.probes);
  EXPECT_GT(s.probesRelocated + s.probesDisabled, 0u);  // some grid points fall in or next to walls/slabs
  EXPECT_EQ(s.probesDisabledByLayout, 0u) << "ray placement left probes inside solids";
  for (int64_t i = 0; i < int64_t(s.probes); ++i) {
    if (cell.probes.flags[size_t(i)] & kProbeDisabledSolid) continue;
    glm::vec3 p = cell.probes.position(i);
    ASSERT_FALSE(cell.layout.insideSolid(p)) << "probe " << i;
    ASSERT_GE(p.y, w.terrainHeight(p.x, p.z));
    ASSERT_TRUE(cell.probes.grid.owns(cell.probes.grid.probePosition(cell.probes.grid.probeCoord(i))));
  }
  // The surfels kept plus those dropped as buried cover the (buried-triangle-free) mesh.
  EXPECT_NEAR((surfelArea(cell.surfels) + s.surfelBuriedAreaM2) / cell.mesh.totalArea(), 1.0, 0.01);
  EXPECT_EQ(decodeSurfels(cell.surfelBytes, "cell").size(), cell.surfels.size());
  EXPECT_GT(double(s.surfelRawBytes) / double(s.surfelEncodedBytes), 2.0);
}

// Buried surfaces (buildCell): what is dropped is a large part of a city cell, and no probe sees any of
// it. The dropped surfels are those of sampleSurfels(cell.mesh) (the call buildCell makes) that it did
// not keep (erase_if keeps order); the dropped triangles are the generated mesh's triangles missing from
// cell.mesh. "Seen": a segment from 1 mm in front of the point to an active probe within 3 probe
// spacings, on its front side, hits nothing in the whole generated mesh plus the neighbours' solids (the
// context probe placement uses). And no kept surfel faces a back face right in front (inside something).
TEST(WorldCells, BuriedSurfacesAreDroppedAndNoProbeSeesThem) {
  const SyntheticWorld& w = smallWorld();
  const CellCoord c = firstCellOfKind(CellKind::kCity);
  const BuiltCell cell = buildCell(w, c);
  const CellStats& s = cell.stats;
  GeneratedCell gen = w.generate(c);
  ASSERT_GT(s.trianglesBuried, 0u);
  ASSERT_GT(s.surfelsBuried, 0u);
  ASSERT_EQ(gen.mesh.triangleCount(), s.triangles + s.trianglesBuried);
  const double droppedArea = gen.mesh.totalArea() - cell.mesh.totalArea() + s.surfelBuriedAreaM2;
  std::printf(
      "city cell %d,%d: %zu of %zu triangles and %zu of %zu surfels buried, %.0f of %.0f m^2 (%.1f %%)\n",
      c.x, c.z, s.trianglesBuried, gen.mesh.triangleCount(), s.surfelsBuried, s.surfelsBuried + s.surfels,
      droppedArea, gen.mesh.totalArea(), 100.0 * droppedArea / gen.mesh.totalArea());
  EXPECT_GT(droppedArea / gen.mesh.totalArea(), 0.10);

  // Points to check: the dropped surfels, and each dropped triangle's centroid and corners pulled 10 %
  // towards it.
  std::vector<std::pair<glm::vec3, glm::vec3>> dropped;  // (point, normal)
  SurfelOptions so;
  so.spacing = s.surfelSpacingM;
  so.seed = CellBuildOptions{}.surfelSeed ^ (uint64_t(uint32_t(c.x)) << 32 | uint32_t(c.z));
  const std::vector<Surfel> resampled = sampleSurfels(cell.mesh, so);
  ASSERT_EQ(resampled.size(), s.surfels + s.surfelsBuried);
  for (size_t i = 0, k = 0; i < resampled.size(); ++i) {
    if (k < cell.surfels.size() && resampled[i].positionRadius == cell.surfels[k].positionRadius &&
        resampled[i].normal == cell.surfels[k].normal) {
      ++k;
      continue;
    }
    dropped.push_back({glm::vec3(resampled[i].positionRadius), glm::vec3(resampled[i].normal)});
  }
  ASSERT_EQ(dropped.size(), s.surfelsBuried);
  std::set<std::array<float, 9>> kept;
  auto corners = [](const TriangleMesh& m, size_t t) {
    const glm::vec3 a = m.vertex(t, 0), b = m.vertex(t, 1), d = m.vertex(t, 2);
    return std::array<float, 9>{a.x, a.y, a.z, b.x, b.y, b.z, d.x, d.y, d.z};
  };
  for (size_t t = 0; t < cell.mesh.triangleCount(); ++t) kept.insert(corners(cell.mesh, t));
  size_t droppedTriangles = 0;
  for (size_t t = 0; t < gen.mesh.triangleCount(); ++t) {
    if (kept.count(corners(gen.mesh, t))) continue;
    ++droppedTriangles;
    const glm::vec3 centroid = (gen.mesh.vertex(t, 0) + gen.mesh.vertex(t, 1) + gen.mesh.vertex(t, 2)) / 3.0f;
    dropped.push_back({centroid, gen.mesh.faceNormal(t)});
    for (int v = 0; v < 3; ++v)
      dropped.push_back({glm::mix(gen.mesh.vertex(t, v), centroid, 0.1f), gen.mesh.faceNormal(t)});
  }
  EXPECT_EQ(droppedTriangles, s.trianglesBuried);

  TriangleMesh context = gen.mesh;
  const uint32_t proxy = context.addMaterial(Material{});
  for (int dz = -1; dz <= 1; ++dz)
    for (int dx = -1; dx <= 1; ++dx)
      if ((dx != 0 || dz != 0) && w.contains({c.x + dx, c.z + dz}))
        for (const SolidBox& b : w.describeCell({c.x + dx, c.z + dz}).solids)
          context.addBox(b.box.min, b.box.max, proxy);
  const TriangleBvh bvh(context);
  std::vector<glm::vec3> probes;
  for (int64_t i = 0; i < int64_t(s.probes); ++i)
    if (!(cell.probes.flags[size_t(i)] & kProbeDisabledSolid)) probes.push_back(cell.probes.position(i));
  const float range = 3.0f * s.probeSpacingM;
  size_t seen = 0, tested = 0;
  for (size_t k = 0; k < dropped.size(); k += 3) {
    const auto [p, n] = dropped[k];
    const glm::vec3 o = p + n * 1e-3f;
    ++tested;
    for (const glm::vec3& q : probes) {
      const glm::vec3 d = q - o;
      const float dist = glm::length(d);
      if (dist < range && glm::dot(d, n) > 0.0f && !bvh.intersect(o, d / dist, dist * (1.0f - 1e-4f))) {
        if (++seen <= 5)
          ADD_FAILURE() << "dropped point " << p.x << "," << p.y << "," << p.z << " (normal " << n.x << ","
                        << n.y << "," << n.z << ") is seen from probe " << q.x << "," << q.y << "," << q.z;
        break;
      }
    }
  }
  EXPECT_GT(tested, 1000u);
  EXPECT_EQ(seen, 0u) << "of " << tested << " dropped points tested";

  size_t inside = 0;
  for (const Surfel& k : cell.surfels) {
    const glm::vec3 n(k.normal), o = glm::vec3(k.positionRadius) + n * 1e-3f;
    const auto hit = bvh.intersect(o, n, 4.0f * k.positionRadius.w);
    if (hit && hit->backface && ++inside <= 5)
      ADD_FAILURE() << "kept surfel at " << o.x << "," << o.y << "," << o.z << " (normal " << n.x << ","
                    << n.y << "," << n.z << ") faces the back of triangle " << hit->triangle << " at "
                    << hit->t << " m";
  }
  EXPECT_EQ(inside, 0u) << "kept surfels facing a back face right in front (inside a solid)";
}

TEST(WorldCells, FieldCellUsesSparseProbes) {
  BuiltCell cell = buildCell(smallWorld(), firstCellOfKind(CellKind::kField));
  EXPECT_EQ(cell.stats.probeSpacingM, 8.0f);
  EXPECT_LE(cell.stats.probes, 8u * 8u * 4u);  // 8 m spacing over 64 m, a few layers
  EXPECT_EQ(cell.stats.probesDisabledByLayout, 0u);
}

TEST(WorldCells, DeterministicAcrossCalls) {
  CellCoord c = firstCellOfKind(CellKind::kCity);
  BuiltCell a = buildCell(smallWorld(), c), b = buildCell(smallWorld(), c);
  EXPECT_EQ(a.stats.meshHash, b.stats.meshHash);
  EXPECT_EQ(a.probes.flags, b.probes.flags);
  EXPECT_EQ(a.surfelBytes, b.surfelBytes);
}

TEST(WorldCells, DirectoryRoundTripAndResumeMarker) {
  auto dir = tmpDir("world_cells_roundtrip");
  WorldParams p{7, 64.0, 32.0};
  writeWorldManifest(dir, p);
  WorldParams back = readWorldManifest(dir);
  EXPECT_EQ(back.seed, 7u);
  EXPECT_EQ(back.sizeM, 64.0);
  writeWorldManifest(dir, p);  // same world again: fine
  WorldParams other = p;
  other.seed = 8;
  EXPECT_THROW(writeWorldManifest(dir, other), Error);

  SyntheticWorld w(p);
  EXPECT_FALSE(cellDone(dir, {1, 0}));
  EXPECT_FALSE(readCellProbes(dir, {1, 0}).has_value());
  const BuiltCell built = buildCell(w, {1, 0});
  writeCell(dir, built);
  EXPECT_TRUE(cellDone(dir, {1, 0}));
  // The probe file reads back what was written; a truncated one names the file.
  const std::optional<CellProbeFile> probes = readCellProbes(dir, {1, 0});
  ASSERT_TRUE(probes.has_value());
  EXPECT_EQ(probes->flags, built.probes.flags);
  EXPECT_EQ(probes->offsets, built.probes.offsets);
  {
    const std::filesystem::path file = dir / "cells" / "cell_1_0.probes";
    std::vector<std::byte> bytes = readFileBytes(file);
    bytes.pop_back();
    const std::filesystem::path cut = tmpDir("world_cells_probes_cut");
    std::filesystem::create_directories(cut / "cells");
    writeFileAtomic(cut / "cells" / "cell_1_0.probes", bytes);
    try {
      readCellProbes(cut, {1, 0});
      ADD_FAILURE() << "no throw";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("cell_1_0.probes"), std::string::npos) << e.what();
    }
  }
  nlohmann::ordered_json j = readCellJson(dir, {1, 0});
  EXPECT_EQ(j["cell"][0], 1);
  EXPECT_TRUE(std::filesystem::exists(dir / "cells" / "cell_1_0.surfels"));
  for (const auto& e : std::filesystem::directory_iterator(dir / "cells"))
    EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << e.path();
}

TEST(WorldCells, BadManifestsNameTheFile) {
  auto dir = tmpDir("world_cells_bad");
  try {
    readWorldManifest(dir);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("world.json: no world here"), std::string::npos) << e.what();
  }
  for (const std::string& text :
       {std::string("{not json"), std::string("{\"format\":\"other\"}"),
        std::string("{\"format\":\"lfgi-world\",\"version\":99}"),
        std::string("{\"format\":\"lfgi-world\",\"version\":1,\"seed\":1,\"size_m\":100,\"cell_m\":64}"),
        std::string("{\"format\":\"lfgi-world\",\"version\":1,\"seed\":\"x\"}")}) {
    writeFileAtomic(dir / "world.json", text);
    try {
      readWorldManifest(dir);
      FAIL() << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("world.json"), std::string::npos) << e.what();
    }
  }
}

// Bad input (docs/ARCHITECTURE.md "Bad input and interruption"): every malformed manifest is an lfgi::Error
// naming the file, never a JSON library exception or a crash: wrong types, wrong version, huge and non-finite
// numbers, every truncation, bit flips.
std::string manifestError(std::string_view text) {
  try {
    const WorldParams p = parseWorldManifest(text, "w/world.json");
    p.validate();
    return {};
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("not an lfgi::Error: ") + e.what();
  }
}

TEST(WorldManifest, WrongTypesVersionsAndNumbersNameTheFile) {
  const std::string good = "{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":64,\"cell_m\":32}";
  EXPECT_EQ(manifestError(good), "");
  const std::pair<std::string, std::string> cases[] = {
      {"{\"format\":5,\"version\":1}", "format field"},
      {"{\"format\":\"lfgi-world\",\"version\":\"1\"}", "world format version \"1\""},
      {"{\"format\":\"lfgi-world\",\"version\":2}", "world format version 2 (this build reads 1)"},
      {"{\"format\":\"lfgi-world\",\"version\":1.5}", "world format version 1.5"},
      {"{\"format\":\"lfgi-world\"}", "world format version missing"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"size_m\":64,\"cell_m\":32}", "missing field 'seed'"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":-1,\"size_m\":64,\"cell_m\":32}",
       "field 'seed' is -1"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":1.5,\"size_m\":64,\"cell_m\":32}",
       "field 'seed' is 1.5"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":\"64\",\"cell_m\":32}",
       "field 'size_m' is \"64\""},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":1e400,\"cell_m\":32}",
       "not valid JSON"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":-64,\"cell_m\":32}", "size -64 m"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":1e12,\"cell_m\":64}",
       "more than 65536"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":64,\"cell_m\":null}",
       "field 'cell_m' is null"},
      {"{\"format\":\"lfgi-world\",\"version\":1,\"seed\":3,\"size_m\":64,\"cell_m\":0.001}",
       "cell size 0.001 m"},
      {"[1, 2, 3]", "not valid JSON"},
      {"NaN", "not valid JSON"},
  };
  for (const auto& [text, expect] : cases) {
    const std::string e = manifestError(text);
    EXPECT_EQ(e.rfind("w/world.json: ", 0), 0u) << text << " -> '" << e << "'";
    EXPECT_NE(e.find(expect), std::string::npos) << text << " -> '" << e << "'";
  }
}

TEST(WorldManifest, EveryTruncationAndRandomCorruptionIsAnError) {
  const std::string good =
      "{\n  \"format\": \"lfgi-world\",\n  \"version\": 1,\n  \"generator\": \"synthetic\",\n  \"seed\": 3,\n"
      "  \"size_m\": 64.0,\n  \"cell_m\": 32.0,\n  \"cells_x\": 2,\n  \"cells_z\": 2\n}\n";
  ASSERT_EQ(manifestError(good), "");
  for (size_t len = 0; len + 1 < good.size(); ++len) {  // without the final newline it is still valid
    const std::string e = manifestError(std::string_view(good).substr(0, len));
    EXPECT_EQ(e.rfind("w/world.json: ", 0), 0u) << "length " << len << ": '" << e << "'";
  }
  std::mt19937 rng(10);
  size_t rejected = 0, accepted = 0;
  for (int t = 0; t < 2000; ++t) {
    std::string bad = good;
    for (int k = 0; k < 1 + t % 3; ++k) bad[rng() % bad.size()] ^= char(1u << (rng() % 8));
    const std::string e = manifestError(bad);
    if (e.empty()) {
      ++accepted;  // e.g. a flipped bit in "generator" or whitespace: still a valid manifest
    } else {
      ++rejected;
      ASSERT_EQ(e.rfind("w/world.json: ", 0), 0u) << "trial " << t << ": '" << e << "'";
    }
  }
  std::printf("[ measure  ] manifest bit flips: %zu rejected, %zu still valid\n", rejected, accepted);
}

}  // namespace
}  // namespace lfgi::worlds
