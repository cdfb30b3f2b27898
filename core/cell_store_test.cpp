#include "core/cell_store.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <map>

#include "core/error.h"
#include "core/file_util.h"
#include "core/half.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

// A no-network cell (SH L1 per probe) at (x, z) of a world of 32 m cells.
CellFile storeCell(int x, int z, double trainingSeconds = 1.0) {
  CellFile c;
  c.worldSeed = 11;
  c.cellX = x;
  c.cellZ = z;
  c.inputHash = uint64_t(1000 + x + 100 * z);
  c.grid.origin = {32.0f * float(x) + 8.0f, 1.0f, 32.0f * float(z) + 8.0f};
  c.grid.spacing = glm::vec3(16.0f);
  c.grid.dims = {2, 2, 2};
  c.fallback.kind = CellFallback::Kind::PerProbe;
  for (int i = 0; i < 8 * 12; ++i)
    c.fallback.shHalf.push_back(floatToHalfClamped(0.01f * float(i + x + 3 * z)));
  c.stats.trainingSeconds = trainingSeconds;
  c.stats.model = "no network: SH L1";
  return c;
}

fs::path freshDir(const std::string& name) {
  const fs::path d = fs::path(LFGI_TEST_TMP_DIR) / "cell_store" / name;
  fs::remove_all(d);
  fs::create_directories(d / "cells");
  return d;
}

// A 3 x 3 world, cell (2, 0) missing.
void writeWorld(const fs::path& dir) {
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x)
      if (x != 2 || z != 0) writeCellFile(dir / "cells" / cellFileName({x, z}), storeCell(x, z));
}

std::map<std::string, std::vector<std::byte>> regionFiles(const fs::path& dir) {
  std::map<std::string, std::vector<std::byte>> files;
  for (const auto& f : fs::directory_iterator(dir))
    if (f.path().extension() == ".lfgr") files[f.path().filename().string()] = readFileBytes(f.path());
  return files;
}

TEST(CellStore, RegionsHoldExactlyTheCellFiles) {
  const fs::path dir = freshDir("same");
  writeWorld(dir);
  const PackStats s = packRegions(dir / "cells", dir / "regions", {3, 3}, 2);
  EXPECT_EQ(s.regions, 4);
  EXPECT_EQ(s.cells, 8);
  EXPECT_EQ(s.written, 4);
  EXPECT_TRUE(s.skipped.empty());
  const auto files = openCellFiles(dir / "cells");
  const auto regions = openRegions(dir / "regions");
  EXPECT_STREQ(regions->kind(), "regions");
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) {
      ASSERT_EQ(files->has({x, z}), regions->has({x, z})) << x << "," << z;
      if (!files->has({x, z})) continue;
      EXPECT_EQ(encodeCellFile(regions->read({x, z})), encodeCellFile(files->read({x, z}))) << x << "," << z;
    }
  EXPECT_FALSE(regions->has({2, 0}));
  EXPECT_FALSE(regions->has({5, 0}));
  try {
    regions->read({2, 0});
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cell (2, 0)"), std::string::npos) << e.what();
  }
}

TEST(CellStore, AnEditRewritesOnlyItsRegionAndLeavesEveryOtherByteAlone) {
  const fs::path dir = freshDir("edit");
  writeWorld(dir);
  packRegions(dir / "cells", dir / "regions", {3, 3}, 2);
  const auto before = regionFiles(dir / "regions");
  const PackStats again = packRegions(dir / "cells", dir / "regions", {3, 3}, 2);
  EXPECT_EQ(again.written, 0);
  EXPECT_EQ(again.unchanged, 4);
  EXPECT_EQ(regionFiles(dir / "regions"), before);

  writeCellFile(dir / "cells" / cellFileName({1, 1}), storeCell(1, 1, 99.0));  // a rebaked cell
  const PackStats edit = packRegions(dir / "cells", dir / "regions", {3, 3}, 2);
  EXPECT_EQ(edit.written, 1);
  EXPECT_EQ(edit.unchanged, 3);
  EXPECT_EQ(edit.removed, 1);  // the region's old file
  const auto after = regionFiles(dir / "regions");
  ASSERT_EQ(after.size(), 4u);
  int same = 0;
  for (const auto& [name, bytes] : after) same += before.count(name) && before.at(name) == bytes;
  EXPECT_EQ(same, 3);
  EXPECT_EQ(openRegions(dir / "regions")->read({1, 1}).stats.trainingSeconds, 99.0);
  std::printf("edit of one cell: %llu bytes written (1 region of %zu + regions.json), %d regions untouched\n",
              (unsigned long long)edit.bytesWritten, after.size(), edit.unchanged);
}

TEST(CellStore, CorruptCellFilesAreLeftOutAndNamed) {
  const fs::path dir = freshDir("corrupt");
  writeWorld(dir);
  writeFileAtomic(dir / "cells" / cellFileName({0, 1}), std::string("not a cell"));
  const PackStats s = packRegions(dir / "cells", dir / "regions", {3, 3}, 2);
  ASSERT_EQ(s.skipped.size(), 1u);
  EXPECT_NE(s.skipped[0].find("cell_0_1.vdb"), std::string::npos) << s.skipped[0];
  EXPECT_FALSE(openRegions(dir / "regions")->has({0, 1}));
}

TEST(CellStore, BadIndexesAndSwappedRegionFilesNameTheProblem) {
  const char* good = R"({"format":"lfgi-regions","version":1,"cells_per_side":2,"regions":[)"
                     R"({"x":0,"z":0,"file":"region_0_0_0000000000000000.lfgr","bytes":100,"cells":4}]})";
  EXPECT_EQ(parseRegionIndex(good, "i.json").regions.size(), 1u);
  const std::pair<std::string, std::string> bad[] = {
      {"{", "not valid JSON"},
      {R"({"format":"x","version":1,"cells_per_side":2,"regions":[]})", "format is not"},
      {R"({"format":"lfgi-regions","version":2,"cells_per_side":2,"regions":[]})", "version 2"},
      {R"({"format":"lfgi-regions","version":1,"cells_per_side":0,"regions":[]})", "cells_per_side 0"},
      {R"({"format":"lfgi-regions","version":1,"cells_per_side":2,"regions":[{"x":0,"z":0,"file":"../a.lfgr","bytes":100,"cells":1}]})",
       "not a plain"},
      {R"({"format":"lfgi-regions","version":1,"cells_per_side":2,"regions":[{"x":0,"z":0,"file":"a.lfgr","bytes":100,"cells":5}]})",
       "cells 5"},
      {R"({"format":"lfgi-regions","version":1,"cells_per_side":2,"regions":[{"x":0,"z":0,"file":"a.lfgr","bytes":100}]})",
       "'cells' is missing"},
  };
  for (const auto& [text, expect] : bad) {
    try {
      parseRegionIndex(text, "i.json");
      ADD_FAILURE() << text;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("i.json: ", 0), 0u) << e.what();
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
    }
  }
  // A region file swapped for another region's: the store names the file and both regions.
  const fs::path dir = freshDir("swap");
  writeWorld(dir);
  packRegions(dir / "cells", dir / "regions", {3, 3}, 2);
  const RegionIndex index = readRegionIndex(dir / "regions");
  fs::copy_file(dir / "regions" / index.regions[1].file, dir / "regions" / index.regions[0].file,
                fs::copy_options::overwrite_existing);
  try {
    openRegions(dir / "regions")->read({0, 0});
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(index.regions[0].file), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lfgi
