#include "streaming/cell_file_source.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include <fmt/format.h>

#include "core/cell_store.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/octahedral.h"
#include "core/probe_codecs.h"
#include "core/quantize.h"
#include "core/region_file.h"
#include "generator_test_util.h"
#include "gpu/context.h"
#include "streaming/streaming_manager.h"
#include "worlds/world_cells.h"

namespace lfgi::streaming {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kSeed = 7;
constexpr float kCell = 64.0f;

enum class Kind { Stored, Position, ShPerCell, ShPerProbe };

Kind kindOf(int x, int z) {
  if (x == 0 && z == 0) return Kind::Position;
  if (x == 2 && z == 2) return Kind::ShPerProbe;
  return (x + z) % 2 == 0 ? Kind::Stored : Kind::ShPerCell;
}

void pushSh(std::vector<uint16_t>& h, glm::vec3 dc, glm::vec3 dir) {
  const glm::vec3 c[4] = {dc, dir.y * dc, dir.z * dc, dir.x * dc};
  for (const glm::vec3& v : c)
    for (int k = 0; k < 3; ++k) h.push_back(floatToHalfClamped(v[k]));
}

// A cell of 4 x 2 x 4 probes, 16 m apart; the centre cell has two probes disabled.
CellFile makeCell(int x, int z) {
  std::mt19937 rng(unsigned(100 + 10 * z + x));
  CellFile c;
  c.worldSeed = kSeed;
  c.cellX = x;
  c.cellZ = z;
  c.inputHash = uint64_t(x * 31 + z);
  c.grid.origin = {float(x) * kCell, 0.5f, float(z) * kCell};
  c.grid.spacing = glm::vec3(16.0f);
  c.grid.dims = {4, 2, 4};
  if (x == 1 && z == 1) {
    c.active.assign(32, 1);
    c.active[5] = c.active[17] = 0;
  }
  const Kind kind = kindOf(x, z);
  const int64_t n = c.activeProbeCount();
  if (kind == Kind::Stored || kind == Kind::Position) {
    GeneratorArch a;
    a.latentDim = 4;
    a.convChannels = {8, kGeneratorChannels};  // 8 x 8 maps
    if (kind == Kind::Position) {
      a.latentSource = LatentSource::PositionFourier;
      a.fourierOctaves = 1;
      a.latentDim = 6;
    }
    CellGenerator g;
    g.weights = quantizeWeights(test::uniformRandomWeights(a, rng, 0.2f), WeightPrecision::Int8);
    if (kind == Kind::Stored)
      g.latents =
          quantizeLatents(test::randomLatents(size_t(n), a.latentDim, unsigned(x + 7 * z)), a.latentDim, 8);
    c.generator = std::move(g);
  }
  c.outputScale = {2.0f, 48.0f};
  const glm::vec3 dc(0.6f + 0.1f * float(x), 0.5f + 0.1f * float(z), 0.55f);
  if (kind == Kind::ShPerProbe) {
    c.fallback.kind = CellFallback::Kind::PerProbe;
    for (int64_t i = 0; i < n; ++i)
      pushSh(c.fallback.shHalf, dc * (1.0f + 0.05f * float(i)), {0.1f, 0.3f, -0.1f});
  } else {
    pushSh(c.fallback.shHalf, dc, {0.05f, 0.25f, 0.0f});
  }
  c.stats.model = c.generator ? "test generator" : "no network: SH L1";
  return c;
}

// A 3 x 3 world of 64 m cells with every cell file written.
fs::path makeWorld(const std::string& name) {
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "cell_file_source" / name;
  fs::remove_all(dir);
  fs::create_directories(dir / "baked" / "cells");
  worlds::writeWorldManifest(dir, worlds::WorldParams{kSeed, 3 * kCell, kCell});
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) writeCellFile(dir / "baked" / "cells" / cellFileName({x, z}), makeCell(x, z));
  return dir;
}

CellFileSourceOptions options(const fs::path& world) {
  CellFileSourceOptions o;
  o.worldDir = world;
  return o;
}

fs::path cellFile(const fs::path& world, int x, int z) {
  return world / "baked" / "cells" / cellFileName({x, z});
}

void flipByte(const fs::path& file, size_t at) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  ASSERT_TRUE(f.good());
  f.seekg(std::streamoff(at));
  char b = 0;
  f.read(&b, 1);
  b = char(b ^ 0x10);
  f.seekp(std::streamoff(at));
  f.write(&b, 1);
}

bool sameBits(const float* a, const float* b, size_t n) {
  return std::memcmp(a, b, n * sizeof(float)) == 0;
}

TEST(CellFileSource, LoadEqualsADirectDecode) {
  const fs::path world = makeWorld("direct");
  CellFileSource source(options(world));
  EXPECT_EQ(source.validCells(), 9);
  EXPECT_EQ(source.layout().cells, glm::ivec2(3, 3));
  EXPECT_EQ(source.layout().cellSize, kCell);
  source.setTimeOfDay(15.5f);
  size_t largest = 0;
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) {
      SCOPED_TRACE(fmt::format("cell {},{}", x, z));
      const CellFile file = readCellFile(cellFile(world, x, z));
      const ShL1 cellSh = cellFileFallback(file, 15.5f, 0.0f);
      const ShL1 fb = source.fallback({x, z});
      for (int k = 0; k < 4; ++k) EXPECT_EQ(fb.c[size_t(k)], cellSh.c[size_t(k)]);
      ProbeField f;
      source.load({x, z}, f);
      // + the room a slot keeps for the probes' relocation offsets (set by VIR visibility on load)
      largest = std::max(largest, f.bytes() + sizeof(glm::vec3) * size_t(f.probeCount()));
      ASSERT_EQ(f.resolution, 8);
      ASSERT_EQ(f.irradianceResolution, 4);
      ASSERT_EQ(f.probeCount(), 32);
      ASSERT_NO_THROW(f.validate());
      const size_t tn = 64, tm = 16;
      const int64_t A = file.activeProbeCount();
      if (file.generator) {
        // The direct route: core's dequantize + decodeProbeField over the active probes, deriveIrradiance.
        const GeneratorWeights w = dequantizeWeights(file.generator->weights);
        GeneratorCpu dec(w);
        std::vector<float> z8;
        if (w.arch.latentSource == LatentSource::Stored) {
          z8 = dequantizeLatents(file.generator->latents);
        } else {
          for (int64_t i = 0; i < 32; ++i) {
            const glm::vec3 p = file.grid.probePosition(file.grid.probeCoord(i));
            const glm::vec3 q = (p - file.grid.origin) / (file.grid.boxMax() - file.grid.origin);
            z8.resize(z8.size() + 6);
            positionLatent(q, 1, std::span<float>(z8).last(6));
          }
        }
        ProbeField d;
        d.grid.dims = {int(A), 1, 1};
        d.resolution = 8;
        d.irradianceResolution = 4;
        const auto cond = conditioningVector(15.5f, 0.0f);
        decodeProbeField(dec, z8, cond, file.outputScale, d);
        deriveIrradiance(d);
        int64_t k = 0;
        for (int64_t i = 0; i < 32; ++i) {
          if (!f.isActive(i)) continue;
          EXPECT_TRUE(sameBits(&f.radiance[size_t(i) * tn * 3], &d.radiance[size_t(k) * tn * 3], tn * 3))
              << i;
          EXPECT_TRUE(sameBits(&f.distance[size_t(i) * tn * 2], &d.distance[size_t(k) * tn * 2], tn * 2))
              << i;
          for (size_t t = 0; t < tm * 3; ++t) {
            const float want = d.irradiance[size_t(k) * tm * 3 + t];
            EXPECT_NEAR(f.irradiance[size_t(i) * tm * 3 + t], want, 1e-5f * std::abs(want) + 1e-6f) << i;
          }
          ++k;
        }
        EXPECT_EQ(k, A);
      }
      // SH-evaluated probes: every probe of an SH-only cell, the disabled probes of a generator cell.
      int64_t k = 0;
      for (int64_t i = 0; i < 32; ++i) {
        const bool own = file.fallback.kind == CellFallback::Kind::PerProbe && f.isActive(i);
        if (file.generator && f.isActive(i)) {
          ++k;
          continue;
        }
        ShL1 sh = cellSh;
        if (own)
          for (int b = 0; b < 4; ++b)
            for (int ch = 0; ch < 3; ++ch)
              sh.c[size_t(b)][ch] =
                  halfToFloat(file.fallback.shHalf[size_t(k) * 12 + size_t(b) * 3 + size_t(ch)]);
        for (int t = 0; t < 16; ++t) {
          const glm::vec3 e = shIrradiance(sh, octTexelDirection(t % 4, t / 4, 4));
          EXPECT_EQ(f.irradiance[size_t(i) * tm * 3 + size_t(t) * 3], std::max(e.x, 0.0f)) << i;
        }
        EXPECT_EQ(f.distance[size_t(i) * tn * 2], 48.0f);
        if (f.isActive(i)) ++k;
      }
      // A second load into the same field reuses its arrays.
      const float* before = f.radiance.data();
      source.load({x, z}, f);
      EXPECT_EQ(f.radiance.data(), before);
    }
  EXPECT_EQ(source.maxCellBytes(), largest);
  EXPECT_EQ(source.loads(), 18u);
}

// More active probes than one staging chunk (>= 1024): the chunked decode equals one decodeProbeField
// over all active probes, bit for bit, and disabled probes between chunks land in the right places.
TEST(CellFileSource, ChunkedDecodeOfALargeCellEqualsOneDecode) {
  CellFile c = makeCell(2, 0);  // a stored-latent cell
  ASSERT_TRUE(c.generator.has_value());
  c.grid.dims = {16, 6, 16};
  c.grid.spacing = glm::vec3(4.0f);
  c.active.assign(size_t(c.grid.probeCount()), 1);
  for (size_t i = 0; i < c.active.size(); i += 7) c.active[i] = 0;
  const int64_t A = c.activeProbeCount();
  ASSERT_GT(A, 1024 + 256);
  const GeneratorWeights w = dequantizeWeights(c.generator->weights);
  c.generator->latents =
      quantizeLatents(test::randomLatents(size_t(A), w.arch.latentDim, 5), w.arch.latentDim, 8);
  ProbeField f;
  decodeCellField(c, 9.0f, 0.25f, 0, 8, f);
  GeneratorCpu dec(w);
  ASSERT_LT(dec.chunkProbes(), size_t(A));
  ProbeField d;
  d.grid.dims = {int(A), 1, 1};
  d.resolution = 8;
  const auto cond = conditioningVector(9.0f, 0.25f);
  decodeProbeField(dec, dequantizeLatents(c.generator->latents), cond, c.outputScale, d);
  int64_t k = 0;
  for (int64_t i = 0; i < c.grid.probeCount(); ++i) {
    if (!f.isActive(i)) {
      EXPECT_EQ(f.distance[size_t(i) * 128], c.outputScale.range) << i;
      continue;
    }
    ASSERT_TRUE(sameBits(&f.radiance[size_t(i) * 192], &d.radiance[size_t(k) * 192], 192)) << i;
    ASSERT_TRUE(sameBits(&f.distance[size_t(i) * 128], &d.distance[size_t(k) * 128], 128)) << i;
    ++k;
  }
  EXPECT_EQ(k, A);
}

TEST(CellFileSource, RelightReDecodesGeneratorCellsUnderTheNewTimeOfDay) {
  const fs::path world = makeWorld("relight");
  CellFileSource source(options(world));
  source.setTimeOfDay(8.0f);
  ProbeField gen, sh, fresh;
  source.load({1, 1}, gen);
  source.load({1, 0}, sh);  // no network
  const std::vector<float> morning = gen.irradiance, shBefore = sh.irradiance;
  const ProbeField morningField = gen;
  const float* data = gen.radiance.data();
  EXPECT_TRUE(source.relight({1, 1}, gen, 16.0f));
  EXPECT_EQ(gen.radiance.data(), data);  // in place
  source.setTimeOfDay(16.0f);
  source.load({1, 1}, fresh);
  EXPECT_EQ(gen.irradiance, fresh.irradiance);
  EXPECT_EQ(gen.radiance, fresh.radiance);
  EXPECT_NE(gen.irradiance, morning);  // the conditioning matters
  EXPECT_TRUE(source.relight({1, 0}, sh, 16.0f));
  EXPECT_EQ(sh.irradiance, shBefore);
  // relightInto (the manager's asynchronous relight): the staging field equals a fresh load at the new
  // time of day, the resident field it reads is untouched; an SH-only cell is copied.
  ProbeField staged, stagedSh;
  source.relightInto({1, 1}, morningField, staged, 16.0f);
  EXPECT_EQ(staged.irradiance, fresh.irradiance);
  EXPECT_EQ(staged.radiance, fresh.radiance);
  EXPECT_EQ(staged.distance, fresh.distance);
  EXPECT_EQ(morningField.irradiance, morning);
  source.relightInto({1, 0}, sh, stagedSh, 16.0f);
  EXPECT_EQ(stagedSh.irradiance, shBefore);
  EXPECT_EQ(stagedSh.grid.dims, sh.grid.dims);
  // A file corrupted after the load: the relight fails and the cell keeps its lighting.
  flipByte(cellFile(world, 1, 1), 400);
  EXPECT_THROW(source.relightInto({1, 1}, gen, staged, 20.0f), Error);
  EXPECT_FALSE(source.relight({1, 1}, gen, 20.0f));
  EXPECT_EQ(gen.irradiance, fresh.irradiance);
}

TEST(CellFileSource, RegionsStreamTheSameCellsAsTheCellFiles) {
  const fs::path world = makeWorld("regions");
  fs::remove(cellFile(world, 2, 2));  // a missing cell stays missing in its region
  const PackStats packed = packRegions(world / "baked" / "cells", world / "baked" / "regions", {3, 3}, 2);
  EXPECT_EQ(packed.cells, 8);
  CellFileSourceOptions fromFiles = options(world);
  fromFiles.storage = CellStorage::CellFiles;
  CellFileSource files(fromFiles);
  CellFileSource regions(options(world));  // Auto: regions.json is there
  EXPECT_STREQ(regions.store().kind(), "regions");
  EXPECT_STREQ(files.store().kind(), "cell files");
  EXPECT_EQ(regions.validCells(), 8);
  EXPECT_EQ(regions.missingCells(), 1);
  EXPECT_EQ(regions.maxCellBytes(), files.maxCellBytes());
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) {
      const ShL1 a = files.fallback({x, z}), b = regions.fallback({x, z});
      for (int k = 0; k < 4; ++k) EXPECT_EQ(a.c[size_t(k)], b.c[size_t(k)]) << x << "," << z;
      if (x == 2 && z == 2) continue;
      ProbeField fa, fb;
      files.load({x, z}, fa);
      regions.load({x, z}, fb);
      ASSERT_EQ(fa.radiance.size(), fb.radiance.size());
      EXPECT_TRUE(sameBits(fa.radiance.data(), fb.radiance.data(), fa.radiance.size())) << x << "," << z;
      EXPECT_TRUE(sameBits(fa.irradiance.data(), fb.irradiance.data(), fa.irradiance.size()))
          << x << "," << z;
      EXPECT_TRUE(sameBits(fa.distance.data(), fb.distance.data(), fa.distance.size())) << x << "," << z;
    }
  // A corrupt record: that cell alone falls back, named by its region file and cell.
  const RegionIndex index = readRegionIndex(world / "baked" / "regions");
  const fs::path region = world / "baked" / "regions" / index.regions[0].file;
  flipByte(region, size_t(RegionFile::open(region).cells()[1].offset + 20));
  CellFileSource broken(options(world));
  EXPECT_EQ(broken.validCells(), 7);
  EXPECT_EQ(broken.corruptCells(), 1);
  EXPECT_EQ(broken.info({1, 0}).state, CellFileState::Corrupt);
  EXPECT_NE(broken.info({1, 0}).error.find(index.regions[0].file + ": cell (1, 0): corrupt"),
            std::string::npos)
      << broken.info({1, 0}).error;
}

TEST(CellFileSource, MissingAndCorruptFilesGetTheirNeighboursFallback) {
  const fs::path world = makeWorld("broken");
  fs::remove(cellFile(world, 0, 2));
  flipByte(cellFile(world, 2, 0), 300);
  fs::copy_file(cellFile(world, 1, 1), cellFile(world, 1, 2),
                fs::copy_options::overwrite_existing);  // wrong cell
  CellFileSource source(options(world));
  EXPECT_EQ(source.validCells(), 6);
  EXPECT_EQ(source.missingCells(), 1);
  EXPECT_EQ(source.corruptCells(), 2);
  EXPECT_EQ(source.info({0, 2}).state, CellFileState::Missing);
  EXPECT_EQ(source.info({2, 0}).state, CellFileState::Corrupt);
  EXPECT_NE(source.info({2, 0}).error.find("cell_2_0.vdb"), std::string::npos) << source.info({2, 0}).error;
  EXPECT_NE(source.info({1, 2}).error.find("holds cell 1,1, expected 1,2"), std::string::npos)
      << source.info({1, 2}).error;
  // Cell (0, 2)'s valid 8-neighbours: (0, 1) and (1, 1) ((1, 2) is corrupt).
  const ShL1 a = cellFileFallback(makeCell(0, 1), 12.0f, 0.0f),
             b = cellFileFallback(makeCell(1, 1), 12.0f, 0.0f), m = source.fallback({0, 2});
  for (int k = 0; k < 4; ++k) EXPECT_EQ(m.c[size_t(k)], (a.c[size_t(k)] + b.c[size_t(k)]) / 2.0f);
  ProbeField f;
  try {
    source.load({0, 2}, f);
    ADD_FAILURE() << "loaded a missing cell";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cell_0_2.vdb: no cell file"), std::string::npos) << e.what();
  }
  try {
    source.load({2, 0}, f);
    ADD_FAILURE() << "loaded a corrupt cell";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cell_2_0.vdb"), std::string::npos) << e.what();
  }
}

TEST(CellFileSource, NoReadableCellNamesTheDirectory) {
  const fs::path world = makeWorld("empty");
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) fs::remove(cellFile(world, x, z));
  try {
    CellFileSource source(options(world));
    ADD_FAILURE() << "constructed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("none of the world's 9 cells"), std::string::npos) << e.what();
  }
  fs::remove_all(world / "baked");
  EXPECT_THROW(CellFileSource(options(world)), Error);
}

// Lighting keys 8, 12, 17.5 h: key k's SH = makeCell's SH x kKeyScale[k] (every entry).
constexpr float kKeyHours[3] = {8.0f, 12.0f, 17.5f};
constexpr float kKeyScale[3] = {0.5f, 1.0f, 1.5f};

CellFile makeKeyedCell(int x, int z) {
  CellFile c = makeCell(x, z);
  const std::vector<uint16_t> one = c.fallback.shHalf;
  c.fallback.keyHours.assign(std::begin(kKeyHours), std::end(kKeyHours));
  c.fallback.keyOvercast.assign(3, 0.0f);
  c.fallback.shHalf.clear();
  for (float scale : kKeyScale)
    for (uint16_t h : one) c.fallback.shHalf.push_back(floatToHalfClamped(halfToFloat(h) * scale));
  return c;
}

fs::path makeKeyedWorld(const std::string& name) {
  const fs::path dir = makeWorld(name);
  for (int z = 0; z < 3; ++z)
    for (int x = 0; x < 3; ++x) writeCellFile(cellFile(dir, x, z), makeKeyedCell(x, z));
  return dir;
}

// Key k's cell SH straight from the stored halves (per-cell entry, or the mean of the per-probe ones).
ShL1 storedKeySh(const CellFile& c, size_t key) {
  const size_t entries = c.fallback.shHalf.size() / 12 / c.fallback.keyCount();
  ShL1 sh;
  for (size_t e = 0; e < entries; ++e)
    for (int k = 0; k < 4; ++k)
      for (int ch = 0; ch < 3; ++ch)
        sh.c[size_t(k)][ch] +=
            halfToFloat(c.fallback.shHalf[(key * entries + e) * 12 + size_t(k) * 3 + size_t(ch)]);
  for (glm::vec3& v : sh.c) v /= float(entries);
  return sh;
}

void expectShNear(const ShL1& a, const ShL1& b, float relTol, const std::string& what) {
  for (int k = 0; k < 4; ++k)
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(a.c[size_t(k)][ch], b.c[size_t(k)][ch], relTol * (std::fabs(b.c[size_t(k)][ch]) + 1e-6f))
          << what << " coefficient " << k << " channel " << ch;
}

TEST(CellFileSource, FallbackFollowsTheTimeOfDayBetweenKeys) {
  const fs::path world = makeKeyedWorld("keys");
  CellFileSource source(options(world));
  EXPECT_TRUE(source.fallbackFollowsTimeOfDay());
  // (1, 0): SH-only per cell; (2, 2): per probe (mean of its entries); (1, 1): a generator cell.
  for (glm::ivec2 c : {glm::ivec2(1, 0), glm::ivec2(2, 2), glm::ivec2(1, 1)}) {
    const std::string what = fmt::format("cell {},{}", c.x, c.y);
    const CellFile file = readCellFile(cellFile(world, c.x, c.y));
    ASSERT_EQ(file.fallback.keyCount(), 3u);
    EXPECT_EQ(source.info(c).fallbackKeys, 3);
    const ShL1 k8 = storedKeySh(file, 0), k12 = storedKeySh(file, 1), k175 = storedKeySh(file, 2);
    // At a key: that key's stored SH (per cell exactly; per probe to the float mean's rounding).
    source.setTimeOfDay(8.0f);
    expectShNear(source.fallback(c), k8, 1e-6f, what + " at 8 h");
    source.setTimeOfDay(12.0f);
    expectShNear(source.fallback(c), k12, 1e-6f, what + " at 12 h");
    source.setTimeOfDay(17.5f);
    expectShNear(source.fallback(c), k175, 1e-6f, what + " at 17.5 h");
    if (c == glm::ivec2(1, 0)) {
      const ShL1 f = source.fallback(c);
      for (int k = 0; k < 4; ++k) EXPECT_EQ(f.c[size_t(k)], k175.c[size_t(k)]);
    }
    // Halfway between two keys: their mean; a quarter of the way: the lerp.
    ShL1 mid, quarter;
    for (int k = 0; k < 4; ++k) {
      mid.c[size_t(k)] = 0.5f * (k8.c[size_t(k)] + k12.c[size_t(k)]);
      quarter.c[size_t(k)] = 0.75f * k12.c[size_t(k)] + 0.25f * k175.c[size_t(k)];
    }
    source.setTimeOfDay(10.0f);
    expectShNear(source.fallback(c), mid, 1e-5f, what + " at 10 h");
    source.setTimeOfDay(12.0f + 0.25f * 5.5f);
    expectShNear(source.fallback(c), quarter, 1e-5f, what + " at 13.375 h");
    // Outside the keys: clamped to the first / last.
    source.setTimeOfDay(6.0f);
    expectShNear(source.fallback(c), k8, 1e-6f, what + " at 6 h");
    source.setTimeOfDay(23.0f);
    expectShNear(source.fallback(c), k175, 1e-6f, what + " at 23 h");
    // The keys really differ (k17.5 = 3 x k8 here), so the checks above can fail.
    EXPECT_NEAR(k175.c[0].x, 3.0f * k8.c[0].x, 3e-3f * k175.c[0].x) << what;
    // The free function agrees with the source.
    expectShNear(cellFileFallback(file, 10.0f, 0.0f), mid, 1e-5f, what + " cellFileFallback at 10 h");
  }
  // A world of one-key files: the fallback does not move.
  CellFileSource oneKey(options(makeWorld("one_key")));
  EXPECT_FALSE(oneKey.fallbackFollowsTimeOfDay());
  oneKey.setTimeOfDay(6.0f);
  const ShL1 a = oneKey.fallback({1, 0});
  oneKey.setTimeOfDay(20.0f);
  const ShL1 b = oneKey.fallback({1, 0});
  for (int k = 0; k < 4; ++k) EXPECT_EQ(a.c[size_t(k)], b.c[size_t(k)]);
}

TEST(CellFileSource, FallbackKeysWithOvercastUseTheSourcesWeather) {
  // Keys 8 h, 12 h clear and 12 h overcast 1: a clear source interpolates the clear keys, an overcast
  // source has only the overcast key (constant).
  const fs::path world = makeWorld("overcast_keys");
  CellFile c = makeCell(1, 0);
  const std::vector<uint16_t> one = c.fallback.shHalf;
  c.fallback.keyHours = {8.0f, 12.0f, 12.0f};
  c.fallback.keyOvercast = {0.0f, 0.0f, 1.0f};
  c.fallback.shHalf.clear();
  for (float scale : {0.5f, 1.0f, 0.25f})
    for (uint16_t h : one) c.fallback.shHalf.push_back(floatToHalfClamped(halfToFloat(h) * scale));
  writeCellFile(cellFile(world, 1, 0), c);
  CellFileSource clear(options(world));
  CellFileSourceOptions o = options(world);
  o.weather = 0.8f;
  CellFileSource overcast(o);
  const ShL1 k8 = storedKeySh(c, 0), k12 = storedKeySh(c, 1), k12o = storedKeySh(c, 2);
  EXPECT_EQ(clear.info({1, 0}).fallbackKeys, 2);
  EXPECT_EQ(overcast.info({1, 0}).fallbackKeys, 1);
  clear.setTimeOfDay(10.0f);
  overcast.setTimeOfDay(10.0f);
  ShL1 mid;
  for (int k = 0; k < 4; ++k) mid.c[size_t(k)] = 0.5f * (k8.c[size_t(k)] + k12.c[size_t(k)]);
  expectShNear(clear.fallback({1, 0}), mid, 1e-5f, "clear at 10 h");
  expectShNear(overcast.fallback({1, 0}), k12o, 1e-6f, "overcast at 10 h");
}

TEST(CellFileSource, MissingCellsGetTheirRingsMeanFallbackPerKey) {
  const fs::path world = makeKeyedWorld("keys_missing");
  fs::remove(cellFile(world, 0, 2));
  // (1, 2) is a version-1 file (one key, scale 1 at every hour): the ring mixes 3-key and 1-key cells.
  const std::vector<detail::CellFileOverride> v1 = {{"lfgi_format_version", 1, ""},
                                                    {"fallback_key_count", 0, "", true},
                                                    {"fallback_key_hours", 0, "", true},
                                                    {"fallback_key_overcast", 0, "", true}};
  writeFileAtomic(cellFile(world, 1, 2), detail::encodeCellFileWithOverrides(makeCell(1, 2), v1));
  CellFileSource source(options(world));
  ASSERT_EQ(source.info({1, 2}).state, CellFileState::Valid) << source.info({1, 2}).error;
  EXPECT_EQ(source.info({1, 2}).fallbackKeys, 1);
  EXPECT_EQ(source.validCells(), 8);
  // Cell (0, 2)'s ring: (0, 1), (1, 1) (3 keys) and (1, 2) (version 1: one key).
  const CellFile a = makeKeyedCell(0, 1), b = makeKeyedCell(1, 1), v = makeCell(1, 2);
  for (float h : {6.0f, 8.0f, 10.0f, 12.0f, 15.0f, 17.5f, 20.0f}) {
    source.setTimeOfDay(h);
    const ShL1 fa = cellFileFallback(a, h, 0.0f), fb = cellFileFallback(b, h, 0.0f),
               fv = cellFileFallback(v, h, 0.0f);
    ShL1 mean;
    for (int k = 0; k < 4; ++k)
      mean.c[size_t(k)] = (fa.c[size_t(k)] + fb.c[size_t(k)] + fv.c[size_t(k)]) / 3.0f;
    expectShNear(source.fallback({0, 2}), mean, 1e-5f, fmt::format("missing cell at {} h", h));
    // The version-1 cell: its one key at every hour.
    expectShNear(source.fallback({1, 2}), storedKeySh(v, 0), 1e-6f, fmt::format("version-1 cell at {} h", h));
  }
  source.setTimeOfDay(8.0f);
  const ShL1 morning = source.fallback({0, 2});
  source.setTimeOfDay(17.5f);
  EXPECT_GT(source.fallback({0, 2}).c[0].x, 1.5f * morning.c[0].x);  // it moves with the keys
}

TEST(CellFileSource, ShOnlyCellsDecodeAndRelightAtTheTimeOfDay) {
  const fs::path world = makeKeyedWorld("keys_decode");
  CellFileSource source(options(world));
  const glm::ivec2 c{1, 0};  // SH-only per cell
  ASSERT_FALSE(source.info(c).network);
  source.setTimeOfDay(8.0f);
  ProbeField morning, evening, relit;
  source.load(c, morning);
  source.setTimeOfDay(17.5f);
  source.load(c, evening);
  // Probe 0's irradiance = shIrradiance of the fallback at that time (what a decode holds), checked at
  // its brightest texel.
  const int m = morning.irradianceResolution;
  source.setTimeOfDay(8.0f);
  const ShL1 f8 = source.fallback(c);
  source.setTimeOfDay(17.5f);
  const ShL1 f175 = source.fallback(c);
  size_t best = 0;
  for (size_t t = 0; t < size_t(m * m); ++t)
    if (morning.irradiance[t * 3] > morning.irradiance[best * 3]) best = t;
  const glm::vec3 dir = octTexelDirection(int(best % size_t(m)), int(best / size_t(m)), m);
  const glm::vec3 e8 = glm::max(shIrradiance(f8, dir), glm::vec3(0.0f));
  const glm::vec3 e175 = glm::max(shIrradiance(f175, dir), glm::vec3(0.0f));
  ASSERT_GT(e8.x, 0.0f);
  EXPECT_NEAR(morning.irradiance[best * 3], e8.x, 1e-5f * e8.x);
  EXPECT_NEAR(evening.irradiance[best * 3], e175.x, 1e-5f * e175.x);
  EXPECT_GT(evening.irradiance[best * 3], 2.0f * morning.irradiance[best * 3]);
  // relightInto re-decodes it (no longer a copy of `current`): the same as a fresh load at that hour.
  source.relightInto(c, morning, relit, 17.5f);
  ASSERT_EQ(relit.irradiance.size(), evening.irradiance.size());
  EXPECT_TRUE(sameBits(relit.irradiance.data(), evening.irradiance.data(), evening.irradiance.size()));
  EXPECT_TRUE(sameBits(relit.radiance.data(), evening.radiance.data(), evening.radiance.size()));
  // In place too.
  ProbeField inPlace = morning;
  EXPECT_TRUE(source.relight(c, inPlace, 17.5f));
  EXPECT_TRUE(sameBits(inPlace.irradiance.data(), evening.irradiance.data(), evening.irradiance.size()));
}

StreamingConfig fileConfig(size_t cellBytes);

TEST(CellFileStreaming, ManagerFallbackFollowsTheTimeOfDay) {
  const fs::path world = makeKeyedWorld("keys_manager");
  CellFileSource source(options(world));
  StreamingManager m(source, fileConfig(source.maxCellBytes()));
  // The camera in cell (0, 0); cell (2, 2)'s centre stays on its fallback (beyond the decode radius).
  const glm::vec3 far(2.5f * kCell, 1.0f, 2.5f * kCell);
  FrameInput in;
  in.position = {8.0f, 10.0f, 8.0f};
  in.dtSeconds = 0.1f;
  in.timeOfDayHours = 8.0f;
  m.update(in);
  const IrradianceSample s8 = m.sample(far, {0, 1, 0});
  ASSERT_EQ(s8.fallbackWeight, 1.0f);
  in.timeOfDayHours = 17.5f;
  m.update(in);
  const IrradianceSample s175 = m.sample(far, {0, 1, 0});
  ASSERT_EQ(s175.fallbackWeight, 1.0f);
  // Every key is the 12 h SH scaled by 0.5 / 1 / 1.5: the evening fallback is 3x the morning one.
  EXPECT_NEAR(s175.irradiance.x, 3.0f * s8.irradiance.x, 5e-3f * s175.irradiance.x);
  source.setTimeOfDay(17.5f);
  EXPECT_NEAR(s175.irradiance.y, shIrradiance(source.fallback({2, 2}), {0, 1, 0}).y,
              1e-4f * s175.irradiance.y);
}

StreamingConfig fileConfig(size_t cellBytes) {
  StreamingConfig c;
  c.decodeRadius = 40.0f;
  c.keepRadius = 56.0f;
  c.maxPrefetchDistance = 20.0f;
  c.ioThreads = 0;
  c.maxInlineLoadsPerFrame = 1;
  c.maxActivationsPerFrame = 4;
  c.activateBudgetMs = 1e9;
  c.fadeSeconds = 0.0f;
  c.recordEvents = true;
  c.memoryBudgetBytes = 5 * cellBytes + 17;  // 4 slots (fewer than cells) + 1 relight staging field
  return c;
}

// West -> east through the middle row, 20 m/s at 10 fps, time of day moving.
std::vector<FrameInput> eastward() {
  std::vector<FrameInput> path;
  for (int f = 0; f < 90; ++f) {
    FrameInput in;
    in.position = {8.0f + 2.0f * float(f), 10.0f, 96.0f};
    in.velocity = {20.0f, 0.0f, 0.0f};
    in.direction = {1.0f, 0.0f, 0.0f};
    in.timeOfDayHours = 8.0f + 0.05f * float(f);
    in.dtSeconds = 0.1f;
    path.push_back(in);
  }
  return path;
}

// Ground points around the camera (in the world) have GI every frame.
void expectNoHoles(const StreamingManager& m, glm::vec3 cam, int frame) {
  for (float dz : {-60.0f, -20.0f, 0.0f, 20.0f, 60.0f})
    for (float dx : {-60.0f, -20.0f, 0.0f, 20.0f, 60.0f}) {
      glm::vec3 p(cam.x + dx, 1.0f, cam.z + dz);
      if (!m.layout().contains(m.layout().cellOf(p))) continue;
      IrradianceSample s = m.sample(p, {0, 1, 0});
      ASSERT_FALSE(s.missing) << "frame " << frame;
      ASSERT_TRUE(std::isfinite(s.irradiance.x + s.irradiance.y + s.irradiance.z)) << "frame " << frame;
    }
}

TEST(CellFileStreaming, ScriptedFlightIsDeterministicWithinBudgetAndReplacesFallbacks) {
  const fs::path world = makeWorld("flight");
  auto run = [&](std::vector<float>* fallbackAtFar) {
    CellFileSource source(options(world));
    const StreamingConfig c = fileConfig(source.maxCellBytes());
    StreamingManager m(source, c);
    EXPECT_EQ(m.slotCount(), 4);
    const glm::vec3 far(2 * kCell + 30.0f, 1.0f, kCell + 30.0f);  // cell (2, 1), reached late
    int f = 0;
    for (const FrameInput& in : eastward()) {
      FrameStats s = m.update(in);
      EXPECT_LE(s.bytesResident, c.memoryBudgetBytes) << "frame " << f;
      EXPECT_EQ(s.failed, 0);
      expectNoHoles(m, in.position, f);
      fallbackAtFar->push_back(m.sample(far, {0, 1, 0}).fallbackWeight);
      ++f;
    }
    EXPECT_TRUE(m.isResident({2, 1}));
    EXPECT_GT(source.loads(), 4u);
    return m.events();
  };
  std::vector<float> w1, w2;
  const std::vector<StreamingEvent> e1 = run(&w1), e2 = run(&w2);
  EXPECT_EQ(e1, e2);
  EXPECT_EQ(w1, w2);
  EXPECT_EQ(w1.front(), 1.0f);  // the far cell starts on its fallback...
  EXPECT_EQ(w1.back(), 0.0f);   // ...and ends on its full field
  int evictions = 0;
  for (const StreamingEvent& e : e1) evictions += e.type == StreamingEventType::Evict;
  EXPECT_GT(evictions, 0);  // the western cells were dropped to make room
}

TEST(CellFileStreaming, CorruptAndMissingFilesMidFlightKeepTheFallback) {
  const fs::path world = makeWorld("midflight");
  fs::remove(cellFile(world, 2, 0));  // missing from the start
  CellFileSource source(options(world));
  ASSERT_EQ(source.info({2, 1}).state, CellFileState::Valid);
  StreamingManager m(source, fileConfig(source.maxCellBytes()));
  int f = 0, failed = 0;
  bool flipped = false;
  for (const FrameInput& in : eastward()) {
    // Corrupt cell (2, 1) while the camera is still two cells away from it.
    if (!flipped && in.position.x > 40.0f) {
      EXPECT_FALSE(m.isResident({2, 1}));
      flipByte(cellFile(world, 2, 1), size_t(fs::file_size(cellFile(world, 2, 1)) / 2));
      flipped = true;
    }
    failed += m.update(in).failed;
    expectNoHoles(m, in.position, f++);
  }
  EXPECT_TRUE(flipped);
  EXPECT_EQ(failed, 2);
  ASSERT_EQ(m.failures().size(), 2u);
  for (const CellFailure& e : m.failures()) {
    EXPECT_TRUE(e.cell == glm::ivec2(2, 1) || e.cell == glm::ivec2(2, 0)) << e.cell.x << "," << e.cell.y;
    EXPECT_NE(e.error.find(cellFileName(e.cell)), std::string::npos) << e.error;
  }
  EXPECT_FALSE(m.isResident({2, 1}));
  EXPECT_TRUE(m.isResident({2, 2}));
  // The corrupt cell is lit by its fallback (the one read at construction), not by nothing.
  IrradianceSample s = m.sample({2 * kCell + 40.0f, 1.0f, kCell + 40.0f}, {0, 1, 0});
  EXPECT_FALSE(s.missing);
  EXPECT_EQ(s.fallbackWeight, 1.0f);
  EXPECT_GT(s.irradiance.x, 0.0f);
}

// ---- The GPU decoder (streaming/generator_backend.h) ----

CellFileSourceOptions gpuOptions(const fs::path& world, DecoderChoice d = DecoderChoice::Gpu) {
  CellFileSourceOptions o = options(world);
  o.decoder = d;
  return o;
}

// Tolerance of a GPU-decoded field against the CPU-decoded one, relative to the array's largest magnitude.
// gpu/generator_pass_test.cpp holds the raw network outputs to 1e-5 of their largest magnitude (float sums
// in another order, lavapipe fusing multiply-adds). After the network: radiance = exposure * expm1(y), so
// dL = (L + exposure) dy: relative to the largest L the error grows by at most (Lmax + exposure) / Lmax times
// max|y| (<= ~3 for these models: ~2e-5 x a few); distance is linear in y; irradiance is a non-negative
// weighted sum of radiance (same relative bound). 1e-4 leaves ~2-5x headroom over that estimate, and is
// far below what a wrong channel, texel or probe order would give (O(1)).
constexpr double kGpuFieldTolerance = 1e-4;

void expectFieldsClose(const ProbeField& gpu, const ProbeField& cpu, const std::string& what) {
  ASSERT_EQ(gpu.grid.dims, cpu.grid.dims) << what;
  ASSERT_EQ(gpu.resolution, cpu.resolution) << what;
  ASSERT_EQ(gpu.irradianceResolution, cpu.irradianceResolution) << what;
  EXPECT_EQ(gpu.active, cpu.active) << what;
  ASSERT_EQ(gpu.radiance.size(), cpu.radiance.size()) << what;
  ASSERT_EQ(gpu.distance.size(), cpu.distance.size()) << what;
  ASSERT_EQ(gpu.irradiance.size(), cpu.irradiance.size()) << what;
  const double r = test::relMaxError(gpu.radiance, cpu.radiance),
               d = test::relMaxError(gpu.distance, cpu.distance),
               e = test::relMaxError(gpu.irradiance, cpu.irradiance);
  std::printf("  %s: max rel error radiance %.2e, distance %.2e, irradiance %.2e\n", what.c_str(), r, d, e);
  EXPECT_LT(r, kGpuFieldTolerance) << what;
  EXPECT_LT(d, kGpuFieldTolerance) << what;
  EXPECT_LT(e, kGpuFieldTolerance) << what;
}

TEST(CellFileSourceGpu, GpuLoadEqualsTheCpuLoadWithinTolerance) {
  const fs::path world = makeWorld("gpu_vs_cpu");
  CellFileSource cpu(options(world)), gpu(gpuOptions(world));
  ASSERT_NE(gpu.gpuBackend(), nullptr);
  EXPECT_EQ(cpu.gpuBackend(), nullptr);
  EXPECT_EQ(gpu.selection().backend, "gpu");
  EXPECT_EQ(cpu.selection().backend, "cpu");
  cpu.setTimeOfDay(15.5f);
  gpu.setTimeOfDay(15.5f);
  std::vector<ProbeField> fields(9);
  int generatorCells = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const uint64_t allocations = gpu.gpuBackend()->bufferAllocations(),
                   uploads = gpu.gpuBackend()->modelUploads();
    for (int z = 0; z < 3; ++z)
      for (int x = 0; x < 3; ++x) {
        ProbeField& g = fields[size_t(z * 3 + x)];
        ProbeField c;
        const float* before = g.radiance.data();
        gpu.load({x, z}, g);
        cpu.load({x, z}, c);
        ASSERT_NO_THROW(g.validate());
        if (cpu.info({x, z}).network) {
          generatorCells += pass == 0;
          expectFieldsClose(g, c, fmt::format("cell {},{}", x, z));
        } else {  // SH-only: no network, the same code for both
          EXPECT_EQ(g.radiance, c.radiance);
          EXPECT_EQ(g.irradiance, c.irradiance);
          EXPECT_EQ(g.distance, c.distance);
        }
        if (pass == 1) {
          EXPECT_EQ(g.radiance.data(), before);  // the slot's arrays are reused
        }
      }
    if (pass == 1) {  // warm: no new device buffers, no re-upload of a cell's weights
      EXPECT_EQ(gpu.gpuBackend()->bufferAllocations(), allocations);
      EXPECT_EQ(gpu.gpuBackend()->modelUploads(), uploads);
    }
  }
  EXPECT_EQ(generatorCells, 4);  // (0, 0) position latents, (2, 0), (1, 1), (0, 2) stored
  EXPECT_EQ(gpu.gpuBackend()->modelUploads(), 4u);
  EXPECT_EQ(gpu.decodeSamples().size(), 18u);
  EXPECT_EQ(gpu.gpuBackend()->context().validationErrors.load(), 0u);
}

// More active probes than one GPU batch: batches of 256 with disabled probes between them land where the
// CPU's 1024-probe chunks put them.
TEST(CellFileSourceGpu, MultiBatchDecodeOfALargeCellMatchesTheCpu) {
  CellFile c = makeCell(2, 0);
  c.grid.dims = {16, 6, 16};
  c.grid.spacing = glm::vec3(4.0f);
  c.active.assign(size_t(c.grid.probeCount()), 1);
  for (size_t i = 0; i < c.active.size(); i += 7) c.active[i] = 0;
  const int64_t A = c.activeProbeCount();
  const GeneratorWeights w = dequantizeWeights(c.generator->weights);
  c.generator->latents =
      quantizeLatents(test::randomLatents(size_t(A), w.arch.latentDim, 5), w.arch.latentDim, 8);
  GpuBackendOptions go;
  go.batchProbes = 256;
  ASSERT_GT(A, 4 * 256);
  GpuGeneratorBackend gpu(go);
  ProbeField fc, fg;
  decodeCellField(c, 9.0f, 0.25f, 0, 8, fc);
  decodeCellField(c, 9.0f, 0.25f, 0, 8, fg, "large cell", &gpu);
  expectFieldsClose(fg, fc, "large cell");
  EXPECT_EQ(gpu.context().validationErrors.load(), 0u);
}

TEST(CellFileSourceGpu, RelightIntoWithTheGpuEqualsAFreshGpuLoad) {
  const fs::path world = makeWorld("gpu_relight");
  CellFileSource source(gpuOptions(world));
  source.setTimeOfDay(8.0f);
  ProbeField morning, staged, fresh;
  source.load({1, 1}, morning);
  const ProbeField before = morning;
  source.relightInto({1, 1}, morning, staged, 16.0f);
  source.setTimeOfDay(16.0f);
  source.load({1, 1}, fresh);
  EXPECT_EQ(staged.radiance, fresh.radiance);
  EXPECT_EQ(staged.distance, fresh.distance);
  EXPECT_EQ(staged.irradiance, fresh.irradiance);
  EXPECT_NE(staged.irradiance, before.irradiance);   // the conditioning reached the device
  EXPECT_EQ(morning.irradiance, before.irradiance);  // the resident field is untouched
  // The in-place relight agrees too.
  EXPECT_TRUE(source.relight({1, 1}, morning, 16.0f));
  EXPECT_EQ(morning.irradiance, fresh.irradiance);
  EXPECT_EQ(source.gpuBackend()->context().validationErrors.load(), 0u);
}

TEST(CellFileSourceGpu, AutoPicksABackendAndReportsBothRates) {
  const fs::path world = makeWorld("gpu_auto");
  CellFileSource source(gpuOptions(world, DecoderChoice::Auto));
  const DecoderSelection& s = source.selection();
  std::printf("  %s -> %s\n", s.reason.c_str(), s.backend.c_str());
  EXPECT_EQ(s.requested, DecoderChoice::Auto);
  EXPECT_TRUE(s.backend == "cpu" || s.backend == "gpu") << s.backend;
  EXPECT_GT(s.cpuProbesPerS, 0.0);
  EXPECT_GT(s.gpuProbesPerS, 0.0);
  EXPECT_EQ(s.measuredProbes, 512u);  // the first generator cell (0, 0)'s 32 probes, repeated to 512
  EXPECT_FALSE(s.device.empty());
  EXPECT_EQ(s.backend == "gpu", s.gpuProbesPerS > s.cpuProbesPerS);
  EXPECT_EQ(source.gpuBackend() != nullptr, s.backend == "gpu");
  EXPECT_NE(s.reason.find("probes/s"), std::string::npos) << s.reason;
  CellFileSource cpu(options(world));
  ProbeField a, b;
  source.load({0, 0}, a);
  cpu.load({0, 0}, b);
  expectFieldsClose(a, b, "auto cell 0,0");
}

// No usable Vulkan device (simulated by naming one that does not exist): `gpu` is an error that says so,
// `auto` logs the reason and decodes on the CPU.
TEST(CellFileSourceGpu, NoDeviceGpuIsAnErrorAndAutoFallsBackToTheCpu) {
  const fs::path world = makeWorld("gpu_none");
  const char* old = std::getenv("LFGI_VK_DEVICE");
  const std::string saved = old ? old : "";
  setenv("LFGI_VK_DEVICE", "no-such-device-xyz", 1);
  std::string error;
  try {
    CellFileSource source(gpuOptions(world));
  } catch (const Error& e) {
    error = e.what();
  }
  std::unique_ptr<CellFileSource> autoSource;
  EXPECT_NO_THROW(autoSource = std::make_unique<CellFileSource>(gpuOptions(world, DecoderChoice::Auto)));
  if (old)
    setenv("LFGI_VK_DEVICE", saved.c_str(), 1);
  else
    unsetenv("LFGI_VK_DEVICE");
  EXPECT_NE(error.find("decoder gpu: no usable Vulkan device"), std::string::npos) << error;
  EXPECT_NE(error.find("no-such-device-xyz"), std::string::npos) << error;
  ASSERT_TRUE(autoSource);
  EXPECT_EQ(autoSource->selection().backend, "cpu");
  EXPECT_EQ(autoSource->gpuBackend(), nullptr);
  EXPECT_NE(autoSource->selection().reason.find("no Vulkan device"), std::string::npos)
      << autoSource->selection().reason;
  ProbeField f;
  autoSource->load({1, 1}, f);
  EXPECT_NO_THROW(f.validate());
}

// The scripted flight of CellFileStreaming above with the GPU decoder: inline IO makes the decisions the same
// as the CPU's (the decoder changes values, not timing-free decisions); then two IO threads decode on the
// device at once (serialised by the backend): no hole, budget held, every far cell arrives.
TEST(CellFileStreamingGpu, FlightWithTheGpuDecoderHasNoHolesAndStaysWithinBudget) {
  const fs::path world = makeWorld("gpu_flight");
  auto fly = [&](DecoderChoice d, int ioThreads, std::vector<StreamingEvent>* events,
                 glm::vec3* finalSample) {
    CellFileSource source(gpuOptions(world, d));
    StreamingConfig c = fileConfig(source.maxCellBytes());
    c.ioThreads = ioThreads;
    StreamingManager m(source, c);
    int f = 0, missing = 0;
    std::vector<FrameInput> path = eastward();
    for (int extra = 0; extra < 200; ++extra) {  // hover at the end (wall time for the IO threads)
      FrameInput in = path.back();
      in.velocity = glm::vec3(0.0f);
      path.push_back(in);
    }
    for (const FrameInput& in : path) {
      const FrameStats s = m.update(in);
      EXPECT_LE(s.bytesResident, c.memoryBudgetBytes) << "frame " << f;
      EXPECT_EQ(s.failed, 0) << "frame " << f;
      for (float dz : {-60.0f, 0.0f, 60.0f})
        for (float dx : {-60.0f, 0.0f, 60.0f}) {
          const glm::vec3 p(in.position.x + dx, 1.0f, in.position.z + dz);
          if (m.layout().contains(m.layout().cellOf(p))) missing += m.sample(p, {0, 1, 0}).missing;
        }
      if (ioThreads > 0 && f >= 90 && m.isResident({2, 1}) &&
          m.sample({2 * kCell + 30.0f, 1.0f, kCell + 30.0f}, {0, 1, 0}).fallbackWeight == 0.0f)
        break;
      if (ioThreads > 0 && f >= 90) std::this_thread::sleep_for(std::chrono::milliseconds(5));
      ++f;
    }
    EXPECT_EQ(missing, 0);
    EXPECT_TRUE(m.isResident({2, 1}));
    *finalSample = m.sample({2 * kCell + 30.0f, 1.0f, kCell + 30.0f}, {0, 1, 0}).irradiance;
    if (events) *events = m.events();
    if (source.gpuBackend()) {
      EXPECT_EQ(source.gpuBackend()->context().validationErrors.load(), 0u);
    }
    EXPECT_GE(source.loads(), 4u);
  };
  std::vector<StreamingEvent> cpuEvents, gpuEvents;
  glm::vec3 cpuE, gpuE, threadedE;
  fly(DecoderChoice::Cpu, 0, &cpuEvents, &cpuE);
  fly(DecoderChoice::Gpu, 0, &gpuEvents, &gpuE);
  EXPECT_EQ(gpuEvents, cpuEvents);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(gpuE[k], cpuE[k], kGpuFieldTolerance * std::abs(cpuE[k]) + 1e-6) << k;
  // With IO threads the lighting a cell holds depends on when its relight landed: invariants only.
  fly(DecoderChoice::Gpu, 2, nullptr, &threadedE);
  EXPECT_TRUE(std::isfinite(threadedE.x + threadedE.y + threadedE.z));
}
}  // namespace
}  // namespace lfgi::streaming
