// The public runtime API (include/lfgi/runtime.h) as a host sees it: the test binary links lfgi::runtime
// (the shared library) for the API and lfgi_core / lfgi_worlds only to write its test world.
#include "lfgi/runtime.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/cell_file.h"
#include "core/half.h"
#include "worlds/world_cells.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kSeed = 5;
constexpr float kCell = 32.0f;
constexpr float kRadiance = 0.75f;  // every cell's SH: constant radiance -> irradiance pi * L

// A 2 x 2 world of 32 m cells, each an SH-only cell (4 x 2 x 4 probes, 7 m apart) of constant radiance.
fs::path makeWorld(const std::string& name) {
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "runtime" / name;
  fs::remove_all(dir);
  fs::create_directories(dir / "baked" / "cells");
  worlds::writeWorldManifest(dir, worlds::WorldParams{kSeed, 2 * kCell, kCell});
  const float l0 =
      kRadiance / 0.28209479f;  // SH L0 coefficient of constant radiance (Y00 = 1 / (2 sqrt(pi)))
  for (int z = 0; z < 2; ++z)
    for (int x = 0; x < 2; ++x) {
      CellFile c;
      c.worldSeed = kSeed;
      c.cellX = x;
      c.cellZ = z;
      c.grid.origin = {float(x) * kCell + 2.0f, 0.5f, float(z) * kCell + 2.0f};
      c.grid.spacing = glm::vec3(7.0f);
      c.grid.dims = {4, 2, 4};
      c.fallback.shHalf.assign(12, floatToHalfClamped(0.0f));
      for (int ch = 0; ch < 3; ++ch) c.fallback.shHalf[size_t(ch)] = floatToHalfClamped(l0);
      c.stats.model = "no network: SH L1";
      writeCellFile(dir / "baked" / "cells" / fmt::format("cell_{}_{}.vdb", x, z), c);
    }
  return dir;
}

std::string errorOf(const RuntimeConfig& c) {
  try {
    Runtime::open(c);
  } catch (const RuntimeError& e) {
    return e.what();
  }
  return "";
}

TEST(Runtime, StreamsABakedWorldAndSamplesItsLight) {
  RuntimeConfig c;
  c.world = makeWorld("stream");
  c.ioThreads = 0;  // deterministic: loads inline in update()
  c.decodeRadius = 40.0f;
  c.keepRadius = 60.0f;
  const std::unique_ptr<Runtime> rt = Runtime::open(c);
  EXPECT_EQ(rt->worldSizeX(), 2 * kCell);
  EXPECT_EQ(rt->cellSize(), kCell);
  Frame f;
  f.position[0] = 20.0f, f.position[1] = 10.0f, f.position[2] = 20.0f;
  FrameReport r;
  for (int i = 0; i < 120; ++i) r = rt->update(f);
  EXPECT_EQ(r.residentCells, 4);
  EXPECT_EQ(r.failedCells, 0);
  EXPECT_GT(r.bytesResident, 0u);
  EXPECT_LE(r.bytesResident, c.memoryBudgetBytes);
  const std::vector<float> pos = {10.0f, 2.0f, 10.0f, 50.0f, 3.0f, 40.0f, -100.0f, 1.0f, 5.0f};
  const std::vector<float> nrm = {0.0f, 1.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
  std::vector<GiSample> out(3);
  rt->sample(pos, nrm, out);
  for (int i = 0; i < 2; ++i) {
    EXPECT_FALSE(out[size_t(i)].missing);
    EXPECT_LT(out[size_t(i)].fallbackWeight, 1e-6f);  // faded in: all from the decoded cells
    for (float e : out[size_t(i)].irradiance) EXPECT_NEAR(e, std::numbers::pi_v<float> * kRadiance, 0.01f);
  }
  EXPECT_TRUE(out[2].missing);  // outside the world
  // Sizes are checked.
  std::vector<GiSample> two(2);
  EXPECT_THROW(rt->sample(pos, nrm, two), RuntimeError);
  f.position[0] = std::nanf("");
  EXPECT_THROW(rt->update(f), RuntimeError);
}

TEST(Runtime, BadInputsGiveNamedErrors) {
  RuntimeConfig c;
  c.world = "/nonexistent/lfgi-world";
  EXPECT_NE(errorOf(c).find("/nonexistent/lfgi-world: no world.json"), std::string::npos) << errorOf(c);
  c.world = makeWorld("errors");
  RuntimeConfig b = c;
  b.memoryBudgetBytes = 0;
  EXPECT_NE(errorOf(b).find("memoryBudgetBytes is 0"), std::string::npos) << errorOf(b);
  b = c;
  b.memoryBudgetBytes = 16;  // less than one cell
  EXPECT_NE(errorOf(b), "");
  b = c;
  b.decodeRadius = -1.0f;
  EXPECT_NE(errorOf(b).find("decodeRadius = -1"), std::string::npos) << errorOf(b);
  b = c;
  b.keepRadius = 10.0f;
  EXPECT_NE(errorOf(b).find("keepRadius = 10"), std::string::npos) << errorOf(b);
  b = c;
  b.ioThreads = 65;
  EXPECT_NE(errorOf(b).find("ioThreads = 65"), std::string::npos) << errorOf(b);
  // A world that was never baked.
  fs::remove_all(c.world / "baked");
  EXPECT_NE(errorOf(c).find("no cell-file directory"), std::string::npos) << errorOf(c);
}

TEST(Runtime, ReportsItsVersion) {
  EXPECT_STREQ(runtimeVersion(), LFGI_TEST_PROJECT_VERSION);
}

}  // namespace
}  // namespace lfgi
