#include "core/region_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>
#include <thread>

#include "core/error.h"
#include "core/file_util.h"
#include "core/half.h"
#include "generator_test_util.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

enum class Kind { Network, NetworkAllActive, NoNetwork, Int8Fallback };

// A cell of region (0, 0) at (x, z): 2x2x3 probes (some disabled unless NetworkAllActive), per-cell
// statistics and hashes as a bake writes them.
CellFile regionCell(int x, int z, Kind kind, glm::ivec3 dims = {3, 2, 2}, GeneratorArch arch = {}) {
  std::mt19937 rng(uint32_t(7 + x * 13 + z * 101));
  CellFile c;
  c.worldSeed = 0xfedcba9876543210ull;
  c.cellX = x;
  c.cellZ = z;
  c.inputHash = 0x0123456789abcdefull * uint64_t(1 + x + 8 * z);
  c.grid.spacing = {8.0f, 4.0f, 8.0f};
  c.grid.dims = dims;
  c.grid.origin = {64.0f * float(x) + 4.0f, 0.5f, 64.0f * float(z) + 4.0f};
  if (kind != Kind::NetworkAllActive) {
    c.active.assign(size_t(c.grid.probeCount()), 1);
    for (size_t i = size_t(2 + (x + z) % 3); i < c.active.size(); i += 5) c.active[i] = 0;
  }
  const int64_t n = c.activeProbeCount();
  const bool network = kind == Kind::Network || kind == Kind::NetworkAllActive;
  if (network) {
    if (arch.convChannels.empty() || arch.latentDim == 0) {
      arch.latentDim = 8;
      arch.convChannels = {8, 6, kGeneratorChannels};
    }
    CellGenerator g;
    g.weights = quantizeWeights(test::uniformRandomWeights(arch, rng), WeightPrecision::Int8);
    std::vector<float> lat(size_t(n * arch.latentDim));
    for (float& v : lat) v = std::normal_distribution<float>(0.0f, 1.0f)(rng);
    g.latents = quantizeLatents(lat, arch.latentDim, kind == Kind::Network ? 8 : 4);
    c.generator = std::move(g);
  }
  c.outputScale = {3.5f + float(x), 96.0f};
  c.fallback.kind = network ? CellFallback::Kind::PerCell : CellFallback::Kind::PerProbe;
  c.fallback.keyHours = {8.0f, 12.0f, 17.5f};
  c.fallback.keyOvercast = {0.0f, 0.0f, 0.0f};
  const size_t entries = network ? 1 : size_t(n);
  for (size_t i = 0; i < 3 * entries * 12; ++i)
    c.fallback.shHalf.push_back(floatToHalfClamped(0.25f * float((i + size_t(x)) % 7) + 0.125f));
  if (kind == Kind::Int8Fallback) quantizeFallbackToInt8(c.fallback);
  c.stats.errorAchieved = 0.04 + 0.001 * x;
  c.stats.errorTarget = 0.05;
  c.stats.trainingSeconds = 12.75 + z;
  c.stats.model = network ? "L8 C8-6 test" : "no network: SH L1";
  return c;
}

std::vector<CellFile> mixedRegion() {
  return {regionCell(0, 0, Kind::Network), regionCell(1, 0, Kind::NetworkAllActive),
          regionCell(0, 1, Kind::NoNetwork), regionCell(1, 1, Kind::Int8Fallback)};
}

// The first error reading the whole region (open + every cell), or "".
std::string errorOf(std::span<const std::byte> bytes, const std::string& name) {
  try {
    RegionFile f = RegionFile::open(bytes, name);
    for (size_t i = 0; i < f.cells().size(); ++i) f.readCell(i);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(RegionFile, EachCellReadsBackAsTheCellFileWrittenAlone) {
  const std::vector<CellFile> cells = mixedRegion();
  const std::vector<std::byte> bytes = encodeRegionFile({0, 0}, 2, cells);
  const RegionFile f = RegionFile::open(bytes, "r.lfgr");
  ASSERT_EQ(f.cells().size(), 4u);
  std::vector<CellFile> back;
  for (const CellFile& c : cells) {
    const int i = f.find(c.cellX, c.cellZ);
    ASSERT_GE(i, 0);
    back.push_back(f.readCell(size_t(i)));
    // Field for field the same cell: its cell file is byte-identical to the original's.
    EXPECT_EQ(encodeCellFile(back.back()), encodeCellFile(c)) << c.cellX << "," << c.cellZ;
  }
  EXPECT_EQ(f.find(2, 0), -1);
  // And the region re-encodes bit-exactly, whatever order the cells come in.
  std::reverse(back.begin(), back.end());
  EXPECT_EQ(encodeRegionFile({0, 0}, 2, back), bytes);
  std::printf("4 cells: region %zu B, the four cell files %zu B\n", bytes.size(),
              encodeCellFile(cells[0]).size() + encodeCellFile(cells[1]).size() +
                  encodeCellFile(cells[2]).size() + encodeCellFile(cells[3]).size());
}

TEST(RegionFile, OneCellRegionAndNegativeRegionsRoundTrip) {
  CellFile c = regionCell(0, 0, Kind::Network);
  c.cellX = -9;  // region (-2, 3) of 8 x 8 cells holds x in -16 .. -9, z in 24 .. 31
  c.cellZ = 31;
  c.grid.origin = {-9 * 64.0f + 4.0f, 0.5f, 31 * 64.0f + 4.0f};
  const std::vector<std::byte> bytes = encodeRegionFile({-2, 3}, 8, std::span(&c, 1));
  const RegionFile f = RegionFile::open(bytes, "one.lfgr");
  EXPECT_EQ(f.region(), glm::ivec2(-2, 3));
  ASSERT_EQ(f.find(-9, 31), 0);
  EXPECT_EQ(encodeCellFile(f.readCell(0)), encodeCellFile(c));
}

TEST(RegionFile, EveryTruncationIsRejectedNamingTheFile) {
  const std::vector<std::byte> bytes = encodeRegionFile({0, 0}, 2, mixedRegion());
  for (size_t len = 0; len < bytes.size(); ++len) {
    const std::string e = errorOf(std::span(bytes).first(len), "cut.lfgr");
    ASSERT_EQ(e.rfind("cut.lfgr: ", 0), 0u) << "length " << len << ": '" << e << "'";
  }
  std::vector<std::byte> longer = bytes;
  longer.push_back(std::byte{0});
  EXPECT_NE(errorOf(longer, "long.lfgr").find("padded"), std::string::npos);
}

TEST(RegionFile, EveryBitFlipIsRejectedNamingTheFileAndTheCell) {
  const std::vector<std::byte> bytes = encodeRegionFile({0, 0}, 2, mixedRegion());
  const uint64_t head = RegionFile::open(bytes, "r").headBytes();
  size_t inRecords = 0;
  for (size_t pos = 0; pos < bytes.size(); ++pos) {
    std::vector<std::byte> b = bytes;
    b[pos] ^= std::byte(1u << (pos % 8));
    const std::string e = errorOf(b, "flip.lfgr");
    ASSERT_EQ(e.rfind("flip.lfgr: ", 0), 0u) << "byte " << pos << ": '" << e << "'";
    if (pos >= head) {  // a record's flip names its cell
      ASSERT_EQ(e.rfind("flip.lfgr: cell (", 0), 0u) << "byte " << pos << ": '" << e << "'";
      ++inRecords;
    }
  }
  EXPECT_GT(inRecords, bytes.size() / 2);
}

TEST(RegionFile, IntactButWrongCellsNameTheCellAndTheProblem) {
  const std::vector<CellFile> cells = mixedRegion();
  const struct {
    detail::CellFileOverride o;
    std::string expect;
  } cases[] = {
      {{"lfgi_format_version", 99, ""}, "cell (0, 0): cell file format version 99"},
      {{"probe_count", 3, ""}, "probe_count = 3, but"},
      {{"exposure", 0, "nan"}, "field 'exposure'"},
      {{"cell_x", 5, ""}, "the record holds cell (5, 0)"},
      {{"probe_mask", 0, std::string("\x05", 1)}, "probe_mask"},
  };
  for (const auto& c : cases) {
    // probe_mask: only in cells that have one.
    const std::vector<CellFile> some =
        c.o.field == "probe_mask" ? std::vector<CellFile>{cells[0], cells[2]} : cells;
    const std::vector<std::byte> bytes = detail::encodeRegionFileWithOverrides({0, 0}, 2, some, {&c.o, 1});
    const std::string e = errorOf(bytes, "bad.lfgr");
    EXPECT_EQ(e.rfind("bad.lfgr: cell (", 0), 0u) << c.o.field << ": '" << e << "'";
    EXPECT_NE(e.find(c.expect), std::string::npos) << c.o.field << ": '" << e << "'";
  }
}

TEST(RegionFile, WriterRejectsCellsOutsideTheRegionOrTwice) {
  std::vector<CellFile> cells = mixedRegion();
  EXPECT_THROW(encodeRegionFile({1, 0}, 2, cells), Error);  // cells of region (0, 0)
  EXPECT_THROW(encodeRegionFile({0, 0}, 0, cells), Error);
  EXPECT_THROW(encodeRegionFile({0, 0}, 2, {}), Error);
  cells.push_back(cells[0]);
  try {
    encodeRegionFile({0, 0}, 2, cells);
    ADD_FAILURE() << "a cell given twice was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("given twice"), std::string::npos) << e.what();
  }
}

TEST(RegionFile, ContainerCostPerCellOfAnEightByEightRegionIsUnder200Bytes) {
  // 64 default-sized cells (16 x 8 x 16 probes at 4 m, L16 C 32-16-11 int8, 3 lighting keys): everything
  // that is not weights, latents, fallback or probe mask is the container.
  GeneratorArch arch;  // defaults
  std::vector<CellFile> cells;
  for (int z = 0; z < 8; ++z)
    for (int x = 0; x < 8; ++x) {
      CellFile c = regionCell(x, z, Kind::Network, {16, 8, 16}, arch);
      c.grid.spacing = glm::vec3(4.0f);
      cells.push_back(std::move(c));
    }
  const std::vector<std::byte> bytes = encodeRegionFile({0, 0}, 8, cells);
  const RegionFile f = RegionFile::open(bytes, "r8.lfgr");
  const RegionFileBytes b = f.bytesByPart();
  EXPECT_EQ(b.total(), bytes.size());
  size_t cellFileContainer = 0;  // the same cells written alone: OpenVDB metadata and topology
  for (const CellFile& c : cells) {
    CellFileBytes parts;
    decodeCellFile(encodeCellFile(c), "alone", &parts);
    cellFileContainer += parts.metadata();
  }
  const double container = b.containerPerCell(cells.size());
  std::printf(
      "8x8 region: %zu B = head %llu + records %llu; payload %llu, masks %llu; container %.1f B/cell "
      "(cell files alone: %.0f B/cell of metadata + topology)\n",
      bytes.size(), (unsigned long long)b.head, (unsigned long long)b.records, (unsigned long long)b.payload,
      (unsigned long long)b.topology, container, double(cellFileContainer) / 64.0);
  EXPECT_LE(container, 200.0);
  EXPECT_GT(container, 0.0);
}

TEST(RegionFile, DiskReadsOneRangePerCellAndConcurrentReadsAgree) {
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "region_file";
  fs::create_directories(dir);
  const std::vector<CellFile> cells = mixedRegion();
  const std::vector<std::byte> bytes = encodeRegionFile({0, 0}, 2, cells);
  const fs::path path = dir / regionFileName({0, 0}, bytes);
  writeFileAtomic(path, bytes);
  EXPECT_EQ(path.filename().string().rfind("region_0_0_", 0), 0u);
  const RegionFile f = RegionFile::open(path);
  std::vector<std::thread> threads;
  std::vector<int> ok(8, 0);
  for (int t = 0; t < 8; ++t)
    threads.emplace_back([&, t] {
      const CellFile& c = cells[size_t(t % 4)];
      ok[size_t(t)] = encodeCellFile(f.readCell(size_t(f.find(c.cellX, c.cellZ)))) == encodeCellFile(c);
    });
  for (std::thread& t : threads) t.join();
  for (int t = 0; t < 8; ++t) EXPECT_EQ(ok[size_t(t)], 1) << t;
  try {
    RegionFile::open(dir / "missing.lfgr");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "missing.lfgr").string() + ": ", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace lfgi
