#include "core/shared_model.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>

#include "core/error.h"
#include "core/half.h"
#include "generator_test_util.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

GeneratorArch smallArch() {
  GeneratorArch a;
  a.latentDim = 8;
  a.convChannels = {8, 6, kGeneratorChannels};
  return a;
}

SharedModel makeModel(uint32_t seed = 3) {
  std::mt19937 rng(seed);
  SharedModel m;
  m.worldSeed = 0x1122334455667788ull;
  m.inputHash = 0xabcdef0123456789ull + seed;
  m.weights = quantizeWeights(test::uniformRandomWeights(smallArch(), rng), WeightPrecision::Int8);
  m.stats = {1234, 56.5, 0.0375, "0,1 field; 2,0 city"};
  return m;
}

ResolvedSharedModel resolved(const SharedModel& m) {
  ResolvedSharedModel r;
  r.weights = dequantizeWeights(m.weights);
  r.hash = weightsContentHash(r.weights);
  r.name = "w/shared_model.vdb";
  return r;
}

// A 3x2x2 cell (two probes disabled) that refers to `model` with a 2-stage adapter.
CellFile makeSharedCell(const SharedModel& model, int adapterBits = 8) {
  std::mt19937 rng(11);
  std::normal_distribution<float> nd(0.0f, 0.2f);
  CellFile c;
  c.worldSeed = model.worldSeed;
  c.cellX = 2;
  c.cellZ = -1;
  c.inputHash = 0x5555aaaa5555aaaaull;
  c.grid.origin = {128.0f, 0.5f, -64.0f};
  c.grid.spacing = {8.0f, 4.0f, 8.0f};
  c.grid.dims = {3, 2, 2};
  c.active = {1, 1, 0, 1, 1, 1, 1, 0, 1, 1, 1, 1};
  const GeneratorArch a = model.weights.arch;
  CellGenerator g;
  g.weights.arch = a;
  g.weights.precision = model.weights.precision;
  std::vector<float> lat(size_t(c.activeProbeCount() * a.latentDim));
  for (float& x : lat) x = nd(rng) * 5.0f;
  g.latents = quantizeLatents(lat, a.latentDim, 8);
  GeneratorAdapter ad = identityAdapter(a, 2);
  for (float& x : ad.scale) x = nd(rng);
  for (float& x : ad.shift) x = nd(rng);
  g.shared = CellSharedModelRef{model.weightsHash(), quantizeAdapter(ad, adapterBits)};
  c.generator = std::move(g);
  c.outputScale = {2.5f, 80.0f};
  c.fallback.keyHours = {8.0f, 17.5f};
  c.fallback.keyOvercast = {0.0f, 0.0f};
  for (int i = 0; i < 24; ++i) c.fallback.shHalf.push_back(floatToHalfClamped(0.1f * float(i % 5)));
  c.stats = {0.031, 0.05, 0.0, "shared z8 C8-6 + FiLM 2 int8"};
  return c;
}

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Every truncation and 2000 seeded 1-4 bit flips give an error starting with "<name>: ".
void expectCorruptionRejected(
    const std::vector<std::byte>& bytes,
    const std::function<void(std::span<const std::byte>, const std::string&)>& decode) {
  for (size_t len = 0; len < bytes.size(); ++len) {
    const std::string e = errorOf([&] { decode(std::span(bytes).first(len), "cut.vdb"); });
    ASSERT_EQ(e.rfind("cut.vdb: ", 0), 0u) << "length " << len << ": '" << e << "'";
  }
  std::mt19937 rng(77);
  for (int t = 0; t < 2000; ++t) {
    std::vector<std::byte> b = bytes;
    for (int k = 0; k < 1 + t % 4; ++k)
      b[std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng)] ^= std::byte(1u << (t + k) % 8);
    if (b == bytes) continue;
    const std::string e = errorOf([&] { decode(b, "flip.vdb"); });
    ASSERT_EQ(e.rfind("flip.vdb: ", 0), 0u) << "trial " << t << ": '" << e << "'";
  }
  std::printf("%zu truncations and 2000 bit flips of a %zu-byte file rejected\n", bytes.size(), bytes.size());
}

std::vector<uint32_t> bits(const std::vector<float>& v) {
  std::vector<uint32_t> b;
  for (float x : v) b.push_back(std::bit_cast<uint32_t>(x));
  return b;
}

TEST(SharedModel, RoundTripIsBitExact) {
  const SharedModel m = makeModel();
  const fs::path p = fs::path(LFGI_TEST_TMP_DIR) / "shared_model" / "shared_model.vdb";
  fs::create_directories(p.parent_path());
  writeSharedModel(p, m);
  uint64_t hash = 0;
  const SharedModel back = readSharedModel(p, &hash);
  EXPECT_EQ(hash, m.weightsHash());
  EXPECT_NE(hash, 0u);
  EXPECT_EQ(back.worldSeed, m.worldSeed);
  EXPECT_EQ(back.inputHash, m.inputHash);
  EXPECT_EQ(back.weights.arch.convChannels, m.weights.arch.convChannels);
  EXPECT_EQ(back.weights.precision, m.weights.precision);
  ASSERT_EQ(back.weights.tensors.size(), m.weights.tensors.size());
  for (size_t k = 0; k < m.weights.tensors.size(); ++k) {
    EXPECT_EQ(back.weights.tensors[k].codes, m.weights.tensors[k].codes);
    EXPECT_EQ(bits(back.weights.tensors[k].scales), bits(m.weights.tensors[k].scales));
    EXPECT_EQ(bits(back.weights.tensors[k].f32), bits(m.weights.tensors[k].f32));
  }
  EXPECT_EQ(back.stats.steps, 1234);
  EXPECT_EQ(back.stats.seconds, 56.5);
  EXPECT_EQ(back.stats.errorAchieved, 0.0375);
  EXPECT_EQ(back.stats.cells, m.stats.cells);
  EXPECT_EQ(encodeSharedModel(back), encodeSharedModel(m));  // deterministic bytes
  std::printf("shared model file: %zu bytes (int8 weights %zu)\n", fs::file_size(p), m.weights.bytes());
}

TEST(SharedModel, CorruptFilesAreRejectedCleanly) {
  expectCorruptionRejected(
      encodeSharedModel(makeModel()),
      [](std::span<const std::byte> b, const std::string& n) { decodeSharedModel(b, n); });
  // A cell file is not a shared model file, and the other way round.
  const SharedModel m = makeModel();
  EXPECT_NE(errorOf([&] {
              decodeSharedModel(encodeCellFile(makeSharedCell(m)), "c.vdb");
            }).find("c.vdb: truncated or not a shared model file"),
            std::string::npos);
  EXPECT_NE(errorOf([&] {
              decodeCellFile(encodeSharedModel(m), "s.vdb");
            }).find("s.vdb: truncated or not a cell file"),
            std::string::npos);
}

TEST(SharedModel, IntactButWrongFilesNameTheProblem) {
  const SharedModel m = makeModel();
  auto err = [&](std::vector<detail::CellFileOverride> o) {
    return errorOf([&] { decodeSharedModel(detail::encodeSharedModelWithOverrides(m, o), "s.vdb"); });
  };
  std::string e = err({{"weights_hash", 0, "0000000000000001"}});
  EXPECT_NE(e.find("s.vdb: weights_hash is 0000000000000001, the stored weights hash to"), std::string::npos)
      << e;
  e = err({{"lfgi_format_version", 2, ""}});
  EXPECT_NE(e.find("s.vdb: shared model format version 2"), std::string::npos) << e;
  e = err({{"generator_weights", 0, "abc"}});
  EXPECT_NE(e.find("s.vdb: generator_weights ends after 3 bytes"), std::string::npos) << e;
  e = err({{"training_seconds", 0, "nan"}});
  EXPECT_NE(e.find("s.vdb: field 'training_seconds' is nan"), std::string::npos) << e;
  e = err({{"lfgi_magic", 0, "lfgi-cell"}});
  EXPECT_NE(e.find("not a shared model file"), std::string::npos) << e;
}

TEST(SharedModel, VersionThreeCellRoundTripIsBitExact) {
  const SharedModel m = makeModel();
  for (int adapterBits : {8, 4}) {
    const CellFile c = makeSharedCell(m, adapterBits);
    const std::vector<std::byte> bytes = encodeCellFile(c);
    CellFileBytes parts;
    const CellFile back = decodeCellFile(bytes, "v3.vdb", &parts);
    EXPECT_EQ(parts.version, 3);
    EXPECT_EQ(parts.weights, 0u);
    EXPECT_EQ(parts.adapter, c.generator->shared->adapter.bytes() - 1);  // stages is a field, not in the blob
    EXPECT_EQ(parts.latents, c.generator->latents.bytes());
    ASSERT_TRUE(back.generator && back.generator->shared);
    const CellSharedModelRef &a = *c.generator->shared, &b = *back.generator->shared;
    EXPECT_EQ(b.modelHash, a.modelHash);
    EXPECT_EQ(b.adapter.stages, a.adapter.stages);
    EXPECT_EQ(b.adapter.bits, adapterBits);
    EXPECT_EQ(b.adapter.channels, a.adapter.channels);
    EXPECT_EQ(b.adapter.codes, a.adapter.codes);
    EXPECT_EQ(bits(b.adapter.scales), bits(a.adapter.scales));
    EXPECT_TRUE(back.generator->weights.tensors.empty());
    EXPECT_EQ(back.generator->weights.arch.convChannels, m.weights.arch.convChannels);
    EXPECT_EQ(back.generator->latents.codes, c.generator->latents.codes);
    EXPECT_EQ(encodeCellFile(back), bytes);
    std::printf("v3 cell, %d-bit adapter: %zu bytes (adapter %zu, latents %zu, fallback %zu, metadata %zu)\n",
                adapterBits, parts.total, parts.adapter, parts.latents, parts.fallback, parts.metadata());
  }
  // A cell with its own weights is still written as version 2 (what v2 readers read).
  CellFile own = makeSharedCell(m);
  own.generator->shared.reset();
  own.generator->weights = m.weights;
  CellFileBytes parts;
  decodeCellFile(encodeCellFile(own), "v2.vdb", &parts);
  EXPECT_EQ(parts.version, 2);
  EXPECT_EQ(parts.adapter, 0u);
}

TEST(SharedModel, CorruptVersionThreeCellsAreRejectedCleanly) {
  expectCorruptionRejected(encodeCellFile(makeSharedCell(makeModel())),
                           [](std::span<const std::byte> b, const std::string& n) { decodeCellFile(b, n); });
}

TEST(SharedModel, VersionThreeFieldsAreCheckedByName) {
  const SharedModel m = makeModel();
  const CellFile c = makeSharedCell(m);
  auto err = [&](std::vector<detail::CellFileOverride> o) {
    return errorOf([&] { decodeCellFile(detail::encodeCellFileWithOverrides(c, o), "v3.vdb"); });
  };
  struct Case {
    std::vector<detail::CellFileOverride> o;
    std::string expect;
  };
  const std::vector<Case> cases = {
      {{{"shared_model_hash", 0, "0000000000000000"}}, "v3.vdb: shared_model_hash is 0"},
      {{{"shared_model_hash", 0, "xyz"}}, "v3.vdb: shared_model_hash: 'xyz' is not 16 hex digits"},
      {{{"adapter_channels", 9, ""}},
       "v3.vdb: adapter: adapter of 9 channels, 2 stages of the model have 14"},
      {{{"adapter_stages", 7, ""}}, "v3.vdb: field 'adapter_stages' = 7 outside [0, 3]"},
      {{{"adapter_bits", 6, ""}}, "v3.vdb: adapter: 6 bits per adapter code"},
      {{{"adapter", 0, "12345"}}, "v3.vdb: adapter ends after 5 bytes"},
      {{{"adapter", 0, "", true}}, "v3.vdb: field 'adapter' is missing"},
      {{{"lfgi_format_version", 2, ""}}, "v3.vdb: a version-2 cell file refers to a shared model"},
      {{{"generator_weights", 0, "w"}}, "v3.vdb: a shared-model cell holds its own 'generator_weights'"},
      {{{"latent_count", 3, ""}}, "v3.vdb: latent_count = 3, but the file has 10 probes"},
      {{{"generator_conv_channels", 0, "0,6,11"}}, "v3.vdb: generator architecture"},
  };
  for (const Case& k : cases) {
    const std::string e = err(k.o);
    EXPECT_NE(e.find(k.expect), std::string::npos) << "expected '" << k.expect << "', got '" << e << "'";
  }
  // A cell with its own weights may not carry a shared reference's fields.
  CellFile own = c;
  own.generator->shared.reset();
  own.generator->weights = m.weights;
  const std::string e = errorOf([&] {
    decodeCellFile(
        detail::encodeCellFileWithOverrides(
            own, std::vector<detail::CellFileOverride>{{"shared_model_hash", 0, "0000000000000001"}}),
        "v2.vdb");
  });
  EXPECT_NE(e.find("v2.vdb: a cell with its own weights holds field 'shared_model_hash'"), std::string::npos)
      << e;
  // The writer refuses an inconsistent reference.
  CellFile bad = c;
  bad.generator->shared->modelHash = 0;
  EXPECT_NE(errorOf([&] { encodeCellFile(bad); }).find("shared model hash is 0"), std::string::npos);
  bad = c;
  bad.generator->shared->adapter.codes.pop_back();
  EXPECT_NE(errorOf([&] { encodeCellFile(bad); }).find("adapter"), std::string::npos);
  bad = c;
  bad.generator->weights = m.weights;  // own tensors and a reference
  EXPECT_NE(errorOf([&] { encodeCellFile(bad); }).find("holds 6 weight tensors of its own"),
            std::string::npos);
}

TEST(SharedModel, ResolveFoldsTheAdapterAndNamesBothFiles) {
  const SharedModel m = makeModel();
  const CellFile c = decodeCellFile(encodeCellFile(makeSharedCell(m)), "c.vdb");
  const ResolvedSharedModel r = resolved(m);
  const GeneratorWeights w = resolveCellWeights(*c.generator, &r, "c.vdb");
  const GeneratorWeights byHand =
      applyAdapter(dequantizeWeights(m.weights), dequantizeAdapter(c.generator->shared->adapter));
  EXPECT_EQ(weightsContentHash(w), weightsContentHash(byHand));
  EXPECT_NE(weightsContentHash(w), r.hash);  // the adapter changed something
  std::string e = errorOf([&] { resolveCellWeights(*c.generator, nullptr, "c.vdb"); });
  EXPECT_NE(e.find("c.vdb: refers to shared model"), std::string::npos) << e;
  EXPECT_NE(e.find("no shared model file is loaded"), std::string::npos) << e;
  const ResolvedSharedModel other = resolved(makeModel(4));
  e = errorOf([&] { resolveCellWeights(*c.generator, &other, "c.vdb"); });
  EXPECT_NE(e.find("c.vdb: refers to shared model"), std::string::npos) << e;
  EXPECT_NE(e.find("but w/shared_model.vdb holds"), std::string::npos) << e;
}

TEST(SharedModel, VdbPrintListsTheFile) {
  if (std::system("command -v vdb_print >/dev/null 2>&1") != 0) GTEST_SKIP() << "vdb_print not installed";
  const fs::path p = fs::path(LFGI_TEST_TMP_DIR) / "shared_model" / "listed.vdb";
  fs::create_directories(p.parent_path());
  writeSharedModel(p, makeModel());
  FILE* f = popen(("vdb_print -m '" + p.string() + "' 2>&1").c_str(), "r");
  ASSERT_NE(f, nullptr);
  std::string out;
  char buf[4096];
  while (size_t k = std::fread(buf, 1, sizeof buf, f)) out.append(buf, k);
  const int rc = pclose(f);
  std::printf("%s", out.c_str());
  EXPECT_EQ(rc, 0);
  EXPECT_NE(out.find("lfgi_magic: lfgi-shared-model"), std::string::npos);
}

}  // namespace
}  // namespace lfgi
