// Benchmark `codec`: rate-distortion-speed of the probe codecs (docs/docs/DESIGN.md §4-5) on the same
// ground-truth probes: the Cornell box, Sponza and synthetic cells of every kind (field, suburb, city blocks
// of each type, park) of the default 256 m world, captured with Embree (bake/probe_capture.h, low sample
// counts) and cached under --cache so re-runs skip the capture.
//
// Per scene and codec: all-in bytes per probe (the codec's whole byte string / probes), irradiance
// relative RMS against the capture's irradiance (SH codecs evaluate irradiance from their coefficients,
// the others go through deriveIrradiance, the capture's own texel sum; the "reference_fp32" row passes the
// float radiance through unchanged, so its irradiance error is the floor every radiance codec shares: the
// capture adds the sun analytically, a 16 x 16 map holds it in one texel; with --sun separate, the default,
// the sun is taken out of the maps, see splitSun), radiance relative RMS (of what the codec stores), radiance
// PSNR (peak = the scene's largest reference radiance value), and encode / decode µs per probe on one CPU
// thread (OpenBLAS limited to 1 thread; best of several repetitions). irr_codec_rel_rms is the codec's own
// loss: irradiance against the irradiance of the uncompressed float radiance (same derivation), without
// the sun floor. Pooled rows (scene "kind" per scene kind, scene "all" over every scene): bytes = total
// bytes / total probes, errors = mean of the per-scene errors.
//
// The generative codecs ("gan" rows: a per-cell generator, GanCodec below, --no-gan skips its training;
// "shared_adapter" rows: latents + FiLM adapter against one world-shared generator, SharedAdapterCodec,
// --no-shared) fill summary.json's codec_* keys: the cheapest of their settings at SH L2's irradiance error
// (shared rows with the shared model's bytes spread over the default world), else the most accurate row
// (codec_reached_sh_l2_error false). The best baseline at SH L2's error is reported beside it, and
// summary.json "shared_generator" holds the shared rows over all scenes and over the synthetic cells alone.
#include <cblas.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

#include "bake/embree_scene.h"
#include "bake/generator_training.h"
#include "bake/probe_capture.h"
#include "bench/bench_output.h"
#include "core/byte_stream.h"
#include "core/cell_file.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/hash.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/probe_codecs.h"
#include "core/progress.h"
#include "core/sh.h"
#include "worlds/gltf_io.h"
#include "worlds/world_cells.h"

namespace fs = std::filesystem;
using namespace lfgi;

namespace {

// ------------------------------------------------------------------------------------------------ scenes

struct SceneSpec {
  std::string name;  // csv "scene"
  std::string kind;  // csv "kind": cornell, sponza, field, suburb, city, park
  worlds::TriangleMesh mesh;
  std::vector<glm::vec3> positions;
};

// Every stride-th active probe of a synthetic cell, up to `want`, so the sample spans the cell's layers.
SceneSpec worldCell(const worlds::SyntheticWorld& world, worlds::CellCoord c, size_t want) {
  worlds::BuiltCell built = worlds::buildCell(world, c);
  SceneSpec s;
  s.kind = std::string(worlds::cellKindName(built.stats.kind));
  s.name = fmt::format("cell_{}_{}_{}", c.x, c.z, s.kind);
  std::vector<glm::vec3> all;
  for (int64_t i = 0; i < built.probes.grid.probeCount(); ++i)
    if (!(built.probes.flags[size_t(i)] & worlds::kProbeDisabledSolid))
      all.push_back(built.probes.position(i));
  const size_t stride = std::max<size_t>(1, all.size() / want);
  for (size_t i = 0; i < all.size() && s.positions.size() < want; i += stride) s.positions.push_back(all[i]);
  s.mesh = std::move(built.mesh);
  for (int dz = -1; dz <= 1; ++dz)
    for (int dx = -1; dx <= 1; ++dx)
      if ((dx || dz) && world.contains({c.x + dx, c.z + dz}))
        s.mesh.append(world.generateCell({c.x + dx, c.z + dz}));
  return s;
}

SceneSpec presetScene(const std::string& preset, const std::string& scenesDir, glm::ivec3 dims) {
  worlds::ScenePreset p = worlds::findScenePreset(preset);
  p.probeDims = dims;
  SceneSpec s;
  s.name = preset;
  s.kind = preset;
  s.mesh = worlds::loadScenePreset(p, scenesDir);
  const ProbeGrid grid = worlds::presetProbeGrid(p, s.mesh.bounds());
  for (int64_t i = 0; i < grid.probeCount(); ++i)
    s.positions.push_back(grid.probePosition(grid.probeCoord(i)));
  return s;
}

// ------------------------------------------------------------------------------------------ capture cache

struct Captured {
  int n = 0, m = 0;
  std::vector<glm::vec3> positions;
  std::vector<float> radiance, irradiance;
};

constexpr char kCacheMagic[8] = {'L', 'F', 'G', 'I', 'C', 'C', 'A', '1'};

// Cache key: everything the capture depends on (options, sky time, probe positions, mesh content).
uint64_t captureKey(const SceneSpec& s, const bake::CaptureOptions& co, float timeOfDay) {
  uint64_t h = kFnv1aOffset;
  h = fnv1a(h, s.name.data(), s.name.size());
  const int opts[5] = {co.resolution, co.irradianceResolution, co.samplesPerTexel, co.maxBounces,
                       co.rouletteAfter};
  h = fnv1a(h, opts, sizeof opts);
  h = fnv1a(h, &co.seed, sizeof co.seed);
  h = fnv1a(h, &timeOfDay, sizeof timeOfDay);
  h = fnv1a(h, s.positions.data(), s.positions.size() * sizeof(glm::vec3));
  const uint64_t mesh = s.mesh.contentHash();
  return fnv1a(h, &mesh, sizeof mesh);
}

std::optional<Captured> readCache(const fs::path& file, size_t probes, int n, int m) {
  if (!fs::exists(file)) return std::nullopt;
  const std::vector<std::byte> b = readFileBytes(file);
  const size_t rad = probes * size_t(n * n * 3), irr = probes * size_t(m * m * 3);
  const size_t want = sizeof kCacheMagic + probes * sizeof(glm::vec3) + 4 * (rad + irr);
  if (b.size() != want || std::memcmp(b.data(), kCacheMagic, sizeof kCacheMagic) != 0) {
    spdlog::warn("{}: stale or damaged capture cache, capturing again", file.string());
    return std::nullopt;
  }
  Captured c;
  c.n = n;
  c.m = m;
  c.positions.resize(probes);
  c.radiance.resize(rad);
  c.irradiance.resize(irr);
  const std::byte* p = b.data() + sizeof kCacheMagic;
  std::memcpy(c.positions.data(), p, probes * sizeof(glm::vec3));
  p += probes * sizeof(glm::vec3);
  std::memcpy(c.radiance.data(), p, 4 * rad);
  std::memcpy(c.irradiance.data(), p + 4 * rad, 4 * irr);
  return c;
}

void writeCache(const fs::path& file, const Captured& c) {
  std::vector<std::byte> b(sizeof kCacheMagic + c.positions.size() * sizeof(glm::vec3) +
                           4 * (c.radiance.size() + c.irradiance.size()));
  std::byte* p = b.data();
  std::memcpy(p, kCacheMagic, sizeof kCacheMagic);
  p += sizeof kCacheMagic;
  std::memcpy(p, c.positions.data(), c.positions.size() * sizeof(glm::vec3));
  p += c.positions.size() * sizeof(glm::vec3);
  std::memcpy(p, c.radiance.data(), 4 * c.radiance.size());
  std::memcpy(p + 4 * c.radiance.size(), c.irradiance.data(), 4 * c.irradiance.size());
  fs::create_directories(file.parent_path());
  writeFileAtomic(file, b);
}

Captured capture(SceneSpec& s, const bake::CaptureOptions& co, const worlds::SkyModel& sky, float timeOfDay,
                 const fs::path& cacheDir) {
  const fs::path file = cacheDir / fmt::format("{}_{:016x}.bin", s.name, captureKey(s, co, timeOfDay));
  if (auto c = readCache(file, s.positions.size(), co.resolution, co.irradianceResolution)) {
    spdlog::info("{}: {} probes from the capture cache {}", s.name, s.positions.size(), file.string());
    return *c;
  }
  const size_t triangles = s.mesh.triangleCount();
  const bake::EmbreeScene scene(std::move(s.mesh), s.name);
  spdlog::info("{}: capturing {} probes ({} triangles, {} spp)", s.name, s.positions.size(), triangles,
               co.samplesPerTexel);
  const bake::CaptureResult r = bake::captureProbes(scene, sky, s.positions, co, /*showProgress=*/true);
  if (r.interrupted) fail("interrupted");
  Captured c;
  c.n = co.resolution;
  c.m = co.irradianceResolution;
  c.positions = s.positions;
  for (const bake::ProbeCapture& p : r.probes) {
    c.radiance.insert(c.radiance.end(), p.radiance.begin(), p.radiance.end());
    c.irradiance.insert(c.irradiance.end(), p.irradiance.begin(), p.irradiance.end());
  }
  writeCache(file, c);
  spdlog::info("{}: captured in {:.1f} s -> {}", s.name, r.seconds, file.string());
  return c;
}

// --sun separate: the capture puts the sun disc's whole energy into the one texel holding its direction
// (bake/probe_capture.h) and adds its irradiance analytically. A runtime lights with the sun analytically
// (plus a shadow term), so the probes need not store it: this takes the deposit out of the radiance maps
// before any codec sees them and keeps one visibility bit per probe (counted in the bytes). Irradiance
// after decoding = the codec's irradiance + the disc's analytic irradiance where the bit is set, exactly
// the capture's formula. Visible = the texel holds at least half the deposit (the deposit is ~10^2-10^3
// times the sky's radiance).
std::vector<uint8_t> splitSun(Captured& c, const worlds::DiscLight& sun) {
  const size_t P = c.positions.size(), texels = size_t(c.n) * size_t(c.n);
  std::vector<uint8_t> visible(P, 0);
  const glm::vec3 energy = sun.irradianceNormal();
  if (!(energy.x + energy.y + energy.z > 0.0f)) return visible;
  const glm::ivec2 t = octDirectionTexel(sun.direction, c.n);
  const size_t texel = size_t(t.y) * size_t(c.n) + size_t(t.x);
  const glm::vec3 deposit = energy / float(octTexelSolidAngles(c.n)[texel]);
  for (size_t p = 0; p < P; ++p) {
    float* L = c.radiance.data() + (p * texels + texel) * 3;
    if (L[0] + L[1] + L[2] < 0.5f * (deposit.x + deposit.y + deposit.z)) continue;
    visible[p] = 1;
    for (int k = 0; k < 3; ++k) L[k] = std::max(0.0f, L[k] - deposit[k]);
  }
  return visible;
}

void addSunIrradiance(ProbeField& f, const std::vector<uint8_t>& visible, const worlds::DiscLight& sun) {
  const int m = f.irradianceResolution;
  const size_t tm = size_t(m) * size_t(m);
  for (size_t p = 0; p < visible.size(); ++p) {
    if (!visible[p]) continue;
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const glm::vec3 e = sun.irradiance(octTexelDirection(i, j, m));
        float* o = f.irradiance.data() + (p * tm + size_t(j) * size_t(m) + size_t(i)) * 3;
        for (int k = 0; k < 3; ++k) o[k] += e[k];
      }
  }
}

// ProbeField of the captured probes: a 1D grid (spacing 1 m at the origin) whose offsets put each probe at
// its real position, so a codec that uses positions sees them.
ProbeField fieldOf(const Captured& c) {
  ProbeField f;
  const int P = int(c.positions.size());
  f.grid.dims = glm::ivec3(P, 1, 1);
  f.resolution = c.n;
  f.irradianceResolution = c.m;
  f.radiance = c.radiance;
  f.offsets.resize(size_t(P));
  for (int i = 0; i < P; ++i) f.offsets[size_t(i)] = c.positions[size_t(i)] - glm::vec3(float(i), 0.0f, 0.0f);
  return f;
}

// --------------------------------------------------------------------------------------------- codecs

// The float radiance itself: the irradiance floor of any radiance-map codec (see the file comment).
class ReferenceFp32 final : public ProbeCodec {
 public:
  std::string name() const override { return "reference_fp32"; }
  std::string setting() const override { return ""; }
  std::vector<std::byte> encode(const ProbeField& f) const override {
    std::vector<std::byte> b(f.radiance.size() * 4);
    std::memcpy(b.data(), f.radiance.data(), b.size());
    return b;
  }
  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    out.radiance.resize(bytes.size() / 4);
    std::memcpy(out.radiance.data(), bytes.data(), out.radiance.size() * 4);
    out.irradiance.clear();
  }
};

// The bench probes of one scene as a one-key training set (bench captures keep radiance and irradiance
// only: distance, normal and albedo are placeholders that the bench's training options weight zero).
bake::GeneratorTrainingSet trainingSetOf(const ProbeField& f, float timeOfDay) {
  const size_t P = size_t(f.probeCount());
  const int n = f.resolution, m = f.irradianceResolution;
  const size_t T = size_t(n) * size_t(n);
  ProbeField withIrr = f;
  if (withIrr.irradiance.empty()) deriveIrradiance(withIrr);
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (size_t i = 0; i < P; ++i) {
    lo = glm::min(lo, f.probePosition(int64_t(i)));
    hi = glm::max(hi, f.probePosition(int64_t(i)));
  }
  bake::GeneratorTrainingSet set;
  bake::LightingKey key;
  key.timeOfDayHours = timeOfDay;
  for (size_t i = 0; i < P; ++i) {
    const glm::vec3 p = f.probePosition(int64_t(i)), ext = hi - lo;
    set.positions01.push_back(glm::vec3(ext.x > 0 ? (p.x - lo.x) / ext.x : 0.5f,
                                        ext.y > 0 ? (p.y - lo.y) / ext.y : 0.5f,
                                        ext.z > 0 ? (p.z - lo.z) / ext.z : 0.5f));
    bake::ProbeCapture c;
    c.position = p;
    c.resolution = n;
    c.irradianceResolution = m;
    c.radiance.assign(f.radiance.begin() + ptrdiff_t(i * T * 3),
                      f.radiance.begin() + ptrdiff_t((i + 1) * T * 3));
    c.radianceStdError.assign(T * 3, 0.0f);
    c.distance.assign(T * 2, 1.0f);
    c.normal.assign(T * 3, 0.0f);
    c.albedo.assign(T * 3, 0.0f);
    const size_t M = size_t(m) * size_t(m) * 3;
    c.irradiance.assign(withIrr.irradiance.begin() + ptrdiff_t(i * M),
                        withIrr.irradiance.begin() + ptrdiff_t((i + 1) * M));
    key.probes.push_back(std::move(c));
  }
  set.keys.push_back(std::move(key));
  return set;
}

// Training options of every bench model: radiance / irradiance losses only (see trainingSetOf), 1 thread.
bake::GeneratorTrainingOptions benchTrainingOptions(int maxSteps) {
  bake::GeneratorTrainingOptions o;
  o.maxSteps = maxSteps;
  o.threads = 1;
  o.loss.distance = o.loss.normal = o.loss.albedo = 0.0f;
  return o;
}

// The generative codec: the cell's probes are a one-key training set; bake::chooseCellModel picks
// SH L1 ("no network") when it meets the target, else the cheapest of a few generators; weights and latents
// are int8 and the bytes are the whole OpenVDB cell file (core/cell_file.h), ~11 KB of it fixed OpenVDB
// overhead per cell. The bench captures keep radiance and irradiance only, so the distance / normal /
// albedo channels are trained with zero weight (the baselines also store radiance only).
class GanCodec final : public ProbeCodec {
 public:
  GanCodec(double target, int maxSteps, float timeOfDay)
      : target_(target), maxSteps_(maxSteps), timeOfDay_(timeOfDay) {}
  std::string name() const override { return "gan"; }
  std::string setting() const override { return fmt::format("target {}", target_); }

  std::vector<std::byte> encode(const ProbeField& f) const override {
    const int n = f.resolution;
    const size_t P = size_t(f.probeCount());
    bake::GeneratorTrainingSet set = trainingSetOf(f, timeOfDay_);
    bake::ModelSizingOptions so;
    so.irradianceErrorTarget = target_;
    so.noNetworkKinds = {bake::CellModelKind::kShL1};
    for (int c0 : {16, 32}) {
      GeneratorArch a;
      a.latentDim = 8;
      a.convChannels = {c0, c0 / 2, kGeneratorChannels};
      so.candidates.push_back(a);
    }
    so.training = benchTrainingOptions(maxSteps_);
    bake::CellModelChoice choice = bake::chooseCellModel(set, {}, so);
    CellFile cf;
    cf.grid = f.grid;
    cf.stats.model = choice.describe();
    cf.stats.errorAchieved = choice.error.irradianceRelativeRms;
    cf.stats.errorTarget = target_;
    cf.stats.trainingSeconds = choice.trainingSeconds;
    if (choice.kind == bake::CellModelKind::kGenerator && choice.generator) {
      CellGenerator g;
      g.weights = quantizeWeights(choice.generator->weights, WeightPrecision::Int8);
      g.latents = quantizeLatents(choice.generator->latents, choice.generator->weights.arch.latentDim, 8);
      cf.outputScale = choice.generator->scale;
      cf.generator = std::move(g);
    }
    // SH L1 of the cell: the no-network model's own, else the mean projection (the cell's fallback).
    std::array<float, 12> sh{};
    if (choice.kind == bake::CellModelKind::kShL1 && choice.lighting.size() >= 12) {
      std::copy_n(choice.lighting.begin(), 12, sh.begin());
    } else {
      for (const bake::ProbeCapture& c : set.keys[0].probes) {
        ShL1 p = shProject<4>(c.radiance, n);
        for (int k = 0; k < 12; ++k) sh[size_t(k)] += p.c[size_t(k / 3)][k % 3] / float(P);
      }
    }
    for (float v : sh) cf.fallback.shHalf.push_back(floatToHalfClamped(v));
    return encodeCellFile(cf);
  }

  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    const CellFile cf = decodeCellFile(bytes, "gan cell");
    const int n = out.resolution;
    const size_t P = size_t(out.probeCount()), T = size_t(n) * size_t(n);
    out.irradiance.clear();
    if (cf.generator) {
      GeneratorCpu decoder(dequantizeWeights(cf.generator->weights));
      const std::vector<float> latents = dequantizeLatents(cf.generator->latents);
      const auto c = conditioningVector(timeOfDay_, 0.0f);
      std::span<const float> cond;
      if (decoder.arch().condDim == kConditioningDim) cond = std::span<const float>(c.data(), c.size());
      ProbeField tmp = out;
      decodeProbeField(decoder, latents, cond, cf.outputScale, tmp);
      out.radiance = std::move(tmp.radiance);
      return;
    }
    ShL1 sh;
    for (int k = 0; k < 12; ++k) sh.c[size_t(k / 3)][k % 3] = halfToFloat(cf.fallback.shHalf[size_t(k)]);
    out.radiance.assign(P * T * 3, 0.0f);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const glm::vec3 L = glm::max(shEvaluate<4>(sh, octTexelDirection(i, j, n)), glm::vec3(0.0f));
        for (size_t p = 0; p < P; ++p)
          for (int k = 0; k < 3; ++k) out.radiance[(p * T + size_t(j * n + i)) * 3 + size_t(k)] = L[k];
      }
  }

 private:
  double target_;
  int maxSteps_;
  float timeOfDay_;
};

// ------------------------------------------------------------------------- world-shared generator
// One generator pre-trained on cells of the default world that the bench does not measure (one of each
// kind; bake/generator_training.h pretrainSharedGenerator), stored once per world as int8 weights. Every
// measured scene is held out: its encode fits only latents + a FiLM adapter against the frozen, already
// dequantized int8 shared weights (what every decoder runs), bake::fitCellToSharedGenerator.
struct SharedModel {
  GeneratorWeights weights;      // dequantized int8: the decoders' shared model
  uint64_t hash = 0;             // weightsContentHash(weights): what a cell refers to
  size_t bytes = 0;              // stored once per world: int8 weights + scales + float biases + arch
  double pretrainSeconds = 0.0;  // 0 when loaded from the cache
  double pretrainIrrRelRms = 0.0;
  int steps = 0;
  std::vector<std::string> cells;  // pre-training scenes
};

constexpr int kSharedAdapterStages = 1;  // FiLM on the linear layer's C0 channels only (see bake/OVERVIEW.md)

bake::SharedTrainingOptions sharedOptions(const GeneratorArch& arch, int steps, int latentQatBits) {
  bake::SharedTrainingOptions o;
  o.training = benchTrainingOptions(steps);
  o.training.arch = arch;
  o.training.batchSize = 512;
  o.training.evalEvery = std::max(1, steps / 4);
  o.training.irradianceErrorTarget = 0.0;  // a fixed budget: every cell pays the same fit
  o.training.latentQuantBits = latentQatBits;
  o.adapterStages = kSharedAdapterStages;
  o.adapterQuantBits = latentQatBits > 0 ? 8 : 0;
  return o;
}

// Per-cell byte string of the shared codec (bench-only layout; the OpenVDB cell-file variant is not
// written yet, bench/OVERVIEW.md): "LFSA", u8 version, u64 shared model hash, u32 probes, u8 latent dim,
// u8 latent bits, f32 exposure, f32 range, latent scales (dim f32), packed latent codes, u8 adapter stages,
// u32 adapter channels, 2 f32 adapter scales, int8 adapter codes.
void putCodes(ByteWriter& w, const std::vector<int8_t>& codes, int bits) {
  if (bits == 8) {
    for (int8_t c : codes) w.i8(c);
    return;
  }
  for (size_t i = 0; i < codes.size(); i += 2) {  // 4-bit two's complement, low nibble first
    const uint8_t lo = uint8_t(codes[i]) & 0xf,
                  hi = i + 1 < codes.size() ? uint8_t(uint8_t(codes[i + 1]) & 0xf) : 0;
    w.u8(uint8_t(lo | (hi << 4)));
  }
}
std::vector<int8_t> getCodes(ByteReader& r, size_t n, int bits) {
  std::vector<int8_t> codes(n);
  if (bits == 8) {
    for (int8_t& c : codes) c = r.i8("codes");
    return codes;
  }
  for (size_t i = 0; i < n; i += 2) {
    const uint8_t b = r.u8("codes");
    auto nib = [](int v) { return int8_t(v >= 8 ? v - 16 : v); };
    codes[i] = nib(b & 0xf);
    if (i + 1 < n) codes[i + 1] = nib(b >> 4);
  }
  return codes;
}

// Fits by (scene content hash, bits quantized in the loop): the QAT-off fit serves the int8 and the 4-bit
// rows, and bestSeconds' repeated encodes reuse the fit (its time is the fit's own, lastFitSeconds).
using SharedFitCache = std::map<std::pair<uint64_t, int>, bake::CellAdaptation>;

class SharedAdapterCodec final : public ProbeCodec {
 public:
  // latentBits: stored latent width; qat: train with that quantizer in the loop.
  SharedAdapterCodec(const SharedModel& model, int latentBits, bool qat, int steps, float timeOfDay,
                     std::shared_ptr<SharedFitCache> cache)
      : model_(model),
        bits_(latentBits),
        qat_(qat),
        steps_(steps),
        timeOfDay_(timeOfDay),
        cache_(std::move(cache)) {}
  std::string name() const override { return "shared_adapter"; }
  std::string setting() const override {
    return fmt::format("z{} int{} qat {}", model_.weights.arch.latentDim, bits_, qat_ ? "on" : "off");
  }
  double lastFitSeconds() const { return lastFitSeconds_; }

  std::vector<std::byte> encode(const ProbeField& f) const override {
    const bake::GeneratorTrainingSet set = trainingSetOf(f, timeOfDay_);
    const int qatBits = qat_ ? bits_ : 0;
    const std::pair<uint64_t, int> key{set.contentHash(), qatBits};
    auto it = cache_->find(key);
    if (it == cache_->end())
      it = cache_
               ->emplace(key, bake::fitCellToSharedGenerator(
                                  model_.weights, set, sharedOptions(model_.weights.arch, steps_, qatBits)))
               .first;
    const bake::CellAdaptation& a = it->second;
    lastFitSeconds_ = a.report.seconds;
    const QuantizedLatents q = quantizeLatents(a.latents, model_.weights.arch.latentDim, bits_);
    const QuantizedAdapter qa = quantizeAdapter(a.adapter, 8);
    ByteWriter w;
    w.raw("LFSA", 4);
    w.u8(1);
    w.u64(model_.hash);
    w.u32(uint32_t(q.count));
    w.u8(uint8_t(q.dim));
    w.u8(uint8_t(q.bits));
    w.f32(a.scale.exposure);
    w.f32(a.scale.range);
    for (float v : q.scales) w.f32(v);
    putCodes(w, q.codes, q.bits);
    w.u8(uint8_t(qa.stages));
    w.u32(uint32_t(qa.channels));
    for (float v : qa.scales) w.f32(v);
    putCodes(w, qa.codes, qa.bits);
    return w.bytes;
  }

  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "shared_adapter"};
    if (std::memcmp(r.take(4, "magic"), "LFSA", 4) != 0 || r.u8("version") != 1)
      fail("shared_adapter cell: bad magic or version");
    const uint64_t hash = r.u64("model hash");
    if (hash != model_.hash)
      fail("shared_adapter cell: refers to shared model {:016x}, this world's is {:016x}", hash, model_.hash);
    QuantizedLatents q;
    q.count = r.u32("latent count");
    q.dim = r.u8("latent dim");
    q.bits = r.u8("latent bits");
    if (q.count != out.probeCount() || q.dim != model_.weights.arch.latentDim || (q.bits != 8 && q.bits != 4))
      fail("shared_adapter cell: {} latents of {} x {} bits for {} probes of a z{} model", q.count, q.dim,
           q.bits, out.probeCount(), model_.weights.arch.latentDim);
    GeneratorOutputScale scale;
    scale.exposure = r.f32("exposure");
    scale.range = r.f32("range");
    for (int i = 0; i < q.dim; ++i) q.scales.push_back(r.f32("latent scale"));
    q.codes = getCodes(r, size_t(q.count) * size_t(q.dim), q.bits);
    QuantizedAdapter qa;
    qa.stages = r.u8("adapter stages");
    qa.channels = r.u32("adapter channels");
    if (qa.channels != int64_t(adapterChannels(model_.weights.arch, qa.stages)))
      fail("shared_adapter cell: adapter of {} channels for {} stages", qa.channels, qa.stages);
    if (qa.channels > 0) {
      qa.scales = {r.f32("adapter scale"), r.f32("adapter scale")};
      qa.codes = getCodes(r, size_t(2 * qa.channels), 8);
    }
    r.expectEnd();
    q.validate("shared_adapter cell latents");
    GeneratorCpu decoder(applyAdapter(model_.weights, dequantizeAdapter(qa)));
    const std::vector<float> latents = dequantizeLatents(q);
    const auto c = conditioningVector(timeOfDay_, 0.0f);
    ProbeField tmp = out;
    decodeProbeField(decoder, latents, std::span<const float>(c.data(), size_t(decoder.arch().condDim)),
                     scale, tmp);
    out.radiance = std::move(tmp.radiance);
    out.irradiance.clear();
  }

 private:
  const SharedModel& model_;
  int bits_;
  bool qat_;
  int steps_;
  float timeOfDay_;
  std::shared_ptr<SharedFitCache> cache_;
  mutable double lastFitSeconds_ = 0.0;
};

std::vector<std::unique_ptr<ProbeCodec>> makeBenchCodecs(bool quick, bool skipGan, float timeOfDay,
                                                         const SharedModel* shared, int fitSteps) {
  std::vector<std::unique_ptr<ProbeCodec>> c;
  c.push_back(std::make_unique<ReferenceFp32>());
  c.push_back(makeRawFp16Codec());
  c.push_back(makeZstdFp16Codec(19));
  for (int l : {1, 2, 4, 7}) c.push_back(makeShCodec(l));
  c.push_back(makeShL1Q8Codec());
  // PCA targets are on radiance relative RMS; with --sun in-map the sun texel dominates it, so the loose
  // targets collapse to one component there.
  for (double t : quick ? std::vector<double>{0.2, 0.1, 0.05, 0.02, 0.01}
                        : std::vector<double>{0.3, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005})
    c.push_back(makePcaCodec(t));
  for (int b : {4, 6, 8}) c.push_back(makeAstcHdrCodec(b, 60.0f));  // ASTCENC_PRE_MEDIUM
  // The generative codec, at the irradiance targets the cell bake uses.
  if (!skipGan)
    for (double t : quick ? std::vector<double>{0.05} : std::vector<double>{0.05, 0.02})
      c.push_back(std::make_unique<GanCodec>(t, quick ? 300 : 800, timeOfDay));
  if (shared) {
    auto cache = std::make_shared<SharedFitCache>();
    for (int bits : {8, 4})
      for (bool qat : {true, false})
        c.push_back(std::make_unique<SharedAdapterCodec>(*shared, bits, qat, fitSteps, timeOfDay, cache));
  }
  return c;
}

// The shared model, pre-trained (or read back from the cache: same captures, options and arch give the
// same key) on `sets`, then stored as int8 per channel and dequantized: the model every fit and decode uses.
SharedModel makeSharedModel(const std::vector<bake::GeneratorTrainingSet>& sets,
                            const std::vector<std::string>& names, const GeneratorArch& arch, int steps,
                            const fs::path& cacheDir) {
  const bake::SharedTrainingOptions o = sharedOptions(arch, steps, 0);
  uint64_t key = kFnv1aOffset;
  for (const auto& set : sets) {
    const uint64_t h = set.contentHash();
    key = fnv1a(key, &h, sizeof h);
  }
  const int ints[5] = {arch.latentDim, int(arch.convChannels.size()), arch.convChannels[0], steps,
                       o.adapterStages};
  key = fnv1a(key, ints, sizeof ints);
  const fs::path file = cacheDir / fmt::format("shared_generator_{:016x}.bin", key);
  SharedModel m;
  m.cells = names;
  m.weights.arch = arch;
  // layout: the dequantized arrays in GeneratorWeights order, then f64 pretrain irr rel RMS, i32 steps.
  std::vector<std::vector<float>*> arrays;
  GeneratorWeights shape = randomGeneratorWeights(arch, 1);
  m.weights = shape;
  arrays.push_back(&m.weights.linearWeight);
  arrays.push_back(&m.weights.linearBias);
  for (int i = 0; i < arch.layers(); ++i) {
    arrays.push_back(&m.weights.convWeight[size_t(i)]);
    arrays.push_back(&m.weights.convBias[size_t(i)]);
  }
  size_t floats = 0;
  for (auto* a : arrays) floats += a->size();
  bool loaded = false;
  if (fs::exists(file)) {
    const std::vector<std::byte> b = readFileBytes(file);
    if (b.size() == floats * 4 + 12) {
      size_t off = 0;
      for (auto* a : arrays) {
        std::memcpy(a->data(), b.data() + off, a->size() * 4);
        off += a->size() * 4;
      }
      std::memcpy(&m.pretrainIrrRelRms, b.data() + off, 8);
      std::memcpy(&m.steps, b.data() + off + 8, 4);
      loaded = true;
      spdlog::info("shared generator from the cache {}", file.string());
    } else {
      spdlog::warn("{}: stale shared generator cache, training again", file.string());
    }
  }
  if (!loaded) {
    bake::SharedTrainingOptions po = o;
    po.training.showProgress = true;
    const bake::SharedGenerator g = bake::pretrainSharedGenerator(sets, po);
    m.weights = dequantizeWeights(quantizeWeights(g.weights, WeightPrecision::Int8));
    m.pretrainSeconds = g.report.seconds;
    m.pretrainIrrRelRms = g.report.irradianceRelativeRms;
    m.steps = g.report.steps;
    std::vector<std::byte> b;
    auto put = [&](const void* p, size_t n) {
      const auto* c = static_cast<const std::byte*>(p);
      b.insert(b.end(), c, c + n);
    };
    for (auto* a : {&m.weights.linearWeight, &m.weights.linearBias}) put(a->data(), a->size() * 4);
    for (int i = 0; i < arch.layers(); ++i) {
      put(m.weights.convWeight[size_t(i)].data(), m.weights.convWeight[size_t(i)].size() * 4);
      put(m.weights.convBias[size_t(i)].data(), m.weights.convBias[size_t(i)].size() * 4);
    }
    put(&m.pretrainIrrRelRms, 8);
    put(&m.steps, 4);
    fs::create_directories(file.parent_path());
    writeFileAtomic(file, b);
    spdlog::info("shared generator: {} steps on {} cells in {:.1f} s, mean irradiance rel RMS {:.4f} -> {}",
                 m.steps, sets.size(), m.pretrainSeconds, m.pretrainIrrRelRms, file.string());
  }
  m.weights.validate();
  m.hash = weightsContentHash(m.weights);
  // Stored once per world: the int8 tensors (codes + per-channel scales + float biases) and the architecture
  // (latent dim, cond dim, k + 1 channel counts as u16, a u64 hash).
  m.bytes = quantizeWeights(m.weights, WeightPrecision::Int8).bytes() + 2 + 2 * arch.convChannels.size() + 8;
  return m;
}

std::string familyOf(const std::string& name) {
  if (name == "sh_l1_q8") return name;  // its own point, off the FP16 SH curve
  return name.rfind("sh_l", 0) == 0 ? "sh" : name;
}

// ---------------------------------------------------------------------------------------------- timing

template <typename F>
double bestSeconds(F&& f, double minTotal) {
  double best = 1e30, total = 0.0;
  for (int rep = 0; rep < 50 && (rep < 2 || total < minTotal); ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    best = std::min(best, s);
    total += s;
  }
  return best;
}

struct Result {
  std::string scene, kind, codec, family, setting;
  size_t probes = 0;
  double bytes = 0, irr = 0, irrCodec = 0, rad = 0, psnr = 0, encUs = 0, decUs = 0;
  // All-in bytes per probe with a world-shared model's bytes spread over the probes of the default 256 m
  // world / of a 16 km^2 world of the same probe density (= bytes for codecs without a shared model).
  double bytesWorld = 0, bytes16km2 = 0;
  double encodeSPerScene = 0;  // pooled rows: the mean over their scenes
  bool direct = false;
};

std::string cpuName() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const size_t c = line.find(':');
      if (c != std::string::npos) return line.substr(c + 2);
    }
  return "cpu";
}

struct Args {
  std::string out = "out/bench/codec", cacheDir = "out/cache/codec",
              scenesDir = worlds::defaultScenesDir().string();
  bool quick = false, noGan = false, noShared = false;
  int spp = 0, threads = 0, sharedSteps = 0, fitSteps = 0;
  std::string sunMode = "separate";
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("--out", a.out, "Output directory");
  app.add_option("--cache", a.cacheDir, "Capture cache directory")->capture_default_str();
  app.add_option("--scenes-dir", a.scenesDir, "Folder of the scene presets")->capture_default_str();
  app.add_option("--spp", a.spp, "Capture samples per texel (default 16 quick, 64 full)");
  app.add_option("--threads", a.threads, "Capture threads (0 = all)");
  app.add_flag("--quick", a.quick, "Fewer probes, fewer codec settings, lower capture samples");
  app.add_flag("--no-gan", a.noGan, "Skip the generative codec (it trains a model per scene: minutes)");
  app.add_flag("--no-shared", a.noShared, "Skip the world-shared generator + per-cell adapter rows");
  app.add_option("--shared-steps", a.sharedSteps,
                 "Pre-training steps of the shared generator (default 1000 quick, 3000 full)");
  app.add_option("--fit-steps", a.fitSteps,
                 "Steps of each held-out cell's latent + adapter fit (default 400 quick, 800 full)");
  app.add_option("--sun", a.sunMode,
                 "separate: probes store radiance without the sun disc plus a visibility bit; "
                 "in-map: the sun stays in its radiance texel")
      ->check(CLI::IsMember({"separate", "in-map"}))
      ->capture_default_str();
}

// Steps of each held-out cell's latent + adapter fit.
int sharedFitSteps(const Args& a) {
  return a.fitSteps > 0 ? a.fitSteps : (a.quick ? 400 : 800);
}

constexpr float kTimeOfDay = 15.5f;

// What every scene shares: the capture settings, the sky and the default world the cells come from.
struct Setup {
  bake::CaptureOptions co;
  worlds::SkyModel sky;
  size_t cellProbes = 0;
  worlds::SyntheticWorld world{worlds::WorldParams::smallDefault(1)};
};

Setup makeSetup(const Args& a) {
  Setup s;
  s.co.resolution = 16;
  s.co.irradianceResolution = 8;
  s.co.samplesPerTexel = a.spp > 0 ? a.spp : (a.quick ? 16 : 64);
  s.co.maxBounces = a.quick ? 4 : 8;
  worlds::SkyState st;
  st.timeOfDayHours = kTimeOfDay;
  s.sky = worlds::makeSky(st);
  s.cellProbes = a.quick ? 48 : 160;
  return s;
}

// Scenes: the two test scenes and 9 cells of the default world's showcase district (synthetic_world.h):
// fields, suburbs, a park and the four city block types (leak test, arcade, courtyard, towers).
std::vector<std::function<SceneSpec()>> sceneSpecs(const Args& a, const Setup& setup) {
  const std::vector<worlds::CellCoord> cells = {{0, 0}, {1, 0}, {3, 1}, {1, 1}, {2, 1},
                                                {1, 2}, {2, 2}, {3, 2}, {0, 3}};
  std::vector<std::function<SceneSpec()>> specs;
  const std::string scenesDir = a.scenesDir;
  const bool quick = a.quick;
  specs.push_back([=] { return presetScene("cornell", scenesDir, quick ? glm::ivec3(3) : glm::ivec3(5)); });
  specs.push_back(
      [=] { return presetScene("sponza", scenesDir, quick ? glm::ivec3(6, 3, 4) : glm::ivec3(12, 5, 8)); });
  const worlds::SyntheticWorld& world = setup.world;
  const size_t cellProbes = setup.cellProbes;
  for (const worlds::CellCoord c : cells)
    specs.push_back([&world, c, cellProbes] { return worldCell(world, c, cellProbes); });
  return specs;
}

struct SharedSetup {
  std::optional<SharedModel> model;
  size_t worldProbes = 0;  // active probes of the default world
};

// World-shared generator: pre-trained on the first cell of each kind (field, suburb, city, park) of
// another world (seed 2), so every measured scene is held out; stored once per world.
SharedSetup makeShared(const Args& a, const Setup& setup) {
  SharedSetup out;
  if (a.noShared) return out;
  const worlds::SyntheticWorld pretrainWorld(worlds::WorldParams::smallDefault(2));
  std::vector<bake::GeneratorTrainingSet> sets;
  std::vector<std::string> names, kindsUsed;
  for (int z = 0; z < pretrainWorld.cellsX() && sets.size() < 4; ++z)
    for (int x = 0; x < pretrainWorld.cellsX() && sets.size() < 4; ++x) {
      const worlds::CellCoord c{x, z};
      const std::string kind(worlds::cellKindName(pretrainWorld.cellKind(c)));
      if (std::find(kindsUsed.begin(), kindsUsed.end(), kind) != kindsUsed.end()) continue;
      SceneSpec spec = worldCell(pretrainWorld, c, setup.cellProbes);
      spec.name = "seed2_" + spec.name;
      names.push_back(spec.name);
      Captured cap = capture(spec, setup.co, setup.sky, kTimeOfDay, a.cacheDir);
      if (a.sunMode == "separate") splitSun(cap, setup.sky.sun);
      sets.push_back(trainingSetOf(fieldOf(cap), kTimeOfDay));
      kindsUsed.push_back(kind);
    }
  GeneratorArch arch;
  arch.latentDim = 8;
  arch.convChannels = {32, 16, kGeneratorChannels};
  out.model = makeSharedModel(sets, names, arch, a.sharedSteps > 0 ? a.sharedSteps : (a.quick ? 1000 : 3000),
                              a.cacheDir);
  const worlds::SyntheticWorld& world = setup.world;
  for (int z = 0; z < world.cellsX(); ++z)
    for (int x = 0; x < world.cellsX(); ++x)
      out.worldProbes += worlds::buildCell(world, {x, z}).stats.probesActive;
  spdlog::info("shared generator: {} B (int8) on {}; default world {} active probes", out.model->bytes,
               fmt::join(names, ", "), out.worldProbes);
  return out;
}

// One scene's captured field, its sun split off (--sun separate) and the references a codec row compares
// against.
struct SceneField {
  std::string name, kind;
  Captured cap;
  std::vector<uint8_t> sunVisible;
  ProbeField field;
  ProbeField floatIrr;  // irradiance of the uncompressed float radiance: the reference of the codec's loss
  float peak = 0;
};

SceneField captureScene(SceneSpec spec, const Args& a, const Setup& setup) {
  SceneField s;
  s.name = spec.name;
  s.kind = spec.kind;
  s.cap = capture(spec, setup.co, setup.sky, kTimeOfDay, a.cacheDir);
  if (a.sunMode == "separate") s.sunVisible = splitSun(s.cap, setup.sky.sun);
  s.field = fieldOf(s.cap);
  s.floatIrr = s.field;
  deriveIrradiance(s.floatIrr);
  addSunIrradiance(s.floatIrr, s.sunVisible, setup.sky.sun);
  if (!s.sunVisible.empty())
    spdlog::info("{}: sun separate, visible from {} of {} probes", s.name,
                 std::count(s.sunVisible.begin(), s.sunVisible.end(), uint8_t(1)), s.cap.positions.size());
  s.peak = *std::max_element(s.cap.radiance.begin(), s.cap.radiance.end());
  return s;
}

// One codec on one scene: encode, decode (best of repeats), errors and bytes per probe.
Result measureCodec(const ProbeCodec& codec, const SceneField& s, const Setup& setup,
                    const SharedSetup& shared, double worldKm2) {
  std::vector<std::byte> bytes;
  const double enc = bestSeconds([&] { bytes = codec.encode(s.field); }, 0.05);
  ProbeField dec = s.field;
  dec.radiance.clear();
  const double decS = bestSeconds([&] { codec.decode(bytes, dec); }, 0.05);
  if (!codec.decodesIrradiance()) deriveIrradiance(dec);
  addSunIrradiance(dec, s.sunVisible, setup.sky.sun);
  const size_t P = s.cap.positions.size();
  const size_t sunBytes = s.sunVisible.empty() ? 0 : (P + 7) / 8;
  Result r;
  r.scene = s.name;
  r.kind = s.kind;
  r.codec = codec.name();
  r.family = familyOf(r.codec);
  r.setting = codec.setting();
  r.probes = P;
  r.bytes = double(bytes.size() + sunBytes) / double(P);
  r.irr = relativeRms(dec.irradiance, s.cap.irradiance);
  r.irrCodec = relativeRms(dec.irradiance, s.floatIrr.irradiance);
  r.rad = relativeRms(dec.radiance, s.cap.radiance);
  r.psnr = psnr(dec.radiance, s.cap.radiance, double(s.peak));
  r.encUs = enc * 1e6 / double(P);
  if (const auto* sa = dynamic_cast<const SharedAdapterCodec*>(&codec))
    r.encUs = sa->lastFitSeconds() * 1e6 / double(P);
  r.decUs = decS * 1e6 / double(P);
  r.direct = codec.decodesIrradiance();
  r.encodeSPerScene = r.encUs * double(P) * 1e-6;
  r.bytesWorld = r.bytes16km2 = r.bytes;
  if (shared.model && r.codec == "shared_adapter") {
    r.bytesWorld += double(shared.model->bytes) / double(shared.worldProbes);
    r.bytes16km2 += double(shared.model->bytes) / (double(shared.worldProbes) * 16.0 / worldKm2);
  }
  spdlog::info(
      "{:<22} {:<15} {:<16} {:>9.1f} B/probe  irr {:7.4f} (codec {:7.4f})  rad {:7.4f}  {:6.1f} dB  "
      "enc {:9.1f} us  dec {:7.2f} us",
      s.name, r.codec, r.setting, r.bytes, r.irr, r.irrCodec, r.rad, r.psnr, r.encUs, r.decUs);
  return r;
}

// Pooled rows per codec setting: scene "all" over every scene, scene "kind" per scene kind, "cells" over
// the default world's cells.
std::vector<Result> pool(const std::vector<Result>& results, const std::string& scene,
                         const std::string& kind) {
  std::map<std::pair<std::string, std::string>, std::vector<const Result*>> byCodec;
  for (const Result& r : results)
    if (kind == "all" || r.kind == kind || (kind == "cells" && r.scene.rfind("cell_", 0) == 0))
      byCodec[{r.codec, r.setting}].push_back(&r);
  std::vector<Result> pooled;
  for (const auto& [key, rs] : byCodec) {
    Result a = *rs[0];
    a.scene = scene;
    a.kind = kind;
    double bytes = 0, enc = 0, dec = 0, bytesWorld = 0, bytes16 = 0;
    size_t probes = 0;
    a.irr = a.irrCodec = a.rad = a.psnr = a.encodeSPerScene = 0;
    for (const Result* r : rs) {
      bytes += r->bytes * double(r->probes);
      bytesWorld += r->bytesWorld * double(r->probes);
      bytes16 += r->bytes16km2 * double(r->probes);
      a.encodeSPerScene += r->encodeSPerScene / double(rs.size());
      enc += r->encUs * double(r->probes);
      dec += r->decUs * double(r->probes);
      probes += r->probes;
      a.irr += r->irr / double(rs.size());
      a.irrCodec += r->irrCodec / double(rs.size());
      a.rad += r->rad / double(rs.size());
      a.psnr += r->psnr / double(rs.size());
    }
    a.probes = probes;
    a.bytes = bytes / double(probes);
    a.bytesWorld = bytesWorld / double(probes);
    a.bytes16km2 = bytes16 / double(probes);
    a.encUs = enc / double(probes);
    a.decUs = dec / double(probes);
    pooled.push_back(a);
  }
  std::sort(pooled.begin(), pooled.end(), [](const Result& a, const Result& b) { return a.bytes < b.bytes; });
  return pooled;
}

// The CSV: every scene's rows, then the pooled ones per kind, over all scenes and over the cells.
void writeRows(bench::BenchOutput& o, const std::vector<Result>& results, const std::vector<Result>& all,
               const std::vector<Result>& cellRows) {
  std::vector<std::string> kinds;
  for (const Result& r : results)
    if (std::find(kinds.begin(), kinds.end(), r.kind) == kinds.end()) kinds.push_back(r.kind);
  o.setColumns({"scene", "kind", "codec", "family", "setting", "probes", "bytes_per_probe", "irr_rel_rms",
                "rad_rel_rms", "rad_psnr_db", "encode_us_per_probe", "decode_us_per_probe", "irr_direct",
                "irr_codec_rel_rms", "bytes_per_probe_shared_256m", "bytes_per_probe_shared_16km2",
                "encode_s_per_scene"});
  auto add = [&](const Result& r) {
    o.addRow({r.scene, r.kind, r.codec, r.family, r.setting, std::to_string(r.probes), bench::num(r.bytes),
              bench::num(r.irr), bench::num(r.rad), bench::num(r.psnr), bench::num(r.encUs),
              bench::num(r.decUs), r.direct ? "1" : "0", bench::num(r.irrCodec), bench::num(r.bytesWorld),
              bench::num(r.bytes16km2), bench::num(r.encodeSPerScene)});
  };
  for (const Result& r : results) add(r);
  for (const std::string& k : kinds)
    for (const Result& r : pool(results, "kind", k)) add(r);
  for (const Result& r : all) add(r);
  // The synthetic cells of the default world only (every one held out from the shared generator's
  // pre-training): scene "cells", kind "cells".
  for (const Result& r : cellRows) add(r);
}

// The SH rows of `rows`, fewest bytes first.
std::vector<const Result*> shCurve(const std::vector<Result>& rows) {
  std::vector<const Result*> sh;
  for (const Result& r : rows)
    if (r.family == "sh") sh.push_back(&r);
  std::sort(sh.begin(), sh.end(), [](const Result* a, const Result* b) { return a->bytes < b->bytes; });
  return sh;
}

// SH bytes at a given irradiance error: log-log interpolation between the two SH orders (L1, L2, L4, L7
// rows) whose errors bracket it; nullopt outside [error of the most accurate order, error of SH L1] (no
// extrapolation).
std::optional<double> shBytesAt(const std::vector<const Result*>& shRows, double err) {
  for (size_t i = 0; i + 1 < shRows.size(); ++i) {
    const Result &a = *shRows[i], &b = *shRows[i + 1];
    if (err <= a.irr && err >= b.irr && a.irr > b.irr) {
      const double t = (std::log(err) - std::log(a.irr)) / (std::log(b.irr) - std::log(a.irr));
      return std::exp(std::log(a.bytes) + t * (std::log(b.bytes) - std::log(a.bytes)));
    }
  }
  return std::nullopt;
}

nlohmann::ordered_json shCurveRatio(const std::vector<const Result*>& shRows, const Result& r, double bytes) {
  const std::optional<double> b = shBytesAt(shRows, r.irr);
  return b ? nlohmann::ordered_json(*b / bytes) : nlohmann::ordered_json();
}

// One shared_adapter row of the summary's shared_generator block, against the SH curve and SH L2 of the
// same pooled rows.
nlohmann::ordered_json sharedRow(const Result& r, const Result& sh2, const std::vector<const Result*>& shRows,
                                 bool withCodecError) {
  nlohmann::ordered_json j = {{"bytes_per_probe_cell_only", r.bytes},
                              {"bytes_per_probe_shared_256m", r.bytesWorld},
                              {"bytes_per_probe_shared_16km2", r.bytes16km2},
                              {"irr_rel_rms", r.irr}};
  if (withCodecError) j["irr_codec_rel_rms"] = r.irrCodec;
  j["fit_s_per_scene"] = r.encodeSPerScene;
  j["bytes_ratio_vs_sh_l2_at_equal_error_256m"] =
      r.irr <= sh2.irr ? nlohmann::ordered_json(sh2.bytes / r.bytesWorld) : nlohmann::ordered_json();
  j["bytes_ratio_vs_sh_curve_at_codec_error_256m"] = shCurveRatio(shRows, r, r.bytesWorld);
  j["bytes_ratio_vs_sh_curve_at_codec_error_16km2"] = shCurveRatio(shRows, r, r.bytes16km2);
  j["bytes_ratio_vs_sh_curve_at_codec_error_cell_only"] = shCurveRatio(shRows, r, r.bytes);
  return j;
}

nlohmann::ordered_json ganRow(const Result& r) {
  return {{"bytes_per_probe", r.bytes}, {"irr_rel_rms", r.irr}, {"encode_s_per_scene", r.encodeSPerScene}};
}

// The summary's shared_generator block: the model, then its rows over all scenes and over the cells.
nlohmann::ordered_json sharedSummary(const SharedSetup& shared, const Args& a, double worldKm2,
                                     const std::vector<Result>& all, const Result& sh2,
                                     const std::vector<Result>& cellRows) {
  const SharedModel& m = *shared.model;
  nlohmann::ordered_json j;
  j["model"] = "z8 C32-16, FiLM on the linear layer, int8 weights";
  j["model_bytes"] = m.bytes;
  j["pretrain_cells"] = m.cells;
  j["pretrain_steps"] = m.steps;
  j["pretrain_seconds"] = m.pretrainSeconds;  // 0: read from the cache
  j["pretrain_irr_rel_rms"] = m.pretrainIrrRelRms;
  j["fit_steps"] = sharedFitSteps(a);
  j["world_probes_256m"] = shared.worldProbes;
  j["world_probes_16km2"] = double(shared.worldProbes) * 16.0 / worldKm2;
  // The cells block: against the SH curve over the synthetic cells only (the "cells" rows).
  const std::vector<const Result*> cellSh = shCurve(cellRows);
  const Result* cellSh2 = nullptr;
  for (const Result& r : cellRows)
    if (r.codec == "sh_l2") cellSh2 = &r;
  for (const Result& r : cellRows) {
    if (r.family == "sh") j["cells"]["sh"][r.codec] = {{"bytes_per_probe", r.bytes}, {"irr_rel_rms", r.irr}};
    if (r.family == "gan") j["cells"]["per_cell_gan"][r.setting] = ganRow(r);
    if (r.family != "shared_adapter" || !cellSh2) continue;
    j["cells"]["rows"][r.setting] = sharedRow(r, *cellSh2, cellSh, false);
  }
  const std::vector<const Result*> allSh = shCurve(all);
  for (const Result& r : all) {
    if (r.family == "gan") j["per_cell_gan"][r.setting] = ganRow(r);
    if (r.family != "shared_adapter") continue;
    j["rows"][r.setting] = sharedRow(r, sh2, allSh, true);
  }
  return j;
}

// Headline (BENCHMARKS.md keys), from the "all" rows.
void writeSummary(bench::BenchOutput& o, const Args& a, const Setup& setup, size_t sceneCount,
                  const SharedSetup& shared, double worldKm2, const std::vector<Result>& all,
                  const std::vector<Result>& cellRows) {
  const Result* sh2 = nullptr;
  for (const Result& r : all)
    if (r.codec == "sh_l2") sh2 = &r;
  if (!sh2) fail("no sh_l2 row");
  // Cheapest baseline row at least as accurate (irradiance) as SH L2.
  const Result* baseline = nullptr;
  for (const Result& r : all) {
    if (r.codec == "reference_fp32" || r.codec == "sh_l2" || r.family == "gan" ||
        r.family == "shared_adapter")
      continue;
    if (r.irr <= sh2->irr && (!baseline || r.bytes < baseline->bytes)) baseline = &r;
  }
  auto& s = o.summary();
  const nlohmann::ordered_json null;
  // Headline codec: the cheapest row of the generative families (per-cell gan, shared_adapter with the
  // shared weights spread over the default world) at SH L2's irradiance error or better, else the most
  // accurate of them (codec_reached_sh_l2_error false).
  const Result* gan = nullptr;
  bool haveGan = false;
  for (const Result& r : all) {
    if (r.family != "gan" && r.family != "shared_adapter") continue;
    haveGan = true;
    if (r.irr <= sh2->irr && (!gan || r.bytesWorld < gan->bytesWorld)) gan = &r;
  }
  const bool ganAtShL2 = gan != nullptr;
  if (!gan)
    for (const Result& r : all)
      if ((r.family == "gan" || r.family == "shared_adapter") && (!gan || r.irr < gan->irr)) gan = &r;
  s["codec_bytes_per_probe"] = gan ? nlohmann::ordered_json(gan->bytesWorld) : null;
  s["sh_l2_bytes_per_probe"] = sh2->bytes;
  // Equal error = at SH L2's error: SH L2 bytes / codec bytes, only for a codec at least as accurate.
  s["bytes_ratio_vs_sh_l2_at_equal_error"] =
      ganAtShL2 ? nlohmann::ordered_json(sh2->bytes / gan->bytesWorld) : null;
  s["codec_irr_rel_rms"] = gan ? nlohmann::ordered_json(gan->irr) : null;
  s["sh_l2_irr_rel_rms"] = sh2->irr;
  if (gan) {
    s["codec_family"] = gan->family;
    s["bytes_ratio_vs_sh_curve_at_codec_error"] = shCurveRatio(shCurve(all), *gan, gan->bytesWorld);
  }
  if (shared.model) s["shared_generator"] = sharedSummary(shared, a, worldKm2, all, *sh2, cellRows);
  s["gpu_decode_probes_per_s"] = null;  // GPU decode: the generator helper's gpu/ kernels
  s["gpu_decode_fraction_of_gemm_ceiling"] = null;
  s["cpu_decode_probes_per_s"] = gan ? nlohmann::ordered_json(1e6 / gan->decUs) : null;
  s["cpu_decode_fraction_of_sgemm"] = null;
  s["cells_without_network"] = null;
  s["gan_in_run"] = haveGan;
  s["gan_reached_sh_l2_error"] = ganAtShL2;
  s["codec_reached_sh_l2_error"] = ganAtShL2;
  if (gan) s["gan_setting"] = gan->setting;
  if (baseline) {
    s["best_baseline_at_sh_l2_error"] =
        baseline->codec + (baseline->setting.empty() ? "" : " " + baseline->setting);
    s["best_baseline_bytes_per_probe"] = baseline->bytes;
    s["best_baseline_irr_rel_rms"] = baseline->irr;
    s["best_baseline_bytes_ratio_vs_sh_l2"] = sh2->bytes / baseline->bytes;
  }
  for (const Result& r : all)
    if (r.codec == "reference_fp32") s["irr_rel_rms_floor_fp32_radiance"] = r.irr;
  s["scenes"] = sceneCount;
  s["probes"] = all.empty() ? 0 : all[0].probes;
  s["sun"] = a.sunMode;
  s["resolution"] = setup.co.resolution;
  s["samples_per_texel"] = setup.co.samplesPerTexel;
}

void run(const Args& a) {
  InterruptGuard guard;
  bench::BenchOutput o(a.out, a.quick);
  o.setDevice(fmt::format("{} (codecs on 1 thread)", cpuName()));
  std::optional<tbb::global_control> limit;
  if (a.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
  const Setup setup = makeSetup(a);
  const std::vector<std::function<SceneSpec()>> specs = sceneSpecs(a, setup);
  openblas_set_num_threads(1);
  const SharedSetup shared = makeShared(a, setup);
  const worlds::SyntheticWorld& world = setup.world;
  const double worldKm2 = std::pow(double(world.cellsX()) * world.cellSizeM() * 1e-3, 2.0);
  const auto codecs = makeBenchCodecs(a.quick, a.noGan, kTimeOfDay, shared.model ? &*shared.model : nullptr,
                                      sharedFitSteps(a));
  std::vector<Result> results;
  for (const auto& make : specs) {
    const SceneField scene = captureScene(make(), a, setup);
    for (const auto& codec : codecs) {
      if (InterruptGuard::interrupted()) fail("interrupted");
      results.push_back(measureCodec(*codec, scene, setup, shared, worldKm2));
    }
  }
  const std::vector<Result> all = pool(results, "all", "all");
  const std::vector<Result> cellRows = pool(results, "cells", "cells");
  writeRows(o, results, all, cellRows);
  writeSummary(o, a, setup, specs.size(), shared, worldKm2, all, cellRows);
  o.save();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"lfgi benchmark: probe codecs, rate-distortion-speed"};
  Args a;
  addOptions(app, a);
  CLI11_PARSE(app, argc, argv);
  try {
    run(a);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
