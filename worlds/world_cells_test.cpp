#include "worlds/world_cells.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/file_util.h"

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
  EXPECT_NEAR(surfelArea(cell.surfels) / cell.mesh.totalArea(), 1.0, 0.01);
  EXPECT_EQ(decodeSurfels(cell.surfelBytes, "cell").size(), cell.surfels.size());
  EXPECT_GT(double(s.surfelRawBytes) / double(s.surfelEncodedBytes), 2.0);
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
  writeCell(dir, buildCell(w, {1, 0}));
  EXPECT_TRUE(cellDone(dir, {1, 0}));
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

}  // namespace
}  // namespace lfgi::worlds
