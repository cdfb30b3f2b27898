#include "streaming/cell_file_source.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/half.h"
#include "core/octahedral.h"
#include "core/quantize.h"
#include "core/sh.h"
#include "core/shared_model.h"
#include "streaming/generator_backend.h"
#include "streaming/http_region_source.h"
#include "worlds/world_cells.h"

namespace lfgi::streaming {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
uint64_t usSince(Clock::time_point t0) {
  return uint64_t(std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - t0).count());
}

int irradianceResolutionFor(int n, int option) {
  return option > 0 ? option : streamedIrradianceResolution(n);
}

size_t fieldBytesFor(int64_t probes, int n, int m) {
  const size_t P = size_t(probes), tn = size_t(n) * size_t(n), tm = size_t(m) * size_t(m);
  // + the active flags, + room for the probes' relocation offsets, which VIR visibility on load sets
  // (streaming/vir_relight_source.h: the probes sit where their moments were seen)
  return sizeof(float) * P * (tn * 3 + tn * 2 + tm * 3) + P + sizeof(glm::vec3) * P;
}

// The semantic checks of a cell file against the world it is streamed into (readCellFile has checked
// the file against itself).
void checkCellFits(const CellFile& c, glm::ivec2 cell, uint64_t worldSeed, const WorldLayout& layout,
                   const std::string& where) {
  if (c.cellX != cell.x || c.cellZ != cell.y)
    fail("{}: holds cell {},{}, expected {},{}", where, c.cellX, c.cellZ, cell.x, cell.y);
  if (c.worldSeed != worldSeed)
    fail("{}: baked for world seed {}, the world's seed is {}", where, c.worldSeed, worldSeed);
  const glm::vec2 lo = layout.cellMin(cell), hi = lo + layout.cellSize;
  const glm::vec3 a = c.grid.origin, b = c.grid.boxMax();
  const float eps = 1e-3f * layout.cellSize;
  if (a.x < lo.x - eps || a.z < lo.y - eps || b.x > hi.x + eps || b.z > hi.y + eps)
    fail("{}: probe box x [{}, {}] z [{}, {}] is not inside the cell's square x [{}, {}] z [{}, {}]", where,
         a.x, b.x, a.z, b.z, lo.x, hi.x, lo.y, hi.y);
}

// Kernel K[t][s] = max(0, n_t . w_s) * omega_s of bruteForceIrradiance, per (n, m), built once.
std::shared_ptr<const std::vector<float>> irradianceKernel(int n, int m) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, std::shared_ptr<const std::vector<float>>> cache;
  const std::lock_guard lock(mutex);
  auto it = cache.find({n, m});
  if (it != cache.end()) return it->second;
  const std::vector<double> omega = octTexelSolidAngles(n);
  auto k = std::make_shared<std::vector<float>>(size_t(m * m) * size_t(n * n));
  for (int tj = 0; tj < m; ++tj)
    for (int ti = 0; ti < m; ++ti) {
      const glm::vec3 nrm = octTexelDirection(ti, tj, m);
      float* row = k->data() + size_t(tj * m + ti) * size_t(n * n);
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const float c = glm::dot(nrm, octTexelDirection(i, j, n));
          row[j * n + i] = c > 0.0f ? float(double(c) * omega[size_t(j * n + i)]) : 0.0f;
        }
    }
  return cache.emplace(std::make_pair(n, m), std::move(k)).first->second;
}

// Probe p's maps from SH L1 radiance (see decodeCellField).
void fillFromSh(const ShL1& sh, float range, ProbeField& f, size_t p) {
  const int n = f.resolution, m = f.irradianceResolution;
  const size_t tn = size_t(n) * size_t(n), tm = size_t(m) * size_t(m);
  shProbeMaps(sh, n, m, f.radiance.data() + p * tn * 3, f.irradiance.data() + p * tm * 3);
  float* dist = f.distance.data() + p * tn * 2;
  for (size_t t = 0; t < tn; ++t) dist[t * 2] = range, dist[t * 2 + 1] = range * range;
}

void copyProbe(const ProbeField& from, size_t a, ProbeField& to, size_t b) {
  const size_t tn = size_t(to.resolution) * size_t(to.resolution);
  const size_t tm = size_t(to.irradianceResolution) * size_t(to.irradianceResolution);
  std::copy_n(from.radiance.data() + a * tn * 3, tn * 3, to.radiance.data() + b * tn * 3);
  std::copy_n(from.distance.data() + a * tn * 2, tn * 2, to.distance.data() + b * tn * 2);
  std::copy_n(from.irradiance.data() + a * tm * 3, tm * 3, to.irradiance.data() + b * tm * 3);
}

}  // namespace

void CellFileSourceOptions::validate() const {
  if (worldDir.empty() == worldUrl.empty())
    fail("CellFileSourceOptions: give one of worldDir and worldUrl (worldDir '{}', worldUrl '{}')",
         worldDir.string(), worldUrl);
  if (!worldUrl.empty() && !isHttpUrl(worldUrl))
    fail("CellFileSourceOptions.worldUrl '{}' is not an http:// or https:// URL", worldUrl);
  if (!worldUrl.empty() && storage == CellStorage::CellFiles)
    fail("CellFileSourceOptions: a world served over HTTP is read from its regions, not cell files");
  if (irradianceResolution < 0 || irradianceResolution > 64)
    fail("CellFileSourceOptions.irradianceResolution = {} outside [0, 64]", irradianceResolution);
  if (shOnlyResolution < 0 || shOnlyResolution > 128)
    fail("CellFileSourceOptions.shOnlyResolution = {} outside [0, 128]", shOnlyResolution);
  if (!(weather >= 0.0f && weather <= 1.0f))
    fail("CellFileSourceOptions.weather = {} outside [0, 1]", weather);
}

void cellFileFallbackKeys(const CellFile& cell, float weather, std::vector<float>& hours,
                          std::vector<ShL1>& sh) {
  const size_t entries = fallbackEntries(cell);
  hours.clear();
  sh.clear();
  // The keys fallbackKeyBlend chooses from at this weather: those at the overcast nearest to it.
  const FallbackKeyBlend any = fallbackKeyBlend(cell.fallback, 12.0f, weather);
  const float overcast = cell.fallback.keyOvercast[any.a];
  for (size_t k = 0; k < cell.fallback.keyCount(); ++k) {
    if (cell.fallback.keyOvercast[k] != overcast) continue;
    hours.push_back(cell.fallback.keyHours[k]);
    sh.push_back(cellKeySh(cell, entries, k));
  }
}

ShL1 interpolateFallback(std::span<const float> hours, std::span<const ShL1> sh, float timeOfDayHours) {
  const size_t K = std::min(hours.size(), sh.size());
  if (K == 0) return {};
  if (!(timeOfDayHours > hours[0])) return sh[0];  // clamped (and NaN)
  if (timeOfDayHours >= hours[K - 1]) return sh[K - 1];
  size_t hi = 1;
  while (hours[hi] < timeOfDayHours) ++hi;  // hours[hi - 1] < t <= hours[hi]
  if (hours[hi] == timeOfDayHours) return sh[hi];
  const float t = (timeOfDayHours - hours[hi - 1]) / (hours[hi] - hours[hi - 1]);
  return shLerp(sh[hi - 1], sh[hi], t);
}

int decodedResolution(const CellFile& cell, int shOnlyResolution) {
  return cell.generator ? cell.generator->weights.arch.outputResolution() : shOnlyResolution;
}

void convolveIrradiance(ProbeField& f, int64_t first, int64_t count) {
  const int n = f.resolution, m = f.irradianceResolution;
  const size_t tn = size_t(n) * size_t(n), tm = size_t(m) * size_t(m);
  if (first < 0 || count < 0 || first + count > f.probeCount() ||
      f.radiance.size() < size_t(f.probeCount()) * tn * 3 ||
      f.irradiance.size() < size_t(f.probeCount()) * tm * 3)
    fail("convolveIrradiance: probes [{}, {}) or array sizes disagree with the field's {} probes", first,
         first + count, f.probeCount());
  const auto kernel = irradianceKernel(n, m);
  const float* K = kernel->data();
  for (int64_t p = first; p < first + count; ++p) {
    const float* L = f.radiance.data() + size_t(p) * tn * 3;
    float* E = f.irradiance.data() + size_t(p) * tm * 3;
    for (size_t t = 0; t < tm; ++t) {
      const float* row = K + t * tn;
      float r = 0.0f, g = 0.0f, b = 0.0f;
      for (size_t s = 0; s < tn; ++s) {
        r += row[s] * L[s * 3];
        g += row[s] * L[s * 3 + 1];
        b += row[s] * L[s * 3 + 2];
      }
      E[t * 3] = r, E[t * 3 + 1] = g, E[t * 3 + 2] = b;
    }
  }
}

void cellLatents(const CellFile& cell, std::span<const uint8_t> active, std::vector<float>& latents,
                 const std::string& name) {
  if (!cell.generator) fail("{}: no generator, no latents", name);
  const GeneratorArch& arch = cell.generator->weights.arch;
  const int64_t P = cell.grid.probeCount();
  if (!active.empty() && active.size() != size_t(P))
    fail("{}: {} active flags for {} probes", name, active.size(), P);
  const int64_t A =
      active.empty() ? P
                     : int64_t(std::count_if(active.begin(), active.end(), [](uint8_t a) { return a != 0; }));
  const size_t L = size_t(arch.latentDim);
  if (arch.latentSource == LatentSource::Stored) {
    latents = dequantizeLatents(cell.generator->latents);
  } else {
    latents.resize(size_t(A) * L);
    const glm::vec3 lo = cell.grid.origin, ext = cell.grid.boxMax() - cell.grid.origin;
    size_t k = 0;
    for (int64_t i = 0; i < P; ++i) {
      if (!active.empty() && !active[size_t(i)]) continue;
      const glm::vec3 p = cell.grid.probePosition(cell.grid.probeCoord(i));
      glm::vec3 q;
      for (int a = 0; a < 3; ++a)
        q[a] = ext[a] > 0.0f ? std::clamp((p[a] - lo[a]) / ext[a], 0.0f, 1.0f) : 0.5f;
      positionLatent(q, arch.fourierOctaves, std::span<float>(latents).subspan(k * L, L));
      ++k;
    }
  }
  if (latents.size() != size_t(A) * L)
    fail("{}: {} latent floats for {} active probes of {}", name, latents.size(), A, L);
}

void decodeCellField(const CellFile& cell, float timeOfDayHours, float weather, int irradianceResolution,
                     int shOnlyResolution, ProbeField& out, const std::string& name,
                     GeneratorBackend* backend, const ResolvedSharedModel* shared) {
  const int n = decodedResolution(cell, shOnlyResolution);
  if (n < 1 || n > 128) fail("{}: decoded resolution {} outside [1, 128]", name, n);
  const int m = irradianceResolutionFor(n, irradianceResolution);
  const int64_t P = cell.grid.probeCount();
  const size_t tn = size_t(n) * size_t(n), tm = size_t(m) * size_t(m);
  out.grid = cell.grid;
  out.resolution = n;
  out.irradianceResolution = m;
  out.offsets.clear();
  out.normal.clear();
  out.albedo.clear();
  if (cell.active.empty())
    out.active.assign(size_t(P), 1);
  else
    out.active.assign(cell.active.begin(), cell.active.end());
  out.radiance.resize(size_t(P) * tn * 3);
  out.distance.resize(size_t(P) * tn * 2);
  out.irradiance.resize(size_t(P) * tm * 3);

  // The fallback at this time of day and weather (the keys' SH interpolated, as CellFileSource::fallback).
  const ShL1 cellSh = cellFileFallback(cell, timeOfDayHours, weather);
  const FallbackKeyBlend blend = fallbackKeyBlend(cell.fallback, timeOfDayHours, weather);
  const size_t entries = fallbackEntries(cell);
  const bool perProbe = cell.fallback.kind == CellFallback::Kind::PerProbe;
  const float range = cell.outputScale.range;
  const int64_t A = cell.activeProbeCount();

  if (cell.generator && A > 0) {
    const GeneratorWeights weights = resolveCellWeights(*cell.generator, shared, name);
    const GeneratorArch& arch = weights.arch;
    // The active probes in latent order are decoded densely (batches of the backend's choosing) into a
    // staging field, then scattered. Everything after the network is this code, for every backend.
    thread_local std::vector<float> latents;
    thread_local ProbeField stage;
    cellLatents(cell, out.active, latents, name);
    const auto cond = conditioningVector(timeOfDayHours, weather);
    const std::span<const float> condSpan(cond.data(), size_t(arch.condDim));
    stage.grid = ProbeGrid{};
    stage.resolution = n;
    stage.irradianceResolution = m;
    stage.normal.clear();
    stage.albedo.clear();
    int64_t next = 0;  // next probe index to place
    size_t firstInactive = size_t(-1);
    auto placeUpTo = [&](int64_t end, size_t& k) {  // scatter staged probes, SH for the inactive ones
      for (; next < end; ++next) {
        if (out.active[size_t(next)]) {
          copyProbe(stage, k++, out, size_t(next));
        } else if (firstInactive == size_t(-1)) {
          fillFromSh(cellSh, range, out, size_t(next));
          firstInactive = size_t(next);
        } else {
          copyProbe(out, firstInactive, out, size_t(next));
        }
      }
    };
    const size_t raw = size_t(kGeneratorChannels) * tn;
    if (arch.outChannels() != kGeneratorChannels)
      fail("{}: the model emits {} channels, a probe field needs {}", name, arch.outChannels(),
           kGeneratorChannels);
    auto sink = [&](size_t, size_t cnt, std::span<const float> rawOut) {
      stage.grid.dims = {int(cnt), 1, 1};
      stage.radiance.resize(cnt * tn * 3);
      stage.distance.resize(cnt * tn * 2);
      stage.irradiance.resize(cnt * tm * 3);
      for (size_t p = 0; p < cnt; ++p)
        decodeChannels(rawOut.subspan(p * raw, raw), n, cell.outputScale,
                       std::span(stage.radiance).subspan(p * tn * 3, tn * 3),
                       std::span(stage.distance).subspan(p * tn * 2, tn * 2), {}, {});
      convolveIrradiance(stage, 0, int64_t(cnt));
      // Place probes up to (excluding) the next active one after this batch.
      size_t k = 0, seen = 0;
      int64_t end = next;
      while (end < P && seen < cnt) seen += out.active[size_t(end++)] != 0;
      placeUpTo(end, k);
    };
    CpuGeneratorBackend cpu;
    GeneratorBackend& b = backend ? *backend : static_cast<GeneratorBackend&>(cpu);
    b.decode(ModelRef{weights, backend ? generatorModelKey(weights) : 0}, latents, condSpan, size_t(A), sink);
    size_t k = 0;
    placeUpTo(P, k);  // trailing inactive probes
    return;
  }
  // No network (or no active probe): every probe from SH; a per-cell SH is evaluated once and copied.
  size_t k = 0, firstShared = size_t(-1);
  for (int64_t i = 0; i < P; ++i) {
    const bool own = perProbe && out.active[size_t(i)];
    if (own) {
      fillFromSh(fallbackEntry(cell.fallback, entries, k, blend), range, out, size_t(i));
    } else if (firstShared == size_t(-1)) {
      fillFromSh(cellSh, range, out, size_t(i));
      firstShared = size_t(i);
    } else {
      copyProbe(out, firstShared, out, size_t(i));
    }
    if (out.active[size_t(i)]) ++k;
  }
}

CellFileSource::CellFileSource(CellFileSourceOptions options) : options_(std::move(options)) {
  options_.validate();
  if (options_.cellsDir.empty()) options_.cellsDir = options_.worldDir / "baked" / "cells";
  if (options_.sharedModel.empty())
    options_.sharedModel = options_.cellsDir.parent_path() / "shared_model.vdb";
  world_ = readManifest();
  const int cells = int(std::lround(world_.sizeM / world_.cellM));
  layout_ = {{0.0f, 0.0f}, float(world_.cellM), {cells, cells}};
  worldSeed_ = world_.seed;
  openStore();

  const size_t N = size_t(cells) * size_t(cells);
  info_.assign(N, {});
  keyRange_.assign(N, {0, 0});
  // Auto: the first generator cell's model, latents and active count, for timing both backends.
  std::optional<GeneratorWeights> probeWeights;
  std::vector<float> probeLatents;
  const int maxGeneratorN = scanCellFiles(cells, probeWeights, probeLatents);
  if (validCells_ == 0)
    fail("{}: none of the world's {} cells has a readable cell file ({} missing, {} corrupt)",
         store_->location(), N, missingCells_, corruptCells_);
  sizeSlots(maxGeneratorN);
  fillMissingFallbacks(cells);
  for (const auto& range : keyRange_)
    fallbackFollowsTimeOfDay_ = fallbackFollowsTimeOfDay_ || range.second > 1;
  if (missingCells_ > 0)
    spdlog::warn(
        "streaming: {} of {} cells are not stored in {} (they stream their neighbours' mean fallback)",
        missingCells_, N, store_->location());
  spdlog::info("streaming: {} in {}: {} valid, {} missing, {} corrupt; slot {} bytes", store_->kind(),
               store_->location(), validCells_, missingCells_, corruptCells_, maxCellBytes_);
  chooseDecoder(probeWeights, probeLatents);
  samples_.reserve(4096);
}

std::string CellFileSource::worldUrl(const std::string& file) const {
  std::string base = options_.worldUrl;
  if (base.back() != '/') base += '/';
  return base + file;
}

worlds::WorldParams CellFileSource::readManifest() const {
  if (options_.worldUrl.empty()) return worlds::readWorldManifest(options_.worldDir);
  const std::string url = worldUrl("world.json");
  const std::vector<std::byte> text = httpGet(url, size_t(1) << 20);
  return worlds::parseWorldManifest(std::string_view(reinterpret_cast<const char*>(text.data()), text.size()),
                                    url);
}

void CellFileSource::openStore() {
  if (!options_.worldUrl.empty()) {
    store_ = openRegions(httpRegionSource(worldUrl("baked/regions")));
    return;
  }
  if (options_.regionsDir.empty()) options_.regionsDir = options_.cellsDir.parent_path() / "regions";
  std::error_code ec;
  const bool regions =
      options_.storage == CellStorage::Regions ||
      (options_.storage == CellStorage::Auto && fs::exists(options_.regionsDir / "regions.json", ec));
  if (regions) {
    store_ = openRegions(options_.regionsDir);
    return;
  }
  if (!fs::is_directory(options_.cellsDir, ec))
    fail("{}: no cell-file directory (bake the world with `lfgi bake` first)", options_.cellsDir.string());
  store_ = openCellFiles(options_.cellsDir);
}

// Reads every cell file once: its info_ entry, its fallback keys, the counts; returns the largest generator
// resolution. probeWeights / probeLatents: the first generator cell's (Auto's timing input).
int CellFileSource::scanCellFiles(int cells, std::optional<GeneratorWeights>& probeWeights,
                                  std::vector<float>& probeLatents) {
  std::error_code ec;
  std::vector<float> hours;
  std::vector<ShL1> keySh;
  int maxGeneratorN = 0, logged = 0;
  for (int z = 0; z < cells; ++z)
    for (int x = 0; x < cells; ++x) {
      const glm::ivec2 c{x, z};
      CellFileInfo& inf = info_[size_t(layout_.linear(c))];
      const std::string path = store_->where(c);
      if (!store_->has(c)) {
        inf.state = CellFileState::Missing;
        inf.error = fmt::format("{}: {}", path, store_->missing());
        ++missingCells_;
        continue;
      }
      try {
        CellFile file = store_->read(c);
        checkCellFits(file, c, worldSeed_, layout_, path);
        // A shared-model cell is valid only with its world's shared model (loaded once, hash checked).
        if (file.generator && file.generator->shared)
          checkSharedReference(*file.generator, sharedFor(file, path), path);
        cellFileFallbackKeys(file, options_.weather, hours, keySh);
        keyRange_[size_t(layout_.linear(c))] = {uint32_t(keyHours_.size()), uint32_t(hours.size())};
        keyHours_.insert(keyHours_.end(), hours.begin(), hours.end());
        keySh_.insert(keySh_.end(), keySh.begin(), keySh.end());
        inf.fallbackKeys = int(hours.size());
        inf.state = CellFileState::Valid;
        inf.network = file.generator.has_value();
        inf.probes = file.grid.probeCount();
        inf.grid = file.grid;
        inf.activeProbes = file.activeProbeCount();
        inf.resolution = inf.network ? file.generator->weights.arch.outputResolution() : 0;
        if (inf.network) maxGeneratorN = std::max(maxGeneratorN, inf.resolution);
        if (inf.network && options_.decoder == DecoderChoice::Auto && !probeWeights && inf.activeProbes > 0) {
          probeWeights = resolveCellWeights(*file.generator, sharedFor(file, path), path);
          cellLatents(file, file.active, probeLatents, path);
        }
        ++validCells_;
      } catch (const Error& e) {
        inf.state = CellFileState::Corrupt;
        inf.error = e.what();
        ++corruptCells_;
        if (logged++ < 8)
          spdlog::warn("streaming: {} (the cell streams its neighbours' mean fallback)", inf.error);
      }
    }
  return maxGeneratorN;
}

// Each valid cell's decoded resolution and field size, and the slot size.
void CellFileSource::sizeSlots(int maxGeneratorN) {
  if (options_.shOnlyResolution == 0) options_.shOnlyResolution = maxGeneratorN > 0 ? maxGeneratorN : 8;
  for (CellFileInfo& inf : info_) {
    if (inf.state != CellFileState::Valid) continue;
    if (!inf.network) inf.resolution = options_.shOnlyResolution;
    inf.fieldBytes = fieldBytesFor(inf.probes, inf.resolution,
                                   irradianceResolutionFor(inf.resolution, options_.irradianceResolution));
    maxCellBytes_ = std::max(maxCellBytes_, inf.fieldBytes);
  }
}

void CellFileSource::fillMissingFallbacks(int cells) {
  // Cells without a usable file: the mean fallback of the nearest ring (Chebyshev distance r) holding a
  // valid cell, per key: the keys are the union of the ring's key hours and each holds the mean of the
  // ring's interpolated fallbacks there. Every valid cell's fallback is linear between its keys and
  // constant outside them, so the mean is linear between the union's hours: interpolating these keys
  // gives the ring's mean at every time of day. Any ring reaches every cell by r = cells, and a valid
  // cell exists.
  std::vector<glm::ivec2> ring;
  std::vector<float> hours;
  for (int z = 0; z < cells; ++z)
    for (int x = 0; x < cells; ++x) {
      const size_t self = size_t(layout_.linear({x, z}));
      if (info_[self].state == CellFileState::Valid) continue;
      for (int r = 1; r <= cells; ++r) {
        ring.clear();
        hours.clear();
        for (int dz = -r; dz <= r; ++dz)
          for (int dx = -r; dx <= r; ++dx) {
            const glm::ivec2 c{x + dx, z + dz};
            if (std::max(std::abs(dx), std::abs(dz)) != r || !layout_.contains(c) ||
                info_[size_t(layout_.linear(c))].state != CellFileState::Valid)
              continue;
            ring.push_back(c);
            const auto [first, count] = keyRange_[size_t(layout_.linear(c))];
            hours.insert(hours.end(), keyHours_.begin() + first, keyHours_.begin() + first + count);
          }
        if (ring.empty()) continue;
        std::sort(hours.begin(), hours.end());
        hours.erase(std::unique(hours.begin(), hours.end()), hours.end());
        keyRange_[self] = {uint32_t(keyHours_.size()), uint32_t(hours.size())};
        for (float h : hours) {
          ShL1 sum;
          for (glm::ivec2 c : ring) {
            const ShL1 v = keyFallback(c, h);
            for (int k = 0; k < 4; ++k) sum.c[size_t(k)] += v.c[size_t(k)];
          }
          for (glm::vec3& v : sum.c) v /= float(ring.size());
          keyHours_.push_back(h);
          keySh_.push_back(sum);
        }
        break;
      }
    }
}

void CellFileSource::chooseDecoder(const std::optional<GeneratorWeights>& probeWeights,
                                   const std::vector<float>& probeLatents) {
  // The decoder: the timing input is the real first generator cell (its own model, latents and the noon
  // conditioning), so the rates are the ones this world's loads will see.
  const auto cond = conditioningVector(12.0f, options_.weather);
  const size_t condDim = probeWeights ? size_t(probeWeights->arch.condDim) : 0;
  const size_t probeCount = probeWeights ? probeLatents.size() / size_t(probeWeights->arch.latentDim) : 0;
  backend_ = chooseGeneratorBackend(options_.decoder, probeWeights ? &*probeWeights : nullptr, probeLatents,
                                    std::span<const float>(cond.data(), condDim), probeCount, selection_,
                                    options_.gpu);
  gpuBackend_ = dynamic_cast<GpuGeneratorBackend*>(backend_.get());
}

const ResolvedSharedModel* CellFileSource::sharedFor(const CellFile& file, const std::string& path) {
  if (!file.generator || !file.generator->shared) return nullptr;
  std::call_once(sharedOnce_, [&] {  // usually during construction; any thread may be first
    std::error_code ec;
    if (!options_.worldUrl.empty()) {
      try {
        const std::string url = worldUrl("baked/shared_model.vdb");
        ResolvedSharedModel m;
        m.weights =
            dequantizeWeights(decodeSharedModel(httpGet(url, kCellFileMaxBytes), url, &m.hash).weights);
        m.name = url;
        shared_ = std::move(m);
      } catch (const Error& e) {
        sharedError_ = e.what();
      }
    } else if (!fs::exists(options_.sharedModel, ec)) {
      sharedError_ = fmt::format("{}: no shared model file (bake the world with `lfgi bake --codec shared`)",
                                 options_.sharedModel.string());
    } else {
      try {
        shared_ = loadSharedModel(options_.sharedModel);
        spdlog::info("streaming: shared model {} ({:016x})", options_.sharedModel.string(), shared_->hash);
      } catch (const Error& e) {
        sharedError_ = e.what();
      }
    }
  });
  if (!shared_)
    fail("{}: refers to shared model {:016x}, which cannot be used: {}", path,
         file.generator->shared->modelHash, sharedError_);
  return &*shared_;
}

std::vector<CellFileSource::DecodeSample> CellFileSource::decodeSamples() const {
  const std::lock_guard lock(samplesMutex_);
  return samples_;
}

std::string CellFileSource::where(glm::ivec2 cell) const {
  return store_->where(cell);
}

ShL1 CellFileSource::keyFallback(glm::ivec2 cell, float timeOfDayHours) const {
  const auto [first, count] = keyRange_[size_t(layout_.linear(cell))];
  return interpolateFallback(std::span<const float>(keyHours_).subspan(first, count),
                             std::span<const ShL1>(keySh_).subspan(first, count), timeOfDayHours);
}

ShL1 CellFileSource::fallback(glm::ivec2 cell) const {
  if (!layout_.contains(cell))
    fail("cell {},{}: outside the {}x{} world", cell.x, cell.y, layout_.cells.x, layout_.cells.y);
  return keyFallback(cell, timeOfDay_.load(std::memory_order_relaxed));
}

void CellFileSource::readAndDecode(glm::ivec2 cell, float timeOfDayHours, ProbeField& out) {
  const std::string path = store_->where(cell);
  const auto t0 = Clock::now();
  if (!store_->has(cell)) fail("{}: {}", path, store_->missing());
  const CellFile file = store_->read(cell);
  checkCellFits(file, cell, worldSeed_, layout_, path);
  const auto t1 = Clock::now();
  readUs_.fetch_add(usSince(t0));
  decodeCellField(file, timeOfDayHours, options_.weather, options_.irradianceResolution,
                  options_.shOnlyResolution, out, path, backend_.get(), sharedFor(file, path));
  recordDecode(t1, file);
}

void CellFileSource::recordDecode(std::chrono::steady_clock::time_point t0, const CellFile& file) {
  const uint64_t us = usSince(t0);
  decodeUs_.fetch_add(us);
  const std::lock_guard lock(samplesMutex_);
  samples_.push_back({float(double(us) * 1e-3), file.generator ? file.activeProbeCount() : 0});
}

void CellFileSource::load(glm::ivec2 cell, ProbeField& out) {
  if (!layout_.contains(cell))
    fail("cell {},{}: outside the {}x{} world", cell.x, cell.y, layout_.cells.x, layout_.cells.y);
  readAndDecode(cell, timeOfDay_.load(), out);
  loads_.fetch_add(1);
}

bool CellFileSource::dependsOnTimeOfDay(glm::ivec2 cell) const {
  const CellFileInfo& inf = info_[size_t(layout_.linear(cell))];
  return inf.state == CellFileState::Valid && (inf.network || inf.fallbackKeys > 1);
}

bool CellFileSource::relight(glm::ivec2 cell, ProbeField& field, float timeOfDayHours) {
  if (!layout_.contains(cell) || !dependsOnTimeOfDay(cell)) return true;
  const std::string path = store_->where(cell);
  try {
    const auto t0 = Clock::now();
    const CellFile file = store_->read(cell);
    checkCellFits(file, cell, worldSeed_, layout_, path);
    if (!file.generator && file.fallback.keyCount() <= 1) return true;
    const auto t1 = Clock::now();
    readUs_.fetch_add(usSince(t0));
    // In place: past readCellFile's checks and this size check, decoding cannot fail halfway.
    if (file.grid.probeCount() != field.probeCount() ||
        decodedResolution(file, options_.shOnlyResolution) != field.resolution)
      fail("{}: changed size since the cell was loaded", path);
    decodeCellField(file, timeOfDayHours, options_.weather, options_.irradianceResolution,
                    options_.shOnlyResolution, field, path, backend_.get(), sharedFor(file, path));
    recordDecode(t1, file);
    return true;
  } catch (const Error& e) {
    spdlog::warn("streaming: relight of cell {},{} failed, keeping its lighting: {}", cell.x, cell.y,
                 e.what());
    return false;
  }
}

void CellFileSource::relightInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out,
                                 float timeOfDayHours) {
  if (!layout_.contains(cell))
    fail("cell {},{}: outside the {}x{} world", cell.x, cell.y, layout_.cells.x, layout_.cells.y);
  if (!dependsOnTimeOfDay(cell)) {
    out = current;  // copy-assignment keeps out's capacity when it fits: no allocation once warm
    return;
  }
  readAndDecode(cell, timeOfDayHours, out);
}

}  // namespace lfgi::streaming
