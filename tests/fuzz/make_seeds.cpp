// Writes the fuzz targets' seed corpora (small valid inputs) so nothing binary is committed:
//   lfgi_fuzz_seeds OUT_DIR  ->  OUT_DIR/cell/*, OUT_DIR/region/*, OUT_DIR/surfels/*, OUT_DIR/manifest/*
// Cell seeds come in both of fuzz_cell_file.cpp's forms: 0x00 + whole file, 0x01 + OpenVDB stream only.
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "core/cell_file.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/region_file.h"
#include "worlds/surfels.h"

namespace {

using namespace lfgi;
namespace fs = std::filesystem;

// 2x2x2 probes, one disabled; a 1-layer generator (8x8 output) unless noNetwork.
CellFile smallCell(bool noNetwork, bool positionLatents, int latentBits) {
  CellFile c;
  c.worldSeed = 3;
  c.cellX = 1;
  c.cellZ = 0;
  c.inputHash = 0x1234;
  c.grid.origin = {32.0f, 0.0f, 0.0f};
  c.grid.spacing = {8.0f, 4.0f, 8.0f};
  c.grid.dims = {2, 2, 2};
  c.active = {1, 1, 1, 0, 1, 1, 1, 1};
  const int64_t n = c.activeProbeCount();
  if (!noNetwork) {
    GeneratorArch a;
    a.latentDim = 4;
    a.convChannels = {4, kGeneratorChannels};
    if (positionLatents) {
      a.latentSource = LatentSource::PositionFourier;
      a.fourierOctaves = 1;
      a.latentDim = 6;
    }
    CellGenerator g;
    g.weights = quantizeWeights(randomGeneratorWeights(a, 5),
                                latentBits == 4 ? WeightPrecision::Float16 : WeightPrecision::Int8);
    if (!positionLatents) {
      std::vector<float> z(size_t(n) * size_t(a.latentDim));
      for (size_t i = 0; i < z.size(); ++i) z[i] = 0.1f * float(int(i % 11) - 5);
      g.latents = quantizeLatents(z, a.latentDim, latentBits);
    }
    c.generator = std::move(g);
  }
  c.fallback.kind = noNetwork ? CellFallback::Kind::PerProbe : CellFallback::Kind::PerCell;
  const size_t entries = noNetwork ? size_t(n) : 1;
  for (size_t i = 0; i < entries * 12; ++i)
    c.fallback.shHalf.push_back(floatToHalfClamped(0.125f * float(i % 5)));
  c.stats.errorAchieved = 0.03;
  c.stats.errorTarget = 0.05;
  c.stats.model = noNetwork ? "no network: SH L1" : "seed";
  return c;
}

void writeCellSeeds(const fs::path& dir, const std::string& name, const CellFile& c) {
  const std::vector<std::byte> file = encodeCellFile(c);
  std::vector<std::byte> whole{std::byte{0}}, stream{std::byte{1}};
  whole.insert(whole.end(), file.begin(), file.end());
  stream.insert(stream.end(), file.begin(), file.end() - 24);  // without the trailer
  writeFileAtomic(dir / (name + "_file"), whole);
  writeFileAtomic(dir / (name + "_stream"), stream);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: lfgi_fuzz_seeds OUT_DIR\n");
    return 2;
  }
  try {
    const fs::path out = argv[1];
    writeCellSeeds(out / "cell", "no_network", smallCell(true, false, 8));
    CellFile int8Fallback = smallCell(true, false, 8);  // version 4: the int8 SH L1 layout
    quantizeFallbackToInt8(int8Fallback.fallback);
    writeCellSeeds(out / "cell", "no_network_int8_fallback", int8Fallback);
    writeCellSeeds(out / "cell", "int8_latents8", smallCell(false, false, 8));
    writeCellSeeds(out / "cell", "fp16_latents4", smallCell(false, false, 4));
    writeCellSeeds(out / "cell", "position_latents", smallCell(false, true, 8));

    // Regions: one cell, and two cells of different kinds (fields common to both and per-cell ones).
    CellFile second = smallCell(true, false, 8);
    second.cellZ = 1;
    const CellFile one = smallCell(false, false, 8);
    const std::vector<CellFile> two = {one, second};
    writeFileAtomic(out / "region" / "one_cell", encodeRegionFile({0, 0}, 2, std::span(&one, 1)));
    writeFileAtomic(out / "region" / "two_cells", encodeRegionFile({0, 0}, 2, two));

    worlds::TriangleMesh m;
    m.addBox({0, 0, 0}, {1, 1, 1}, m.addMaterial({}));
    worlds::SurfelOptions so;
    so.spacing = 0.4f;
    const std::vector<worlds::Surfel> s = worlds::sampleSurfels(m, so);
    writeFileAtomic(out / "surfels" / "box", worlds::encodeSurfels(s));
    writeFileAtomic(out / "surfels" / "box_8bit", worlds::encodeSurfels(s, 8));
    writeFileAtomic(out / "surfels" / "one", worlds::encodeSurfels(std::span(s).first(1)));
    writeFileAtomic(out / "surfels" / "empty", worlds::encodeSurfels({}));

    writeFileAtomic(
        out / "manifest" / "world.json",
        std::string("{\"format\": \"lfgi-world\", \"version\": 1, \"generator\": \"synthetic\", \"seed\": 3,"
                    " \"size_m\": 64.0, \"cell_m\": 32.0, \"cells_x\": 2, \"cells_z\": 2}\n"));
    writeFileAtomic(out / "manifest" / "big.json",
                    std::string("{\"format\":\"lfgi-world\",\"version\":1,\"seed\":18446744073709551615,"
                                "\"size_m\":4096,\"cell_m\":64}"));
    std::printf("seeds written to %s\n", out.string().c_str());
    return 0;
  } catch (const Error& e) {
    std::fprintf(stderr, "lfgi_fuzz_seeds: %s\n", e.what());
    return 1;
  }
}
