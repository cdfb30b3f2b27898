#include "bake/bake_records.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/cell_file.h"
#include "core/error.h"
#include "core/half.h"
#include "worlds/world_cells.h"

namespace lfgi::bake {
namespace {

namespace fs = std::filesystem;
using worlds::CellKind;

fs::path freshDir(const char* name) {
  const fs::path d = fs::path(LFGI_TEST_TMP_DIR) / "bake_records" / name;
  fs::remove_all(d);
  fs::create_directories(d / "cells");
  return d;
}

CellBakeRecord makeRecord(worlds::CellCoord c, CellKind kind, double seconds) {
  CellBakeRecord r;
  r.cell = c;
  r.kind = kind;
  r.inputHash = 0xfedcba9876543210ull;
  r.probes = 123;
  r.network = true;
  r.model = "z8 C8-8 int8";
  r.prepareSeconds = 0.25;
  r.captureSeconds = 1.5;
  r.trainingSeconds = 2.75;
  r.totalSeconds = seconds;
  r.bytes = 69000;
  r.host = "node-7";
  r.finishedUtc = "2026-11-26T22:30:00Z";
  return r;
}

TEST(BakeRecords, RecordRoundTripsExactly) {
  const fs::path d = freshDir("round_trip");
  const CellBakeRecord w = makeRecord({3, 1}, CellKind::kPark, 4.625);
  writeCellBakeRecord(d, w);
  EXPECT_TRUE(fs::exists(d / "cells" / "cell_3_1.json"));
  const std::optional<CellBakeRecord> r = readCellBakeRecord(d, {3, 1});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->cell, w.cell);
  EXPECT_EQ(r->kind, w.kind);
  EXPECT_EQ(r->inputHash, w.inputHash);
  EXPECT_EQ(r->probes, w.probes);
  EXPECT_EQ(r->network, w.network);
  EXPECT_EQ(r->model, w.model);
  EXPECT_EQ(r->prepareSeconds, w.prepareSeconds);
  EXPECT_EQ(r->captureSeconds, w.captureSeconds);
  EXPECT_EQ(r->trainingSeconds, w.trainingSeconds);
  EXPECT_EQ(r->totalSeconds, w.totalSeconds);
  EXPECT_EQ(r->bytes, w.bytes);
  EXPECT_EQ(r->host, w.host);
  EXPECT_EQ(r->finishedUtc, w.finishedUtc);
  EXPECT_FALSE(readCellBakeRecord(d, {0, 0}));
}

TEST(BakeRecords, MalformedRecordNamesTheFileAndIsSkippedInBulk) {
  const fs::path d = freshDir("malformed");
  writeCellBakeRecord(d, makeRecord({0, 0}, CellKind::kCity, 2.0));
  std::ofstream(d / "cells" / "cell_1_0.json") << "{\"cell\": [1, 0], \"kind\": \"volcano\"}";
  try {
    (void)readCellBakeRecord(d, {1, 0});
    FAIL() << "expected lfgi::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cell_1_0.json"), std::string::npos) << e.what();
  }
  const std::vector<CellBakeRecord> all = readAllCellBakeRecords(d);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].cell, (worlds::CellCoord{0, 0}));
}

TEST(BakeRecords, FailureMarkerKeepsTheFirstLineAndClears) {
  const fs::path d = freshDir("failure");
  EXPECT_FALSE(readCellBakeFailure(d, {2, 2}));
  writeCellBakeFailure(d, {2, 2}, "cells/cell_2_2.vdb: Is a directory\nsecond line");
  const std::optional<std::string> f = readCellBakeFailure(d, {2, 2});
  ASSERT_TRUE(f);
  EXPECT_EQ(*f, "cells/cell_2_2.vdb: Is a directory");
  clearCellBakeFailure(d, {2, 2});
  EXPECT_FALSE(readCellBakeFailure(d, {2, 2}));
  clearCellBakeFailure(d, {2, 2});  // absent: no error
}

TEST(BakeRecords, CostModelMeansByKindAndFallsBackToTheOverallMean) {
  const std::vector<CellBakeRecord> recs = {
      makeRecord({0, 0}, CellKind::kCity, 10.0), makeRecord({1, 0}, CellKind::kCity, 20.0),
      makeRecord({2, 0}, CellKind::kField, 3.0), makeRecord({3, 0}, CellKind::kSuburb, 7.0)};
  const BakeCostModel m = costModelFromRecords(recs);
  EXPECT_EQ(m.totalSamples, 4u);
  EXPECT_DOUBLE_EQ(m.secondsPerCell(CellKind::kCity), 15.0);
  EXPECT_DOUBLE_EQ(m.secondsPerCell(CellKind::kField), 3.0);
  EXPECT_DOUBLE_EQ(m.secondsPerCell(CellKind::kSuburb), 7.0);
  EXPECT_EQ(m.samples[size_t(CellKind::kPark)], 0u);
  EXPECT_DOUBLE_EQ(m.secondsPerCell(CellKind::kPark), 10.0);  // (10 + 20 + 3 + 7) / 4
  EXPECT_THROW(costModelFromRecords({}), Error);
}

// The 4 x 4 showcase district of every world (worlds/synthetic_world.h): 6 field, 5 suburb, 4 city, 1 park.
TEST(BakeRecords, KindMixOfTheDefaultWorldIsTheShowcaseDistrict) {
  const KindMix mix = worldKindMix(worlds::WorldParams::smallDefault(1));
  EXPECT_EQ(mix.cells, 16u);
  EXPECT_DOUBLE_EQ(mix.km2, 0.065536);
  EXPECT_EQ(mix.cellsByKind[size_t(CellKind::kField)], 6u);
  EXPECT_EQ(mix.cellsByKind[size_t(CellKind::kSuburb)], 5u);
  EXPECT_EQ(mix.cellsByKind[size_t(CellKind::kCity)], 4u);
  EXPECT_EQ(mix.cellsByKind[size_t(CellKind::kPark)], 1u);
}

TEST(BakeRecords, ProjectionIsCountsTimesSecondsOverNodes) {
  const worlds::WorldParams p = worldParamsForArea(100.0, 64.0, 1);
  EXPECT_DOUBLE_EQ(p.sizeM, 156.0 * 64.0);  // 10 km / 64 m = 156.25 cells -> 156
  EXPECT_DOUBLE_EQ(worldParamsForArea(1e-6, 64.0, 1).sizeM, 64.0);
  EXPECT_THROW(worldParamsForArea(0.0, 64.0, 1), Error);

  const BakeCostModel m = costModelFromRecords(
      {makeRecord({0, 0}, CellKind::kCity, 10.0), makeRecord({1, 0}, CellKind::kField, 2.0),
       makeRecord({2, 0}, CellKind::kSuburb, 4.0), makeRecord({3, 0}, CellKind::kPark, 6.0)});
  const worlds::WorldParams small = worlds::WorldParams::smallDefault(1);
  const BakeProjection proj = projectBake(m, small);
  EXPECT_DOUBLE_EQ(proj.cellSeconds, 6 * 2.0 + 5 * 4.0 + 4 * 10.0 + 1 * 6.0);
  EXPECT_DOUBLE_EQ(proj.hours(1), 78.0 / 3600.0);
  EXPECT_DOUBLE_EQ(proj.hours(32), 78.0 / 32.0 / 3600.0);
  const BakeProjection big = projectBake(m, p);
  EXPECT_EQ(big.mix.cells, 156u * 156u);
  size_t sum = 0;
  for (size_t c : big.mix.cellsByKind) sum += c;
  EXPECT_EQ(sum, big.mix.cells);
}

// Missing / corrupt / failed need no input hash; done and stale compare the file's hash with cellInputHash.
TEST(BakeRecords, WorldBakeStatusClassifiesEveryCell) {
  const fs::path d = freshDir("status");
  const worlds::SyntheticWorld world(worlds::WorldParams{3, 64.0, 32.0});  // 2 x 2 cells
  WorldBakeSettings settings;
  settings.resolution = 8;
  settings.keys = "12";
  auto writeFile = [&](worlds::CellCoord c, uint64_t hash) {
    CellFile f;
    f.worldSeed = 3;
    f.cellX = c.x;
    f.cellZ = c.z;
    f.inputHash = hash;
    f.grid.origin = {float(c.x) * 32.0f, 0.0f, float(c.z) * 32.0f};
    f.grid.spacing = {8.0f, 4.0f, 8.0f};
    f.grid.dims = {2, 2, 2};
    f.active.assign(size_t(f.grid.probeCount()), 1);
    f.stats.model = "no network: SH L1";
    f.fallback.kind = CellFallback::Kind::PerCell;
    for (int k = 0; k < 12; ++k) f.fallback.shHalf.push_back(floatToHalfClamped(0.5f));
    writeCellFile(cellFilePath(d, c), f);
  };
  writeFile({0, 0}, cellInputHash(world, {0, 0}, settings));      // done
  writeFile({1, 0}, cellInputHash(world, {1, 0}, settings) ^ 1);  // stale
  std::ofstream(cellFilePath(d, {0, 1})) << "not a cell file";    // corrupt
  writeCellBakeFailure(d, {1, 1}, "boom");                        // failed, no file
  const std::vector<CellStatusEntry> s =
      worldBakeStatus(world, {{0, 0}, {1, 0}, {0, 1}, {1, 1}}, settings, d, false);
  ASSERT_EQ(s.size(), 4u);
  EXPECT_EQ(s[0].status, CellStatus::Done);
  EXPECT_EQ(s[1].status, CellStatus::Stale);
  EXPECT_EQ(s[2].status, CellStatus::Corrupt);
  EXPECT_NE(s[2].detail.find("cell_0_1.vdb"), std::string::npos) << s[2].detail;
  EXPECT_EQ(s[3].status, CellStatus::Failed);
  EXPECT_EQ(s[3].detail, "boom");
  fs::remove(cellFailurePath(d, {1, 1}));
  EXPECT_EQ(worldBakeStatus(world, {{1, 1}}, settings, d, false)[0].status, CellStatus::Missing);
  // A failure marker beside a stale file: failed (the last bake of it did not succeed).
  writeCellBakeFailure(d, {1, 0}, "later failure");
  EXPECT_EQ(worldBakeStatus(world, {{1, 0}}, settings, d, false)[0].status, CellStatus::Failed);
  EXPECT_EQ(s[0].kind, world.cellKind({0, 0}));
  // A directory where the cell file should be: corrupt, with a message naming it (not bad_alloc).
  fs::create_directories(cellFilePath(d, {1, 1}) / "blocker");
  const CellStatusEntry dir = worldBakeStatus(world, {{1, 1}}, settings, d, false)[0];
  EXPECT_EQ(dir.status, CellStatus::Corrupt);
  EXPECT_NE(dir.detail.find("is a directory"), std::string::npos) << dir.detail;
}

}  // namespace
}  // namespace lfgi::bake
