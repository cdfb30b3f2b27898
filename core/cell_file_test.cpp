#include "core/cell_file.h"

#include <gtest/gtest.h>

#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <thread>

#include "core/error.h"
#include "core/file_util.h"
#include "core/half.h"
#include "core/sh_l1_q8.h"
#include "generator_test_util.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

fs::path tmpDir() {
  fs::path d = fs::path(LFGI_TEST_TMP_DIR) / "cell_file";
  fs::create_directories(d);
  return d;
}

enum class Variant { Int8Latents8, Fp16Latents4, PositionLatents, NoNetwork, Int8Fallback };

// A small cell: 3x2x2 probes (some disabled), a 2-layer generator.
CellFile makeCell(Variant v, uint32_t seed = 1) {
  std::mt19937 rng(seed);
  CellFile c;
  c.worldSeed = 0xfedcba9876543210ull;
  c.cellX = -3;
  c.cellZ = 7;
  c.inputHash = 0x0123456789abcdefull + seed;
  c.grid.origin = {-192.0f, 0.5f, 448.0f};
  c.grid.spacing = {8.0f, 4.0f, 8.0f};
  c.grid.dims = {3, 2, 2};
  if (v != Variant::Fp16Latents4) c.active = {1, 1, 0, 1, 1, 1, 1, 0, 1, 1, 1, 1};
  int64_t n = c.activeProbeCount();
  const bool noNetwork = v == Variant::NoNetwork || v == Variant::Int8Fallback;
  if (!noNetwork) {
    GeneratorArch a;
    a.latentDim = 8;
    a.convChannels = {8, 6, kGeneratorChannels};
    if (v == Variant::PositionLatents) {
      a.latentSource = LatentSource::PositionFourier;
      a.fourierOctaves = 2;
      a.latentDim = 12;
    }
    CellGenerator g;
    g.weights =
        quantizeWeights(test::uniformRandomWeights(a, rng),
                        v == Variant::Fp16Latents4 ? WeightPrecision::Float16 : WeightPrecision::Int8);
    if (a.latentSource == LatentSource::Stored) {
      std::vector<float> lat(size_t(n * a.latentDim));
      for (float& x : lat) x = std::normal_distribution<float>(0.0f, 1.0f)(rng);
      g.latents = quantizeLatents(lat, a.latentDim, v == Variant::Fp16Latents4 ? 4 : 8);
    }
    c.generator = std::move(g);
  }
  c.outputScale = {3.5f, 96.0f};
  c.fallback.kind =
      v == Variant::Int8Latents8 || noNetwork ? CellFallback::Kind::PerProbe : CellFallback::Kind::PerCell;
  size_t entries = c.fallback.kind == CellFallback::Kind::PerCell ? 1 : size_t(n);
  // Int8Latents8: one lighting key (as a version-1 file); the others: 3 keys (NoNetwork and Int8Fallback
  // with an overcast key).
  if (v == Variant::Fp16Latents4 || v == Variant::PositionLatents) {
    c.fallback.keyHours = {8.0f, 12.0f, 17.5f};
    c.fallback.keyOvercast = {0.0f, 0.0f, 0.0f};
  } else if (noNetwork) {
    c.fallback.keyHours = {8.0f, 12.0f, 12.0f};
    c.fallback.keyOvercast = {0.0f, 0.0f, 1.0f};
  }
  for (size_t i = 0; i < c.fallback.keyCount() * entries * 12; ++i)
    c.fallback.shHalf.push_back(
        floatToHalfClamped(0.25f * float(i % 7) - 0.5f + 0.125f * float(i / (entries * 12))));
  c.stats.errorAchieved = 0.0423;
  c.stats.errorTarget = 0.05;
  c.stats.trainingSeconds = 12.75;
  if (v == Variant::Int8Fallback) quantizeFallbackToInt8(c.fallback);  // negative L0s become 0
  c.stats.model = noNetwork ? "no network: SH L1" : "L8 C8-6 test";
  return c;
}

// Bit-for-bit float comparison (memcmp on an empty vector's null data() is undefined behaviour).
std::vector<uint32_t> bits(const std::vector<float>& v) {
  std::vector<uint32_t> b;
  for (float x : v) b.push_back(std::bit_cast<uint32_t>(x));
  return b;
}

void expectSameTensor(const QuantizedTensor& a, const QuantizedTensor& b) {
  EXPECT_EQ(a.encoding, b.encoding);
  EXPECT_EQ(a.outer, b.outer);
  EXPECT_EQ(a.channels, b.channels);
  EXPECT_EQ(a.inner, b.inner);
  EXPECT_EQ(a.f16, b.f16);
  EXPECT_EQ(a.codes, b.codes);
  EXPECT_EQ(bits(a.f32), bits(b.f32));
  EXPECT_EQ(bits(a.scales), bits(b.scales));
}

void expectSameCell(const CellFile& a, const CellFile& b) {
  EXPECT_EQ(a.worldSeed, b.worldSeed);
  EXPECT_EQ(a.cellX, b.cellX);
  EXPECT_EQ(a.cellZ, b.cellZ);
  EXPECT_EQ(a.inputHash, b.inputHash);
  EXPECT_EQ(a.grid.origin, b.grid.origin);
  EXPECT_EQ(a.grid.spacing, b.grid.spacing);
  EXPECT_EQ(a.grid.dims, b.grid.dims);
  EXPECT_EQ(a.active, b.active);
  ASSERT_EQ(a.generator.has_value(), b.generator.has_value());
  if (a.generator) {
    const CellGenerator &ga = *a.generator, &gb = *b.generator;
    EXPECT_EQ(ga.weights.arch.latentDim, gb.weights.arch.latentDim);
    EXPECT_EQ(ga.weights.arch.condDim, gb.weights.arch.condDim);
    EXPECT_EQ(ga.weights.arch.convChannels, gb.weights.arch.convChannels);
    EXPECT_EQ(ga.weights.arch.latentSource, gb.weights.arch.latentSource);
    EXPECT_EQ(ga.weights.arch.fourierOctaves, gb.weights.arch.fourierOctaves);
    EXPECT_EQ(ga.weights.precision, gb.weights.precision);
    ASSERT_EQ(ga.weights.tensors.size(), gb.weights.tensors.size());
    for (size_t k = 0; k < ga.weights.tensors.size(); ++k)
      expectSameTensor(ga.weights.tensors[k], gb.weights.tensors[k]);
    EXPECT_EQ(ga.latents.dim, gb.latents.dim);
    EXPECT_EQ(ga.latents.bits, gb.latents.bits);
    EXPECT_EQ(ga.latents.count, gb.latents.count);
    EXPECT_EQ(ga.latents.codes, gb.latents.codes);
    EXPECT_EQ(bits(ga.latents.scales), bits(gb.latents.scales));
  }
  EXPECT_EQ(std::bit_cast<uint32_t>(a.outputScale.exposure), std::bit_cast<uint32_t>(b.outputScale.exposure));
  EXPECT_EQ(std::bit_cast<uint32_t>(a.outputScale.range), std::bit_cast<uint32_t>(b.outputScale.range));
  EXPECT_EQ(a.fallback.kind, b.fallback.kind);
  EXPECT_EQ(a.fallback.precision, b.fallback.precision);
  EXPECT_EQ(bits(a.fallback.keyHours), bits(b.fallback.keyHours));
  EXPECT_EQ(bits(a.fallback.keyOvercast), bits(b.fallback.keyOvercast));
  EXPECT_EQ(a.fallback.shHalf, b.fallback.shHalf);
  EXPECT_EQ(a.stats.errorAchieved, b.stats.errorAchieved);
  EXPECT_EQ(a.stats.errorTarget, b.stats.errorTarget);
  EXPECT_EQ(a.stats.trainingSeconds, b.stats.trainingSeconds);
  EXPECT_EQ(a.stats.model, b.stats.model);
}

std::string errorOf(std::span<const std::byte> bytes, const std::string& name = "x.vdb") {
  try {
    decodeCellFile(bytes, name);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(CellFile, RoundTripIsBitExactForEveryVariant) {
  for (Variant v : {Variant::Int8Latents8, Variant::Fp16Latents4, Variant::PositionLatents,
                    Variant::NoNetwork, Variant::Int8Fallback}) {
    SCOPED_TRACE(int(v));
    CellFile c = makeCell(v);
    std::vector<std::byte> bytes = encodeCellFile(c);
    CellFileBytes parts;
    CellFile back = decodeCellFile(bytes, "mem", &parts);
    expectSameCell(c, back);
    // Deterministic: the same cell (and its decoded copy) encode to the same bytes.
    EXPECT_EQ(bytes, encodeCellFile(c));
    EXPECT_EQ(bytes, encodeCellFile(back));
    EXPECT_EQ(parts.total, bytes.size());
    EXPECT_EQ(parts.weights, c.generator ? c.generator->weights.bytes() : 0u);
    EXPECT_EQ(parts.latents, c.generator ? c.generator->latents.bytes() : 0u);
    EXPECT_EQ(parts.fallback, c.fallback.storedShBytes() + c.fallback.keyCount() * 8);
    EXPECT_EQ(parts.version, v == Variant::Int8Fallback ? 4 : 2);
    std::printf("variant %d: %zu bytes = weights %zu + latents %zu + fallback %zu + metadata/topology %zu\n",
                int(v), parts.total, parts.weights, parts.latents, parts.fallback, parts.metadata());
  }
  // All-active masks read back as the empty "all exist" form.
  CellFile c = makeCell(Variant::NoNetwork);
  c.active.assign(12, 1);
  c.fallback.shHalf.resize(c.fallback.keyCount() * 12 * 12);
  EXPECT_TRUE(decodeCellFile(encodeCellFile(c), "mem").active.empty());
}

TEST(CellFile, DequantizedModelDecodesFromTheFile) {
  CellFile c = makeCell(Variant::Int8Latents8);
  CellFile back = decodeCellFile(encodeCellFile(c), "mem");
  GeneratorWeights w = dequantizeWeights(back.generator->weights);
  std::vector<float> lat = dequantizeLatents(back.generator->latents);
  const GeneratorArch& a = w.arch;
  size_t n = size_t(back.generator->latents.count);
  std::vector<float> out(n * size_t(a.outChannels() * a.outputResolution() * a.outputResolution()));
  auto cond = conditioningVector(9.0f, 0.2f);
  generatorForward(w, lat, cond, n, out);
  for (float x : out) ASSERT_TRUE(std::isfinite(x));
}

TEST(CellFile, WriteIsAtomicAndReadChecksTheFile) {
  fs::path p = tmpDir() / "cell_-3_7.vdb";
  fs::remove(p);
  CellFile c = makeCell(Variant::Int8Latents8);
  writeCellFile(p, c);
  CellFileBytes parts;
  expectSameCell(c, readCellFile(p, &parts));
  EXPECT_EQ(parts.total, fs::file_size(p));

  // An invalid cell is refused before anything is written; the old file stays, no temp file is left.
  CellFile bad = c;
  bad.outputScale.exposure = std::nanf("");
  try {
    writeCellFile(p, bad);
    FAIL() << "NaN exposure written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("exposure nan must be finite"), std::string::npos) << e.what();
  }
  expectSameCell(c, readCellFile(p));
  // Only this file's temporaries: other tests of this directory may be writing theirs (ctest -j).
  const std::string tmpPrefix = p.filename().string() + ".tmp.";
  for (const auto& entry : fs::directory_iterator(p.parent_path()))
    EXPECT_FALSE(entry.path().filename().string().starts_with(tmpPrefix)) << entry.path();
  try {
    readCellFile(tmpDir() / "missing.vdb");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.vdb"), std::string::npos) << e.what();
  }
}

TEST(CellFile, VdbPrintListsTheFile) {
  if (std::system("command -v vdb_print >/dev/null 2>&1") != 0) GTEST_SKIP() << "vdb_print not installed";
  fs::path p = tmpDir() / "listed.vdb";
  writeCellFile(p, makeCell(Variant::Int8Latents8));
  std::string cmd = "vdb_print -l -m '" + p.string() + "' 2>&1";
  FILE* f = popen(cmd.c_str(), "r");
  ASSERT_NE(f, nullptr);
  std::string out;
  char buf[4096];
  while (size_t k = std::fread(buf, 1, sizeof buf, f)) out.append(buf, k);
  int rc = pclose(f);
  std::printf("%s", out.c_str());
  EXPECT_EQ(rc, 0);
  EXPECT_NE(out.find("lfgi_magic: lfgi-cell"), std::string::npos);
  EXPECT_NE(out.find("Name: probes"), std::string::npos);
  EXPECT_NE(out.find("Number of active voxels:       10"), std::string::npos);  // 12 probes, 2 disabled
  EXPECT_NE(out.find("voxel dimensions: [8, 4, 8]"), std::string::npos);
}

TEST(CellFile, EveryTruncationIsRejectedCleanly) {
  std::vector<std::byte> bytes = encodeCellFile(makeCell(Variant::Fp16Latents4));
  size_t rejected = 0;
  for (size_t len = 0; len < bytes.size(); ++len) {
    std::string e = errorOf(std::span(bytes).first(len), "cut.vdb");
    ASSERT_EQ(e.rfind("cut.vdb: ", 0), 0u) << "length " << len << ": '" << e << "'";
    ++rejected;
  }
  std::printf("%zu of %zu truncations rejected; e.g. '%s'\n", rejected, bytes.size(),
              errorOf(std::span(bytes).first(bytes.size() / 2), "cut.vdb").c_str());
  // Extra bytes after the trailer are refused too.
  std::vector<std::byte> longer = bytes;
  longer.push_back(std::byte{0});
  EXPECT_NE(errorOf(longer), "");
}

TEST(CellFile, RandomBitFlipsAreRejectedCleanly) {
  std::vector<std::byte> bytes = encodeCellFile(makeCell(Variant::Int8Latents8));
  std::mt19937 rng(2024);
  const int trials = 3000;
  for (int t = 0; t < trials; ++t) {
    std::vector<std::byte> b = bytes;
    int flips = 1 + t % 4;
    for (int k = 0; k < flips; ++k) {
      size_t pos = std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng);
      b[pos] ^= std::byte(1u << std::uniform_int_distribution<int>(0, 7)(rng));
    }
    if (b == bytes) continue;  // two flips of the same bit
    std::string e = errorOf(b, "flip.vdb");
    ASSERT_EQ(e.rfind("flip.vdb: ", 0), 0u) << "trial " << t << ": '" << e << "'";
  }
  // Each bit of the trailer (magic, length, checksum) on its own.
  for (size_t pos = bytes.size() - 24; pos < bytes.size(); ++pos)
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<std::byte> b = bytes;
      b[pos] ^= std::byte(1u << bit);
      ASSERT_NE(errorOf(b), "") << pos << "." << bit;
    }
}

struct BadFileCase {
  std::vector<detail::CellFileOverride> overrides;
  std::string expect;
};

TEST(CellFile, IntactButWrongFilesNameTheProblem) {
  CellFile c = makeCell(Variant::Int8Latents8);
  const std::vector<BadFileCase> cases = {
      {{{"lfgi_format_version", 99, ""}}, "cell file format version 99, this build reads versions 1 to 4"},
      {{{"lfgi_format_version", 0, ""}}, "cell file format version 0, this build reads versions 1 to 4"},
      {{{"lfgi_magic", 0, "not-a-cell"}}, "lfgi_magic is 'not-a-cell'"},
      {{{"latent_count", int64_t(1) << 40, ""}}, "field 'latent_count' = 1099511627776 outside [0, 4194304]"},
      {{{"latent_count", 9, ""}}, "latent_count = 9, but the file has 10 probes"},
      {{{"probe_count", 11, ""}}, "probe_count = 11, but grid 'probes' has 10 active voxels"},
      {{{"probe_dims", 0, "100000,100000,100000"}}, "probe grid: ProbeGrid: 1000000000000000 probes"},
      {{{"probe_dims", 0, "1000,1000,1000"}},
       "probe_dims 1000x1000x1000 = 1000000000 probes, more than the cell limit"},
      {{{"probe_dims", 0, "2,2,2"}}, "outside [0, 8]"},
      {{{"probe_dims", 0, "0,2,2"}}, "probe grid:"},
      {{{"generator_latent_dim", 100000, ""}}, "generator_latent_dim' = 100000 outside [1, 256]"},
      {{{"generator_conv_channels", 0, "8,x,11"}}, "not a comma-separated list"},
      {{{"generator_conv_channels", 0, "8,7,11"}}, "generator_weights ends after"},
      {{{"generator_weights", 0, "abc"}}, "generator_weights ends after 3 bytes"},
      {{{"latents", 0, std::string(40, '\0')}}, "latents ends after 40 bytes"},
      {{{"generator_weight_precision", 0, "int3"}}, "generator_weight_precision 'int3' is unknown"},
      {{{"latent_bits", 3, ""}}, "latent_bits' = 3 outside"},
      {{{"fallback_sh", 0, "xy"}}, "fallback_sh holds 2 bytes, 240 expected"},
      {{{"model", 0, "gan9000"}}, "model 'gan9000' is unknown"},
      {{{"input_hash", 0, "xyz"}}, "input_hash: 'xyz' is not 16 hex digits"},
      {{{"exposure", 5, ""}}, "field 'exposure' has type int64, expected float"},
  };
  for (const BadFileCase& bc : cases) {
    std::vector<std::byte> bytes = detail::encodeCellFileWithOverrides(c, bc.overrides);
    std::string e = errorOf(bytes, "bad.vdb");
    EXPECT_EQ(e.rfind("bad.vdb: ", 0), 0u) << e;
    EXPECT_NE(e.find(bc.expect), std::string::npos) << "field " << bc.overrides[0].field << ": '" << e << "'";
  }
  // A removed field.
  {
    std::vector<detail::CellFileOverride> o = {{"fallback_kind", 0, "sh_l3"}};
    EXPECT_NE(errorOf(detail::encodeCellFileWithOverrides(c, o)).find("fallback_kind 'sh_l3' is unknown"),
              std::string::npos);
  }
  // Not OpenVDB at all, and an OpenVDB file without our trailer.
  std::string text = "hello, this is not a cell file at all, just some text";
  EXPECT_NE(errorOf(std::as_bytes(std::span(text))).find("not a cell file (no OpenVDB magic"),
            std::string::npos);
  std::vector<std::byte> bytes = encodeCellFile(c);
  bytes.resize(bytes.size() - 24);
  EXPECT_NE(errorOf(bytes).find("trailer is missing"), std::string::npos) << errorOf(bytes);
  EXPECT_NE(errorOf({}).find("too short"), std::string::npos);
}

// NaN and Inf (docs/ARCHITECTURE.md "Bad input and interruption") in every kind of float the file holds:
// metadata fields, weight tensors (f32 biases, int8 scales, FP16 elements) and latent scales. The blobs are
// rebuilt in the writer's layout with one value replaced, so the file is intact (checksum valid) and only the
// value is wrong.
TEST(CellFile, NonFiniteValuesAreRejectedByName) {
  const CellFile c = makeCell(Variant::Int8Latents8);
  const std::pair<detail::CellFileOverride, std::string> fields[] = {
      {{"exposure", 0, "nan"}, "field 'exposure' is nan (must be finite)"},
      {{"range", 0, "inf"}, "field 'range' is inf (must be finite)"},
      {{"exposure", 0, "-2"}, "exposure -2 must be finite and > 0"},
      {{"error_achieved", 0, "nan"}, "field 'error_achieved' is nan"},
      {{"training_seconds", 0, "-inf"}, "field 'training_seconds' is -inf"},
      {{"error_target", 0, "-1"}, "errorTarget = -1 must be finite and >= 0"},
  };
  for (const auto& [o, expect] : fields) {
    const std::string e = errorOf(detail::encodeCellFileWithOverrides(c, std::span(&o, 1)), "nan.vdb");
    EXPECT_EQ(e.rfind("nan.vdb: ", 0), 0u) << e;
    EXPECT_NE(e.find(expect), std::string::npos) << o.field << ": '" << e << "'";
  }
  auto append = [](std::string& out, const auto& values) {
    out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(values[0]));
  };
  auto weightsBlob = [&](const QuantizedWeights& w) {
    std::string out;
    for (const QuantizedTensor& t : w.tensors) {
      append(out, t.f32);
      append(out, t.f16);
      append(out, t.scales);
      append(out, t.codes);
    }
    return out;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // The unmodified rebuilt blob is accepted: the layout above is the writer's.
  ASSERT_EQ(errorOf(detail::encodeCellFileWithOverrides(
                c, std::vector<detail::CellFileOverride>{{"generator_weights", 0,
                                                          weightsBlob(c.generator->weights)}})),
            "");
  QuantizedWeights w = c.generator->weights;
  ASSERT_EQ(w.tensors[1].encoding, TensorEncoding::Float32);  // linear bias
  w.tensors[1].f32[2] = nan;
  std::string e =
      errorOf(detail::encodeCellFileWithOverrides(
                  c, std::vector<detail::CellFileOverride>{{"generator_weights", 0, weightsBlob(w)}}),
              "nan.vdb");
  EXPECT_EQ(e.rfind("nan.vdb: ", 0), 0u) << e;
  EXPECT_NE(e.find("finite"), std::string::npos) << e;
  w = c.generator->weights;
  ASSERT_EQ(w.tensors[0].encoding, TensorEncoding::Int8PerChannel);
  w.tensors[0].scales[1] = std::numeric_limits<float>::infinity();
  e = errorOf(detail::encodeCellFileWithOverrides(
                  c, std::vector<detail::CellFileOverride>{{"generator_weights", 0, weightsBlob(w)}}),
              "nan.vdb");
  EXPECT_NE(e.find("scale 1 is inf"), std::string::npos) << e;
  // FP16 elements: the Fp16Latents4 variant stores FP16 weights.
  const CellFile h = makeCell(Variant::Fp16Latents4);
  w = h.generator->weights;
  ASSERT_EQ(w.tensors[0].encoding, TensorEncoding::Float16);
  w.tensors[0].f16[3] = 0x7e00;  // NaN
  e = errorOf(detail::encodeCellFileWithOverrides(
                  h, std::vector<detail::CellFileOverride>{{"generator_weights", 0, weightsBlob(w)}}),
              "nan.vdb");
  EXPECT_NE(e.find("FP16 element 3 is Inf or NaN"), std::string::npos) << e;
  // Latent scales: 8-bit latents are scales then one code per value.
  QuantizedLatents l = c.generator->latents;
  l.scales[0] = nan;
  std::string latents;
  append(latents, l.scales);
  append(latents, l.codes);
  e = errorOf(
      detail::encodeCellFileWithOverrides(c, std::vector<detail::CellFileOverride>{{"latents", 0, latents}}),
      "nan.vdb");
  EXPECT_EQ(e.rfind("nan.vdb: ", 0), 0u) << e;
  EXPECT_NE(e.find("scale 0 is nan"), std::string::npos) << e;
}

TEST(CellFile, WriterRejectsInconsistentCells) {
  CellFile c = makeCell(Variant::Int8Latents8);
  c.generator->latents.count -= 1;
  c.generator->latents.codes.resize(c.generator->latents.codes.size() - 8);
  EXPECT_THROW(encodeCellFile(c), Error);
  c = makeCell(Variant::Int8Latents8);
  c.fallback.shHalf.pop_back();
  EXPECT_THROW(encodeCellFile(c), Error);
  c = makeCell(Variant::NoNetwork);
  c.fallback.shHalf[3] = 0x7c00;  // +Inf
  EXPECT_THROW(encodeCellFile(c), Error);
  c = makeCell(Variant::NoNetwork);
  c.stats.trainingSeconds = -1.0;
  EXPECT_THROW(encodeCellFile(c), Error);
}

TEST(CellFile, BytesOfADefaultSizedCell) {
  // A 64 m cell at 4 m spacing (16 x 8 x 16 probes), the default generator (L16, C 32-16-11), int8 weights
  // and latents: the fixed OpenVDB cost (header, internal-node masks of the 5-4-3 tree) must stay what
  // the header comment says, so a regression in what we store shows here.
  std::mt19937 rng(3);
  CellFile c;
  c.grid.origin = {0.0f, 0.0f, 0.0f};
  c.grid.spacing = glm::vec3(4.0f);
  c.grid.dims = {16, 8, 16};
  GeneratorArch a;  // defaults
  CellGenerator g;
  g.weights = quantizeWeights(test::uniformRandomWeights(a, rng), WeightPrecision::Int8);
  std::vector<float> lat(size_t(c.grid.probeCount() * a.latentDim));
  for (float& x : lat) x = std::normal_distribution<float>(0.0f, 1.0f)(rng);
  g.latents = quantizeLatents(lat, a.latentDim, 8);
  c.generator = std::move(g);
  c.fallback.shHalf.assign(12, 0);
  CellFileBytes parts;
  auto t0 = std::chrono::steady_clock::now();
  std::vector<std::byte> bytes = encodeCellFile(c);
  auto t1 = std::chrono::steady_clock::now();
  decodeCellFile(bytes, "mem", &parts);
  auto t2 = std::chrono::steady_clock::now();
  std::printf("encode %.2f ms, decode (checksum + OpenVDB parse + checks) %.2f ms\n",
              std::chrono::duration<double, std::milli>(t1 - t0).count(),
              std::chrono::duration<double, std::milli>(t2 - t1).count());
  std::printf(
      "2048 probes, L16 C32-16-11 int8: total %zu B = weights %zu + latents %zu + fallback %zu + metadata "
      "%zu "
      "(%.1f B/probe)\n",
      parts.total, parts.weights, parts.latents, parts.fallback, parts.metadata(),
      double(parts.total) / 2048.0);
  EXPECT_EQ(parts.latents, 2048u * 16u + 16u * 4u);
  EXPECT_LT(parts.metadata(), 12000u);
}

TEST(CellFile, ConcurrentDecodesAgree) {
  // The streaming manager decodes on several IO threads at once.
  std::vector<std::byte> a = encodeCellFile(makeCell(Variant::Int8Latents8, 1));
  std::vector<std::byte> b = encodeCellFile(makeCell(Variant::Fp16Latents4, 2));
  std::atomic<int> mismatches{0};
  auto work = [&](const std::vector<std::byte>& bytes, const CellFile& want) {
    for (int i = 0; i < 20; ++i)
      if (encodeCellFile(decodeCellFile(bytes, "mem")) != bytes ||
          decodeCellFile(bytes, "mem").inputHash != want.inputHash)
        ++mismatches;
  };
  CellFile ca = makeCell(Variant::Int8Latents8, 1), cb = makeCell(Variant::Fp16Latents4, 2);
  std::thread t1(work, std::cref(a), std::cref(ca)), t2(work, std::cref(b), std::cref(cb));
  t1.join();
  t2.join();
  EXPECT_EQ(mismatches.load(), 0);
}

// Raw float32 bytes, as a blob override's text.
std::string floatBytes(std::initializer_list<float> v) {
  std::string s(v.size() * sizeof(float), '\0');
  std::memcpy(s.data(), std::data(v), s.size());
  return s;
}

TEST(CellFile, FallbackKeysRoundTripBitExact) {
  // Version 2: three keys of per-cell SH, each key's 12 halves distinct, read back bit for bit.
  CellFile c = makeCell(Variant::Fp16Latents4);
  ASSERT_EQ(c.fallback.keyCount(), 3u);
  c.fallback.keyHours = {8.0f, 12.0f, 17.5f};
  c.fallback.keyOvercast = {0.0f, 0.25f, 0.0f};
  c.fallback.shHalf.clear();
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 12; ++i)
      c.fallback.shHalf.push_back(floatToHalfClamped(0.1f * float(k + 1) + 0.01f * float(i)));
  const std::vector<std::byte> bytes = encodeCellFile(c);
  CellFileBytes parts;
  const CellFile back = decodeCellFile(bytes, "keys.vdb", &parts);
  expectSameCell(c, back);
  ASSERT_EQ(back.fallback.keyCount(), 3u);
  EXPECT_EQ(back.fallback.keyHours[2], 17.5f);
  EXPECT_EQ(back.fallback.keyOvercast[1], 0.25f);
  EXPECT_EQ(back.fallback.shHalf[24], floatToHalfClamped(0.3f));  // key 2, first half
  EXPECT_EQ(parts.fallback, 3u * 12u * 2u + 3u * 8u);
  EXPECT_EQ(bytes, encodeCellFile(back));
}

TEST(CellFile, VersionOneFilesStillRead) {
  // A version-1 file: the fields the version-1 writer wrote (no fallback key fields, one key of SH).
  const std::vector<detail::CellFileOverride> v1 = {{"lfgi_format_version", 1, ""},
                                                    {"fallback_key_count", 0, "", true},
                                                    {"fallback_key_hours", 0, "", true},
                                                    {"fallback_key_overcast", 0, "", true}};
  for (Variant v : {Variant::Int8Latents8}) {
    CellFile c = makeCell(v);  // one key (per-probe SH)
    c.fallback.keyHours = {12.0f};
    c.fallback.keyOvercast = {0.0f};
    CellFileBytes parts;
    const CellFile back = decodeCellFile(detail::encodeCellFileWithOverrides(c, v1), "v1.vdb", &parts);
    expectSameCell(c, back);
    EXPECT_EQ(back.fallback.keyCount(), 1u);
    EXPECT_EQ(parts.fallback, c.fallback.shHalf.size() * 2);  // no key blobs in a version-1 file
  }
  // A PerCell version-1 cell with its single key at another hour reads as 12 h (v1 records none).
  CellFile c = makeCell(Variant::Fp16Latents4);
  c.fallback.keyHours = {8.0f};
  c.fallback.keyOvercast = {0.0f};
  c.fallback.shHalf.resize(12);
  const CellFile back = decodeCellFile(detail::encodeCellFileWithOverrides(c, v1), "v1.vdb");
  EXPECT_EQ(back.fallback.keyHours, std::vector<float>{12.0f});
  EXPECT_EQ(back.fallback.shHalf, c.fallback.shHalf);
  // A version-1 file cannot hold several keys' SH, nor version-2 key fields.
  std::string e = errorOf(detail::encodeCellFileWithOverrides(makeCell(Variant::Fp16Latents4), v1), "v1.vdb");
  EXPECT_NE(e.find("v1.vdb: fallback_sh holds 72 bytes, 24 expected (1 keys x 1 x 12 halves)"),
            std::string::npos)
      << e;
  const std::vector<detail::CellFileOverride> v1WithKeys = {{"lfgi_format_version", 1, ""}};
  e = errorOf(detail::encodeCellFileWithOverrides(c, v1WithKeys), "v1.vdb");
  EXPECT_NE(e.find("v1.vdb: a version-1 cell file holds field 'fallback_key_count'"), std::string::npos) << e;
}

// The int8 fallback layout (version 4): 15 B per entry, and the reader and writer hold its contract.
TEST(CellFile, Int8FallbackStoresFifteenBytesPerEntryAndChecksThem) {
  const CellFile c = makeCell(Variant::Int8Fallback);  // 10 probes x 3 keys
  const CellFile fp16 = makeCell(Variant::NoNetwork);
  CellFileBytes parts, fp16Parts;
  decodeCellFile(encodeCellFile(c), "mem", &parts);
  decodeCellFile(encodeCellFile(fp16), "mem", &fp16Parts);
  EXPECT_EQ(parts.fallback, 30u * 15u + 3u * 8u);
  EXPECT_EQ(fp16Parts.fallback, 30u * 24u + 3u * 8u);
  EXPECT_LT(parts.total, fp16Parts.total);
  // Entries that are not the quantizer's fixed point are refused by the writer.
  CellFile off = c;
  off.fallback.shHalf[5] ^= 1u;  // an L1 half one bit away from what its code decodes to
  try {
    encodeCellFile(off);
    ADD_FAILURE() << "wrote a non-int8 entry";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("fallback entry 0 is not in the int8 layout"), std::string::npos)
        << e.what();
  }
  // The packed blob with one code the writer never writes (-128).
  std::string blob(30 * 15, '\0');
  for (size_t e = 0; e < 30; ++e)
    packShL1Q8(c.fallback.shHalf.data() + e * 12, (uint8_t*)blob.data() + e * 15);
  blob[15 + 6] = char(0x80);
  const std::vector<BadFileCase> cases = {
      {{{"lfgi_format_version", 3, ""}}, "a version-3 cell file holds field 'fallback_precision'"},
      {{{"fallback_precision", 0, "", true}}, "fallback_precision"},
      {{{"fallback_precision", 0, "int4"}}, "fallback_precision 'int4' is unknown (fp16, l1_int8)"},
      {{{"fallback_sh", 0, std::string(720, '\0')}}, "fallback_sh holds 720 bytes, 450 expected"},
      {{{"fallback_sh", 0, blob}}, "fallback_sh entry 1 holds an L1 code the int8 layout never writes"},
  };
  for (const BadFileCase& bc : cases) {
    const std::string e = errorOf(detail::encodeCellFileWithOverrides(c, bc.overrides), "q8.vdb");
    EXPECT_EQ(e.rfind("q8.vdb: ", 0), 0u) << e;
    EXPECT_NE(e.find(bc.expect), std::string::npos) << "field " << bc.overrides[0].field << ": '" << e << "'";
  }
}

TEST(CellFile, BadFallbackKeysAreRejectedByName) {
  const CellFile c = makeCell(Variant::Fp16Latents4);  // keys 8, 12, 17.5 h
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<BadFileCase> cases = {
      {{{"fallback_key_hours", 0, floatBytes({8.0f, nan, 17.5f})}},
       "fallback key 1 hours = nan (must be finite, in [0, 24])"},
      {{{"fallback_key_hours", 0, floatBytes({8.0f, 12.0f, 24.5f})}},
       "fallback key 2 hours = 24.5 (must be finite, in [0, 24])"},
      {{{"fallback_key_hours", 0, floatBytes({-1.0f, 12.0f, 17.5f})}}, "fallback key 0 hours = -1"},
      {{{"fallback_key_hours", 0, floatBytes({12.0f, 8.0f, 17.5f})}},
       "fallback keys not sorted strictly ascending by (hours, overcast): key 1 (8 h, overcast 0) after key "
       "0 (12 h"},
      {{{"fallback_key_hours", 0, floatBytes({8.0f, 12.0f, 12.0f})}}, "not sorted strictly ascending"},
      {{{"fallback_key_overcast", 0, floatBytes({0.0f, 2.0f, 0.0f})}}, "fallback key 1 overcast = 2"},
      {{{"fallback_key_hours", 0, floatBytes({8.0f, 12.0f})}},
       "fallback_key_hours holds 8 bytes, 12 expected (3 keys x float32)"},
      {{{"fallback_key_overcast", 0, floatBytes({0.0f})}},
       "fallback_key_overcast holds 4 bytes, 12 expected"},
      {{{"fallback_key_count", 2, ""}}, "fallback_key_hours holds 12 bytes, 8 expected (2 keys x float32)"},
      {{{"fallback_key_count", 0, ""}}, "field 'fallback_key_count' = 0 outside [1, 64]"},
      {{{"fallback_key_count", 1000, ""}}, "field 'fallback_key_count' = 1000 outside [1, 64]"},
      {{{"fallback_key_count", 2, ""},
        {"fallback_key_hours", 0, floatBytes({8.0f, 12.0f})},
        {"fallback_key_overcast", 0, floatBytes({0.0f, 0.0f})}},
       "fallback_sh holds 72 bytes, 48 expected (2 keys x 1 x 12 halves)"},
      {{{"fallback_key_hours", 0, "", true}}, "field 'fallback_key_hours' is missing"},
  };
  for (const BadFileCase& bc : cases) {
    std::string e = errorOf(detail::encodeCellFileWithOverrides(c, bc.overrides), "keys.vdb");
    EXPECT_EQ(e.rfind("keys.vdb: ", 0), 0u) << e;
    EXPECT_NE(e.find(bc.expect), std::string::npos) << "field " << bc.overrides[0].field << ": '" << e << "'";
  }
  // The writer refuses the same cells.
  CellFile w = c;
  w.fallback.keyHours[1] = nan;
  EXPECT_THROW(encodeCellFile(w), Error);
  w = c;
  w.fallback.keyHours = {17.5f, 12.0f, 8.0f};
  EXPECT_THROW(encodeCellFile(w), Error);
  w = c;
  w.fallback.keyOvercast.pop_back();
  EXPECT_THROW(encodeCellFile(w), Error);
  w = c;
  w.fallback.shHalf.resize(24);  // 2 keys' SH for 3 keys
  EXPECT_THROW(encodeCellFile(w), Error);
  w = c;
  w.fallback.keyHours.clear();
  w.fallback.keyOvercast.clear();
  EXPECT_THROW(encodeCellFile(w), Error);
}

TEST(CellFile, ContentHasherIsDeterministicAndOrderSensitive) {
  auto h = [](const std::string& a, const std::string& b) { return ContentHasher().add(a).add(b).digest(); };
  EXPECT_EQ(h("mesh", "grid"), h("mesh", "grid"));
  EXPECT_NE(h("mesh", "grid"), h("grid", "mesh"));
  EXPECT_NE(h("ab", "c"), h("a", "bc"));
  int64_t x = 5;
  EXPECT_NE(ContentHasher().addValue(x).digest(), ContentHasher().addValue(x + 1).digest());
}

}  // namespace
}  // namespace lfgi
